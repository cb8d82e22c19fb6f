"""Pixel-integrated elliptical Gaussian spots: the compiled kernels (private).

A particle image of integrated intensity F (image units, e.g. DN above background),
centre (x₀, y₀) px and covariance

    Σ = [[σ_x², ρ σ_x σ_y], [ρ σ_x σ_y, σ_y²]]  (px²)

puts on pixel (row j, column i), which covers [i − ½, i + ½] × [j − ½, j + ½],

    F · ∫∫_pixel N((x, y); (x₀, y₀), Σ) dx dy.

For ρ = 0 the integral is the exact product of erf differences (docs/imaging.md §3).
For ρ ≠ 0 each row's total is still exact (the marginal in y is N(y₀, σ_y²)); within a
row the light is shared between the columns by the conditional law of x given y,
N(x₀ + ρ σ_x/σ_y (y − y₀), σ_x²(1 − ρ²)), exact in x and integrated over the row's
height by 4-point Gauss–Legendre quadrature (relative error below 10⁻⁴ for σ ≥ 0.5 px).

Only a square window of half-width ⌈``radius_sigmas`` · max(σ_x, σ_y)⌉ around the pixel
nearest to the centre is evaluated (3.5 σ drops < 5·10⁻⁴ of F per side).
"""

from math import ceil, erfc, exp, floor, sqrt

import numpy as np
from numba import njit

_SQRT2 = sqrt(2.0)
#: 4-point Gauss–Legendre nodes and weights on [−½, ½] (weights sum to 1).
_GL_NODES = np.array(
    [-0.4305681557970263, -0.1699905217924281, 0.1699905217924281, 0.4305681557970263]
)
_GL_WEIGHTS = np.array(
    [0.1739274225687269, 0.3260725774312731, 0.3260725774312731, 0.1739274225687269]
)
#: Below this |ρ| the spot is treated as axis-aligned (exact, separable, faster).
RHO_SEPARABLE = 1e-6
#: The standard normal CDF Φ tabulated on [−_T_MAX, _T_MAX] in steps of _T_STEP, for
#: :func:`axis_fractions_fast` (linear interpolation: absolute error < 4·10⁻⁸).
_T_MAX, _T_STEP = 8.0, 1e-3
_CDF = 0.5 * np.array(
    [erfc(-t / _SQRT2) for t in np.linspace(-_T_MAX, _T_MAX, round(2 * _T_MAX / _T_STEP) + 1)]
)


@njit(cache=True, nogil=True)
def _gauss_fraction(a, b):  # pragma: no cover (compiled)
    """P(a < Z < b) for a standard normal Z, full relative precision in the tails."""
    qa = 0.5 * erfc(abs(a) / _SQRT2)
    qb = 0.5 * erfc(abs(b) / _SQRT2)
    if a >= 0.0:
        return qa - qb
    if b <= 0.0:
        return qb - qa
    return 1.0 - qa - qb


@njit(cache=True, nogil=True)
def axis_fractions(centre, sigma, lo, n, out):  # pragma: no cover (compiled)
    """Fractions of a unit 1-D Gaussian (centre, σ px) on pixels lo … lo + n − 1 → out[:n]."""
    inv = 1.0 / sigma
    prev = (lo - 0.5 - centre) * inv
    q_prev = 0.5 * erfc(abs(prev) / _SQRT2)
    for k in range(n):
        nxt = (lo + 0.5 + k - centre) * inv
        q_next = 0.5 * erfc(abs(nxt) / _SQRT2)
        if prev >= 0.0:
            out[k] = q_prev - q_next
        elif nxt <= 0.0:
            out[k] = q_next - q_prev
        else:
            out[k] = 1.0 - q_prev - q_next
        prev = nxt
        q_prev = q_next


@njit(cache=True, nogil=True)
def _cdf_fast(t):  # pragma: no cover (compiled)
    if t <= -_T_MAX:
        return 0.0
    if t >= _T_MAX:
        return 1.0
    u = (t + _T_MAX) / _T_STEP
    k = int(u)
    f = u - k
    return _CDF[k] + f * (_CDF[k + 1] - _CDF[k])


