"""Energy spectra E(k) whose energy and dissipation match prescribed (u', ε, ν).

Two spectra (docs/flow.md §2):

* :class:`PopeSpectrum`, Pope's model spectrum (*Turbulent Flows* §6.5) with c_L and
  c_η solved so that ∫E dk = (3/2)u'² and 2ν∫k²E dk = ε. The default.
* :class:`KolmogorovBandSpectrum`, E = C_K ε^{2/3} k^{-5/3} on [k₁, k_N], with k₁ and
  k_N solved so that the energy is (3/2)u'² and 2ν∫k²E dk = ε, which puts the cut-off
  at k_N η ≈ (2/(3C_K))^{3/4} ≈ 0.54 (not at 2π/η, which would dissipate 26ε).

Both expose ``energy(k)``, the wavenumber range ``k_min``, ``k_max`` over which modes
are laid, and ``dissipation()``/``kinetic_energy()`` integrals for checks.
"""

from dataclasses import dataclass, field
from math import exp, log

import numpy as np
from scipy.optimize import root

from simulator.turbulence import TurbulenceParameters

#: Kolmogorov constant of the 3-D spectrum.
C_KOLMOGOROV = 1.5


def _log_integral(func, k_lo: float, k_hi: float, n: int = 20001) -> float:
    """∫ func(k) dk over [k_lo, k_hi] by the trapezoid rule on a log grid."""
    s = np.linspace(log(k_lo), log(k_hi), n)
    k = np.exp(s)
    return float(np.trapezoid(func(k) * k, s))


