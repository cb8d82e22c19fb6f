"""Pope's model spectrum written apart from the simulator (Pope, *Turbulent Flows* §6.5).

    E(k) = C ε^{2/3} k^{-5/3} f_L(kL) f_η(kη),
    f_L = (kL / √((kL)² + c_L))^{5/3 + p₀},   f_η = exp(−β(((kη)⁴ + c_η⁴)^{1/4} − c_η)),

with L = k_t^{3/2}/ε, k_t = (3/2)u′², η = (ν³/ε)^{1/4} and Pope's constants C = 1.5,
p₀ = 2, β = 5.2 stated here. With those three fixed, the two conditions ∫E dk = k_t and
2ν∫k²E dk = ε fix c_L and c_η: a spectrum that matches this formula at its own c_L, c_η
and meets both conditions (by the quadrature of :func:`validation.truth.independent.
log_quadrature`, not the simulator's trapezoid rule) is Pope's spectrum of (u′, ε, ν).
"""

import numpy as np

from validation.truth.independent import log_quadrature

#: Pope's constants: the Kolmogorov constant of the 3-D spectrum, the large-scale
#: exponent p₀ and the dissipation-range β.
POPE_C = 1.5
POPE_P0 = 2.0
POPE_BETA = 5.2


def pope_energy(
    k: np.ndarray, *, u_rms: float, epsilon: float, nu: float, c_l: float, c_eta: float
) -> np.ndarray:
    """E(k) of Pope's model spectrum, m³/s², at wavenumbers k (1/m)."""
    k = np.asarray(k, dtype=float)
    length = (1.5 * u_rms**2) ** 1.5 / epsilon
    eta = (nu**3 / epsilon) ** 0.25
    kl, keta = k * length, k * eta
    f_l = (kl / np.sqrt(kl**2 + c_l)) ** (5.0 / 3.0 + POPE_P0)
    f_eta = np.exp(-POPE_BETA * ((keta**4 + c_eta**4) ** 0.25 - c_eta))
    return POPE_C * epsilon ** (2.0 / 3.0) * k ** (-5.0 / 3.0) * f_l * f_eta


def energy_and_dissipation(energy, k_lo: float, k_hi: float, nu: float) -> tuple[float, float]:
    """∫E dk and 2ν∫k²E dk over [k_lo, k_hi] of a callable E(k), m²/s² and m²/s³."""
    k, w = log_quadrature(k_lo, k_hi)
    e = energy(k)
    return float(w @ e), float(2.0 * nu * (w @ (k**2 * e)))
