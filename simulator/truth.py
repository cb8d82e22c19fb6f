"""Exact second-order ground truth of a spectrum (docs/flow.md §3).

For isotropic turbulence with energy spectrum E(k),

    D_LL(r) = 4 ∫₀^∞ E(k) G(kr) dk,   G(x) = 1/3 − (sin x − x cos x)/x³,

which tends to 2u'² as r → ∞ and to ε r²/(15ν) as r → 0 (ε = 2ν∫k²E dk).
"""

from math import factorial

import numpy as np

from simulator.spectra import Spectrum

#: Below this argument G(x) uses its Taylor series, which avoids the cancellation of the
#: closed form (relative error ~1e-16/x² there); 8 terms are exact to 1e-16 at x = 0.5.
_SERIES_BELOW = 0.5
#: Coefficients of G(x) = Σ_{n≥2} (−1)ⁿ 2n x^{2n−2}/(2n+1)!, in powers of x², from x².
_SERIES = tuple((-1) ** n * 2 * n / factorial(2 * n + 1) for n in range(2, 10))


def structure_kernel(x: np.ndarray) -> np.ndarray:
    """G(x) = 1/3 − (sin x − x cos x)/x³, accurate for all x ≥ 0 (any shape)."""
    x = np.asarray(x, dtype=float)
    small = np.abs(x) < _SERIES_BELOW
    safe = np.where(small, 1.0, x)
    exact = 1.0 / 3.0 - (np.sin(safe) - safe * np.cos(safe)) / safe**3
    x2 = x * x
    series = np.zeros_like(x2)
    for c in reversed(_SERIES):
        series = series * x2 + c
    return np.where(small, series * x2, exact)


def longitudinal_structure_function(
    spectrum: Spectrum, r: np.ndarray, *, points: int = 40001
) -> np.ndarray:
    """Exact D_LL(r) of a continuous spectrum, m²/s².

    Parameters
    ----------
    spectrum : PopeSpectrum or KolmogorovBandSpectrum
        The spectrum; integrated over its support ``spectrum.support``.
    r : array_like
        Separations, m (any shape, r ≥ 0).
    points : int
        Nodes of the trapezoid rule on the logarithmic k grid.

    Returns
    -------
    ndarray
        D_LL(r), same shape as r.

    Examples
    --------
    D_LL of Pope's spectrum for the 10 Hz condition: it tends to ε r²/(15ν) at small r
    and to 2u′² at large r (docs/flow.md §3.1).

    >>> import simulator
    >>> flow = simulator.flow_preset("lem-10hz").parameters
    >>> spectrum = simulator.PopeSpectrum(flow)
    >>> simulator.exact_dll(spectrum, [1e-3, 1e-2]).round(5)  # m²/s²
    array([0.00393, 0.02447])
    >>> r = 1e-6  # m
    >>> round(float(simulator.exact_dll(spectrum, r) / (flow.epsilon * r**2 / (15 * flow.nu))), 4)
    1.0
    >>> round(float(simulator.exact_dll(spectrum, 100.0) / (2 * flow.u_rms**2)), 4)
    1.0
    """
    r = np.asarray(r, dtype=float)
    if np.any(~np.isfinite(r)) or np.any(r < 0):
        raise ValueError("separations must be finite and >= 0")
    k_lo, k_hi = spectrum.support
    s = np.linspace(np.log(k_lo), np.log(k_hi), points)
    k = np.exp(s)
    weight = spectrum.energy(k) * k  # dk = k ds
    flat = r.reshape(-1)
    out = np.empty(flat.shape)
    for lo in range(0, flat.size, 64):  # bound the (r, k) temporary
        g = structure_kernel(np.multiply.outer(flat[lo : lo + 64], k))
        out[lo : lo + 64] = 4.0 * np.trapezoid(g * weight, s, axis=-1)
    return out.reshape(r.shape)