@njit(cache=True, nogil=True)
def axis_fractions_fast(centre, sigma, lo, n, out):  # pragma: no cover (compiled)
    """:func:`axis_fractions` from a table of Φ (absolute error < 10⁻⁷; for trial
    positions, where only differences of costs matter)."""
    inv = 1.0 / sigma
    prev = _cdf_fast((lo - 0.5 - centre) * inv)
    for k in range(n):
        nxt = _cdf_fast((lo + 0.5 + k - centre) * inv)
        out[k] = nxt - prev
        prev = nxt


@njit(cache=True, nogil=True)
def spot_block(x0, y0, sx, sy, rho, i0, j0, nx, ny, fx, fy, out):  # pragma: no cover
    """Unit-integral spot on columns i0 … i0 + nx − 1, rows j0 … j0 + ny − 1 → out[:ny, :nx].

    ``fx`` and ``fy`` are work arrays of at least nx and ny entries (they hold the
    per-axis fractions on return when ρ = 0).
    """
    axis_fractions(y0, sy, j0, ny, fy)
    if abs(rho) < RHO_SEPARABLE:
        axis_fractions(x0, sx, i0, nx, fx)
        for j in range(ny):
            w = fy[j]
            for i in range(nx):
                out[j, i] = w * fx[i]
        return
    slope = rho * sx / sy
    sc = sx * sqrt(1.0 - rho * rho)
    inv_sy = 1.0 / sy
    for j in range(ny):
        total = fy[j]
        for i in range(nx):
            out[j, i] = 0.0
        if total <= 0.0:
            continue
        wsum = 0.0
        for q in range(4):
            y = j0 + j + _GL_NODES[q]
            u = (y - y0) * inv_sy
            wq = _GL_WEIGHTS[q] * exp(-0.5 * u * u)
            wsum += wq
            m = x0 + slope * (y - y0)
            inv_sc = 1.0 / sc
            prev = (i0 - 0.5 - m) * inv_sc
            for i in range(nx):
                nxt = prev + inv_sc
                out[j, i] += wq * _gauss_fraction(prev, nxt)
                prev = nxt
        if wsum > 0.0:
            scale = total / wsum
            for i in range(nx):
                out[j, i] *= scale


@njit(cache=True, nogil=True)
def half_width(sx, sy, radius_sigmas):  # pragma: no cover (compiled)
    """Half-width of a spot's window, px (at least 2)."""
    r = ceil(radius_sigmas * max(sx, sy))
    return max(r, 2)


@njit(cache=True, nogil=True)
def add_spots(image, rows, cols, x, y, flux, sx, sy, rho, radius_sigmas):  # pragma: no cover
    """image[:rows, :cols] += Σ_p flux_p · spot_p (flux may be negative: subtraction).

    Spots with a NaN centre or zero flux are skipped; windows are clipped to the image.
    """
    work = 4 * ceil(radius_sigmas * 8.0) + 8
    fx = np.empty(work)
    fy = np.empty(work)
    block = np.empty((work, work))
    for p in range(x.size):
        xp = x[p]
        yp = y[p]
        f = flux[p]
        if not (np.isfinite(xp) and np.isfinite(yp)) or f == 0.0:
            continue
        r = half_width(sx[p], sy[p], radius_sigmas)
        if 2 * r + 1 > work:
            r = (work - 1) // 2
        ic = floor(xp + 0.5)
        jc = floor(yp + 0.5)
        i0 = max(ic - r, 0)
        i1 = min(ic + r, cols - 1)
        j0 = max(jc - r, 0)
        j1 = min(jc + r, rows - 1)
        if i1 < i0 or j1 < j0:
            continue
        nx = i1 - i0 + 1
        ny = j1 - j0 + 1
        spot_block(xp, yp, sx[p], sy[p], rho[p], i0, j0, nx, ny, fx, fy, block)
        for j in range(ny):
            for i in range(nx):
                image[j0 + j, i0 + i] += f * block[j, i]
