"""Energy spectrum, energy budget and the flow's measured scales (docs/dns.md §6).

All sums run over the half spectrum with each coefficient counted with its complex
conjugate (weight 2 off the planes n_z = 0 and n_z = N/2). With the 'backward'
normalisation a mode of coefficient û holds the energy |û|²/(2N⁶) per unit mass.
"""

from dataclasses import asdict, dataclass
from math import pi, sqrt

import numpy as np

from simulator.dns import spectral_kernels as kern
from simulator.dns.grid import Grid


@dataclass(frozen=True)
class SpectralSums:
    """Instantaneous single-point quantities of one state.

    Attributes
    ----------
    energy : float
        Kinetic energy ½⟨|u|²⟩, m²/s².
    dissipation : float
        2ν⟨s_ij s_ij⟩ = 2ν Σ|k|²E(k), m²/s³.
    inverse_k : float
        ∫E(k)/k dk (Σ over modes of the mode energy over |k|), m³/s².
    """

    energy: float
    dissipation: float
    inverse_k: float


def spectral_sums(uh: np.ndarray, grid: Grid, nu: float) -> SpectralSums:
    """Kinetic energy, dissipation and ∫E/k dk of coefficients of shape (3, N, N, M)."""
    kx, ky, kz = grid.wavenumbers()
    energy, enstrophy, inverse = kern.weighted_sums(uh, kx, ky, kz, grid.mode_weights())
    norm = 2.0 * float(grid.n) ** 6
    return SpectralSums(energy / norm, 2.0 * nu * enstrophy / norm, inverse / norm)


def energy_spectrum(uh: np.ndarray, grid: Grid) -> tuple[np.ndarray, np.ndarray]:
    """Shell-averaged energy spectrum E(k).

    Shell n holds the modes with n − ½ ≤ |k|/(2π/L) < n + ½, n = 1 up to the corners of
    the 2/3-rule cube (|k| ≤ √3 k_max), so that Σ E(k_n)·(2π/L) is the kinetic energy
    (n = 0, the mean flow, is left out).

    Parameters
    ----------
    uh : ndarray, shape (3, N, N, N//2 + 1), complex
        Velocity coefficients.
    grid : Grid

    Returns
    -------
    k : ndarray, shape (S,)
        Shell wavenumbers n·2π/L, n = 1 … S, 1/m.
    spectrum : ndarray, shape (S,)
        E(k), m³/s².
    """
    kx, ky, kz = grid.wavenumbers()
    shell = np.rint(
        np.sqrt(kx[:, None, None] ** 2 + ky[None, :, None] ** 2 + kz[None, None, :] ** 2) / grid.k0
    ).astype(np.intp)
    mode_energy = grid.mode_weights() * np.sum(uh.real**2 + uh.imag**2, axis=0)
    mode_energy /= 2.0 * float(grid.n) ** 6
    kept = np.all(np.meshgrid(*grid.kept(), indexing="ij"), axis=0)
    shells = int(shell[kept].max())
    sums = np.bincount(shell[kept], weights=mode_energy[kept], minlength=shells + 1)
    return np.arange(1, shells + 1) * grid.k0, sums[1:] / grid.k0


@dataclass(frozen=True)
class MeasuredParameters:
    """Scales of a flow measured from its fields (instantaneous or averaged), SI units.

    Attributes
    ----------
    n : int
        Grid points per axis.
    box_side : float
        Side L of the periodic box, m.
    nu : float
        Kinematic viscosity, m²/s.
    epsilon_injection : float
        Power put in by the forcing, m²/s³.
    epsilon : float
        Dissipation 2ν⟨s_ij s_ij⟩, m²/s³; the scales below use it.
    kinetic_energy : float
        ½⟨|u|²⟩ = (3/2)u′², m²/s².
    u_rms : float
        u′, rms of one velocity component, m/s.
    eta : float
        Kolmogorov length (ν³/ε)^{1/4}, m.
    tau_eta : float
        Kolmogorov time (ν/ε)^{1/2}, s.
    taylor_microscale : float
        λ = (15νu′²/ε)^{1/2}, m.
    r_lambda : float
        R_λ = u′λ/ν.
    integral_scale : float
        L = (π/(2u′²)) ∫E(k)/k dk, m.
    eddy_time : float
        T_L = L/u′, s.
    kmax_eta : float
        k_max η with k_max = (N/3)(2π/L).
    """

    n: int
    box_side: float
    nu: float
    epsilon_injection: float
    epsilon: float
    kinetic_energy: float
    u_rms: float
    eta: float
    tau_eta: float
    taylor_microscale: float
    r_lambda: float
    integral_scale: float
    eddy_time: float
    kmax_eta: float

    def as_dict(self) -> dict:
        """The fields as a dict of Python numbers (for HDF5 attributes and JSON)."""
        return asdict(self)


def measured_parameters(
    grid: Grid,
    nu: float,
    *,
    energy: float,
    dissipation: float,
    inverse_k: float,
    injection: float,
) -> MeasuredParameters:
    """The scales from (possibly time-averaged) energy, dissipation and ∫E/k dk.

    Parameters
    ----------
    grid : Grid
    nu : float
        m²/s.
    energy : float
        ½⟨|u|²⟩, m²/s².
    dissipation : float
        2ν⟨s_ij s_ij⟩, m²/s³.
    inverse_k : float
        ∫E(k)/k dk, m³/s².
    injection : float
        Power of the forcing, m²/s³.
    """
    if not (energy > 0.0 and dissipation > 0.0):
        raise ValueError(f"energy and dissipation must be > 0, got {energy!r} and {dissipation!r}")
    u_rms = sqrt(2.0 * energy / 3.0)
    eta = (nu**3 / dissipation) ** 0.25
    taylor = sqrt(15.0 * nu * u_rms**2 / dissipation)
    integral = pi / (2.0 * u_rms**2) * inverse_k
    return MeasuredParameters(
        n=grid.n,
        box_side=grid.box_side,
        nu=nu,
        epsilon_injection=injection,
        epsilon=dissipation,
        kinetic_energy=energy,
        u_rms=u_rms,
        eta=eta,
        tau_eta=sqrt(nu / dissipation),
        taylor_microscale=taylor,
        r_lambda=u_rms * taylor / nu,
        integral_scale=integral,
        eddy_time=integral / u_rms,
        kmax_eta=grid.kmax * eta,
    )
