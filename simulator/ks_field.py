"""Kinematic-simulation (KS) turbulence: one random realization of a divergence-free field.

u(x, t) = Σ_n A_n cos θ_n + B_n sin θ_n, θ_n = k_n·x + ω_n t (docs/flow.md §1), with
k̂_n uniform on the sphere, A_n and B_n perpendicular to k_n (so ∇·u ≡ 0 mode by mode),
|A_n|² = |B_n|² = 2E(k_n)Δk_n and ω_n = λ √(k_n³ E(k_n)).

Velocity, its gradient and the exact Lagrangian acceleration
a = ∂u/∂t + (u·∇)u are evaluated by the compiled kernels of
:mod:`simulator.ks_kernels`, which work on blocks of 128 particles: besides the
outputs, memory does not grow with the number of particles or modes.
"""

from dataclasses import dataclass

import numpy as np

from simulator import ks_kernels
from simulator.spectra import ModeSpectrum, Spectrum, discretise
from simulator.truth import structure_kernel
from simulator.turbulence import TurbulenceParameters

#: Default unsteadiness λ in ω_n = λ √(k³E); 0 freezes the field.
DEFAULT_UNSTEADINESS = 0.5


def _as_points(x: np.ndarray) -> np.ndarray:
    x = np.ascontiguousarray(x, dtype=np.float64)
    if x.ndim != 2 or x.shape[1] != 3:
        raise ValueError(f"points must have shape (P, 3), got {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError("points contain NaN or infinite coordinates")
    return x


def _check_time(t: float) -> float:
    t = float(t)
    if not np.isfinite(t):
        raise ValueError(f"time must be finite, got {t}")
    return t


def random_unit_vectors(n: int, rng: np.random.Generator) -> np.ndarray:
    """Unit vectors uniform on the sphere (μ ~ U(−1, 1), φ ~ U(0, 2π)), shape (n, 3)."""
    mu = rng.uniform(-1.0, 1.0, n)
    phi = rng.uniform(0.0, 2.0 * np.pi, n)
    rho = np.sqrt(1.0 - mu**2)
    return np.column_stack([rho * np.cos(phi), rho * np.sin(phi), mu])


def _perpendicular_unit(k_hat: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Unit vectors (k̂ × ξ)/|k̂ × ξ| for isotropic ξ, perpendicular to each row of k_hat."""
    out = np.cross(k_hat, random_unit_vectors(len(k_hat), rng))
    norm = np.linalg.norm(out, axis=1)
    bad = norm < 1e-8
    while np.any(bad):  # ξ almost parallel to k̂: redraw those (probability ~1e-16)
        out[bad] = np.cross(k_hat[bad], random_unit_vectors(int(bad.sum()), rng))
        norm = np.linalg.norm(out, axis=1)
        bad = norm < 1e-8
    return out / norm[:, None]


@dataclass(frozen=True)
class KSField:
    """One realization of a KS velocity field.

    Attributes
    ----------
    parameters : TurbulenceParameters
        The prescribed u', ε, ν.
    modes : ModeSpectrum
        Mode wavenumbers k_n (1/m), weights Δk_n and energies E_nΔk_n, shape (N,).
    wavevectors : ndarray, shape (N, 3)
        k_n, 1/m.
    a, b : ndarray, shape (N, 3)
        Cosine and sine amplitudes A_n, B_n, m/s; perpendicular to k_n.
    omega : ndarray, shape (N,)
        Angular frequencies ω_n, rad/s.

    Examples
    --------
    A realization of 100 modes of the 10 Hz condition, at two points:

    >>> import numpy as np
    >>> import simulator
    >>> flow = simulator.flow_preset("lem-10hz").parameters
    >>> field = simulator.draw_ks_field(simulator.PopeSpectrum(flow), n_modes=100, rng=0)
    >>> x = np.array([[0.0, 0.0, 0.0], [1e-3, 2e-3, 0.0]])  # (P, 3), m
    >>> field.velocity(x, t=0.0).round(4)  # (P, 3), m/s
    array([[ 0.0008,  0.0709,  0.1614],
           [-0.0542,  0.0899,  0.368 ]])
    >>> field.acceleration(x).round(1)  # Lagrangian, (P, 3), m/s²
    array([[-45.9, -16.3,  26.1],
           [ 14.4, -77.3,  57.4]])

    Its exact D_LL averaged over directions, m²/s², at r = 1 and 10 mm:

    >>> field.longitudinal_structure_function([1e-3, 1e-2]).round(5)
    array([0.00394, 0.02451])
    """

    parameters: TurbulenceParameters
    modes: ModeSpectrum
    wavevectors: np.ndarray
    a: np.ndarray
    b: np.ndarray
    omega: np.ndarray

    @property
    def n_modes(self) -> int:
        """Number of modes N."""
        return len(self.omega)

    def phases(self, t: float | np.ndarray) -> np.ndarray:
        """Temporal phases ω_n t reduced to [0, 2π), shape (N,) or (T, N) for T times."""
        return np.mod(np.multiply.outer(np.asarray(t, dtype=float), self.omega), 2.0 * np.pi)

    def velocity(self, x: np.ndarray, t: float = 0.0) -> np.ndarray:
        """u(x, t).

        Parameters
        ----------
        x : array_like, shape (P, 3)
            Positions, m.
        t : float
            Time, s.

        Returns
        -------
        ndarray, shape (P, 3)
            Velocity, m/s.
        """
        x = _as_points(x)
        phase = self.phases(_check_time(t))
        return ks_kernels.velocity(x, phase, self.wavevectors, self.a, self.b)

    def derivatives(self, x: np.ndarray, t: float = 0.0) -> tuple[np.ndarray, ...]:
        """Velocity, ∂u/∂t, velocity gradient and Lagrangian acceleration.

        Parameters
        ----------
        x : array_like, shape (P, 3)
            Positions, m.
        t : float
            Time, s.

        Returns
        -------
        u : ndarray, shape (P, 3)
            Velocity, m/s.
        dudt : ndarray, shape (P, 3)
            Local time derivative ∂u/∂t, m/s².
        grad : ndarray, shape (P, 3, 3)
            grad[p, i, j] = ∂u_i/∂x_j, 1/s.
        accel : ndarray, shape (P, 3)
            a = ∂u/∂t + (u·∇)u, m/s².
        """
        x = _as_points(x)
        phase = self.phases(_check_time(t))
        u, dudt, accel = np.empty_like(x), np.empty_like(x), np.empty_like(x)
        grad = np.empty((len(x), 3, 3))
        ks_kernels.velocity_derivatives(
            x, phase, self.wavevectors, self.a, self.b, self.omega, u, dudt, grad, accel
        )
        return u, dudt, grad, accel

    def acceleration(self, x: np.ndarray, t: float = 0.0) -> np.ndarray:
        """Exact Lagrangian acceleration a = ∂u/∂t + (u·∇)u, m/s², shape (P, 3)."""
        return self.derivatives(x, t)[3]

    def longitudinal_structure_function(self, r: np.ndarray) -> np.ndarray:
        """Exact D_LL(r) of this realization averaged over directions (docs/flow.md §3.2).

        D_LL(r) = Σ_n (|A_n|² + |B_n|²) G(k_n r), G(x) = 1/3 − (sin x − x cos x)/x³.
        It does not depend on the mode directions: it is the ensemble D_LL of the modes.

        Parameters
        ----------
        r : array_like
            Separations, m (any shape).

        Returns
        -------
        ndarray
            D_LL(r), m²/s², same shape as r.
        """
        r = np.asarray(r, dtype=float)
        weight = np.sum(self.a**2, axis=1) + np.sum(self.b**2, axis=1)
        return structure_kernel(np.multiply.outer(r, self.modes.k)) @ weight


def draw_ks_field(
    spectrum: Spectrum,
    *,
    n_modes: int = 200,
    unsteadiness: float = DEFAULT_UNSTEADINESS,
    rng: np.random.Generator | int | None = None,
) -> KSField:
    """Draw one KS realization of a spectrum.

    Parameters
    ----------
    spectrum : PopeSpectrum or KolmogorovBandSpectrum
        Continuous spectrum with its prescribed parameters.
    n_modes : int
        Number of modes N ≥ 2.
    unsteadiness : float
        λ ≥ 0 in ω_n = λ √(k_n³ E(k_n)).
    rng : numpy.random.Generator, int or None
        Source of the random directions.

    Returns
    -------
    KSField

    Examples
    --------
    The field is divergence-free mode by mode: the trace of its gradient is zero to
    round-off.

    >>> import numpy as np
    >>> import simulator
    >>> flow = simulator.flow_preset("lem-10hz").parameters
    >>> field = simulator.draw_ks_field(simulator.PopeSpectrum(flow), n_modes=100, rng=0)
    >>> field.n_modes, field.wavevectors.shape  # k_n, 1/m
    (100, (100, 3))
    >>> x = np.random.default_rng(1).uniform(-0.05, 0.05, (1000, 3))  # m
    >>> u, dudt, grad, accel = field.derivatives(x, t=0.01)
    >>> bool(np.abs(np.trace(grad, axis1=1, axis2=2)).max() < 1e-9)  # ∇·u, 1/s
    True
    """
    if not np.isfinite(unsteadiness) or unsteadiness < 0:
        raise ValueError(f"unsteadiness must be finite and >= 0, got {unsteadiness}")
    rng = np.random.default_rng(rng)
    modes = discretise(spectrum, n_modes)
    k_hat = random_unit_vectors(n_modes, rng)
    amplitude = np.sqrt(2.0 * modes.energy)[:, None]
    a = amplitude * _perpendicular_unit(k_hat, rng)
    b = amplitude * _perpendicular_unit(k_hat, rng)
    omega = unsteadiness * np.sqrt(modes.k**3 * spectrum.energy(modes.k))
    return KSField(
        parameters=spectrum.parameters,
        modes=modes,
        wavevectors=k_hat * modes.k[:, None],
        a=a,
        b=b,
        omega=omega,
    )