@dataclass(frozen=True)
class PopeSpectrum:
    """Pope's model spectrum E(k) = C ε^{2/3} k^{-5/3} f_L(kL) f_η(kη).

    Parameters
    ----------
    parameters : TurbulenceParameters
        Prescribed u', ε, ν.
    kl_min : float
        Lowest mode wavenumber in units of 1/L (L = k_t^{3/2}/ε); 0.5 misses < 3e-4
        of the energy.
    keta_max : float
        Highest mode wavenumber in units of 1/η; 3 misses < 2e-4 of the dissipation.

    Attributes
    ----------
    c_L, c_eta : float
        The solved shape constants (6.78 and 0.40 at high Reynolds number).

    Examples
    --------
    Fitted to the 10 Hz condition, it holds the energy (3/2)u′² and dissipates ε
    (docs/flow.md §2.1):

    >>> import simulator
    >>> flow = simulator.flow_preset("lem-10hz").parameters
    >>> spectrum = simulator.PopeSpectrum(flow)
    >>> round(spectrum.c_L, 3), round(spectrum.c_eta, 3)
    (6.221, 0.403)
    >>> round(spectrum.kinetic_energy(), 5), round(1.5 * flow.u_rms**2, 5)  # m²/s²
    (0.05415, 0.05415)
    >>> round(spectrum.dissipation(), 5)  # m²/s³
    0.17
    """

    parameters: TurbulenceParameters
    kl_min: float = 0.5
    keta_max: float = 3.0
    C: float = C_KOLMOGOROV
    p0: float = 2.0
    beta: float = 5.2
    c_L: float = field(init=False)
    c_eta: float = field(init=False)

    def __post_init__(self) -> None:
        if not 0 < self.kl_min < 1e3 or not 0 < self.keta_max < 1e3:
            raise ValueError(
                f"kl_min and keta_max must be in (0, 1000), got {self.kl_min}, {self.keta_max}"
            )
        c_l, c_eta = self._solve_constants()
        object.__setattr__(self, "c_L", c_l)
        object.__setattr__(self, "c_eta", c_eta)
        if self.k_min >= self.k_max:
            raise ValueError(
                f"Reynolds number too low for a mode range: k_min={self.k_min:.3g} 1/m "
                f">= k_max={self.k_max:.3g} 1/m (R_lambda={self.parameters.R_lambda:.3g})"
            )

    @property
    def L(self) -> float:
        """Pope's length k_t^{3/2}/ε = 1.837 u'³/ε, m."""
        p = self.parameters
        return p.k_t**1.5 / p.epsilon

    @property
    def k_min(self) -> float:
        """Lowest mode wavenumber, 1/m."""
        return self.kl_min / self.L

    @property
    def k_max(self) -> float:
        """Highest mode wavenumber, 1/m."""
        return self.keta_max / self.parameters.eta

    def _shape(self, k: np.ndarray, c_l: float, c_eta: float) -> np.ndarray:
        p = self.parameters
        kl = k * self.L
        keta = k * p.eta
        f_l = (kl / np.sqrt(kl**2 + c_l)) ** (5.0 / 3.0 + self.p0)
        f_eta = np.exp(-self.beta * (((keta**4 + c_eta**4) ** 0.25) - c_eta))
        return self.C * p.epsilon ** (2.0 / 3.0) * k ** (-5.0 / 3.0) * f_l * f_eta

    @property
    def support(self) -> tuple[float, float]:
        """Wavenumbers (1/m) between which ∫E dk and ∫k²E dk are complete to < 1e-9."""
        return 1e-6 / self.L, 1e3 / self.parameters.eta

    def _integrals(self, c_l: float, c_eta: float) -> tuple[float, float]:
        p = self.parameters
        lo, hi = self.support
        energy = _log_integral(lambda k: self._shape(k, c_l, c_eta), lo, hi)
        dissipation = 2 * p.nu * _log_integral(lambda k: k**2 * self._shape(k, c_l, c_eta), lo, hi)
        return energy, dissipation

    def _solve_constants(self) -> tuple[float, float]:
        p = self.parameters

        def residual(x: np.ndarray) -> list[float]:
            c_l, c_eta = exp(x[0]), exp(x[1])
            energy, dissipation = self._integrals(c_l, c_eta)
            return [energy / p.k_t - 1.0, dissipation / p.epsilon - 1.0]

        sol = root(residual, x0=[log(6.78), log(0.40)], method="hybr")
        if not sol.success or max(abs(v) for v in residual(sol.x)) > 1e-8:
            raise ValueError(
                f"cannot fit Pope's spectrum to u'={p.u_rms}, epsilon={p.epsilon}, nu={p.nu} "
                f"(R_lambda={p.R_lambda:.3g}): {sol.message}"
            )
        return exp(sol.x[0]), exp(sol.x[1])

    def energy(self, k: np.ndarray) -> np.ndarray:
        """E(k), m³/s², for wavenumbers k (any shape), 1/m."""
        return self._shape(np.asarray(k, dtype=float), self.c_L, self.c_eta)

    def kinetic_energy(self) -> float:
        """∫₀^∞ E dk, m²/s² (should equal (3/2)u'²)."""
        return self._integrals(self.c_L, self.c_eta)[0]

    def dissipation(self) -> float:
        """2ν∫₀^∞ k²E dk, m²/s³ (should equal ε)."""
        return self._integrals(self.c_L, self.c_eta)[1]


@dataclass(frozen=True)
class KolmogorovBandSpectrum:
    """Band-limited Kolmogorov spectrum E = C_K ε^{2/3} k^{-5/3} on [k₁, k_N].

    k₁ and k_N solve (3/2)u'² = ∫E dk and ε = 2ν∫k²E dk exactly, so the cut-off sits
    at k_N η ≈ (2/(3 C_K))^{3/4} ≈ 0.54.

    Parameters
    ----------
    parameters : TurbulenceParameters
        Prescribed u', ε, ν.

    Examples
    --------
    The band that holds (3/2)u′² and dissipates ε ends at k_N η ≈ 0.54 (docs/flow.md
    §2.2):

    >>> import simulator
    >>> flow = simulator.flow_preset("lem-10hz").parameters
    >>> band = simulator.KolmogorovBandSpectrum(flow)
    >>> round(band.k_max * flow.eta, 3)
    0.545
    >>> round(band.kinetic_energy(), 5), round(band.dissipation(), 5)  # m²/s², m²/s³
    (0.05415, 0.17)
    """

    parameters: TurbulenceParameters
    C: float = C_KOLMOGOROV
    k_min: float = field(init=False)
    k_max: float = field(init=False)

    def __post_init__(self) -> None:
        p = self.parameters
        a = p.u_rms**2 / (self.C * p.epsilon ** (2.0 / 3.0))  # k1^{-2/3} - kN^{-2/3}
        b = 2.0 * p.epsilon ** (1.0 / 3.0) / (3.0 * self.C * p.nu)  # kN^{4/3} - k1^{4/3}
        k1, kn = 1.0 / p.L_int, 1.0 / p.eta
        for _ in range(200):
            k1_new = (a + kn ** (-2.0 / 3.0)) ** -1.5
            kn_new = (b + k1_new ** (4.0 / 3.0)) ** 0.75
            done = abs(k1_new / k1 - 1) < 1e-15 and abs(kn_new / kn - 1) < 1e-15
            k1, kn = k1_new, kn_new
            if done:
                break
        if not k1 < kn:
            raise ValueError(f"Reynolds number too low for a K41 band: R_lambda={p.R_lambda:.3g}")
        object.__setattr__(self, "k_min", k1)
        object.__setattr__(self, "k_max", kn)

    @property
    def support(self) -> tuple[float, float]:
        """Wavenumbers (1/m) outside which E = 0: (k_min, k_max)."""
        return self.k_min, self.k_max

    def energy(self, k: np.ndarray) -> np.ndarray:
        """E(k), m³/s², zero outside [k_min, k_max]; k in 1/m, any shape."""
        k = np.asarray(k, dtype=float)
        inside = (k >= self.k_min) & (k <= self.k_max)
        safe = np.where(inside, k, 1.0)
        return np.where(
            inside, self.C * self.parameters.epsilon ** (2.0 / 3.0) * safe ** (-5.0 / 3.0), 0.0
        )

    def kinetic_energy(self) -> float:
        """∫E dk in closed form, m²/s²."""
        c = 1.5 * self.C * self.parameters.epsilon ** (2.0 / 3.0)
        return c * (self.k_min ** (-2.0 / 3.0) - self.k_max ** (-2.0 / 3.0))

    def dissipation(self) -> float:
        """2ν∫k²E dk in closed form, m²/s³."""
        p = self.parameters
        c = 1.5 * self.C * p.nu * p.epsilon ** (2.0 / 3.0)
        return c * (self.k_max ** (4.0 / 3.0) - self.k_min ** (4.0 / 3.0))


Spectrum = PopeSpectrum | KolmogorovBandSpectrum

SPECTRA = {"pope": PopeSpectrum, "k41-band": KolmogorovBandSpectrum}


@dataclass(frozen=True)
class ModeSpectrum:
    """A spectrum discretised on geometric wavenumbers with trapezoid weights.

    Attributes
    ----------
    k : ndarray, shape (N,)
        Mode wavenumbers k_n = k₁ (k_N/k₁)^{(n−1)/(N−1)}, 1/m.
    dk : ndarray, shape (N,)
        Trapezoid weights (k_{n+1} − k_{n−1})/2 with half cells at the ends, 1/m.
    energy : ndarray, shape (N,)
        E(k_n) Δk_n, the kinetic energy carried by each mode, m²/s².
    """

    k: np.ndarray
    dk: np.ndarray
    energy: np.ndarray


def discretise(spectrum: Spectrum, n_modes: int) -> ModeSpectrum:
    """Lay ``n_modes`` geometric wavenumbers over the spectrum's range.

    Parameters
    ----------
    spectrum : PopeSpectrum or KolmogorovBandSpectrum
        The continuous spectrum.
    n_modes : int
        Number of modes N ≥ 2.

    Returns
    -------
    ModeSpectrum
    """
    if not isinstance(n_modes, int | np.integer) or n_modes < 2:
        raise ValueError(f"n_modes must be an integer >= 2, got {n_modes!r}")
    k = np.geomspace(spectrum.k_min, spectrum.k_max, n_modes)
    dk = np.empty_like(k)
    dk[1:-1] = 0.5 * (k[2:] - k[:-2])
    dk[0] = 0.5 * (k[1] - k[0])
    dk[-1] = 0.5 * (k[-1] - k[-2])
    return ModeSpectrum(k=k, dk=dk, energy=spectrum.energy(k) * dk)
