"""Periodic spectral fields at arbitrary points, by B-spline interpolation.

A field sampled on the periodic grid x_i = i L/N (i = 0 … N − 1 per axis) is represented by
the periodic spline of degree n (3: cubic, 5: quintic) through its N³ samples,

    s(x) = Σ_{i,j,l} c_{ijl} β_n(x/Δ − i) β_n(y/Δ − j) β_n(z/Δ − l),   Δ = L/N,

with the coefficients c periodic in i, j, l. The interpolation condition s(x_i) = f_i is a
circular convolution of c with the samples of β_n at the integers, so it is diagonal in
Fourier space: per axis, ĉ = f̂ / B_n(θ) with θ = 2πm/N = k Δ and

    B_3(θ) = 2/3 + (1/3) cos θ,
    B_5(θ) = 11/20 + (13/30) cos θ + (1/60) cos 2θ,

the discrete transforms of β_3 (1/6, 2/3, 1/6) and β_5 (1/120, 13/60, 11/20, 13/60, 1/120).
Both are positive for all θ (minimum at θ = π: 1/3 and 2/15), so the prefilter is always
defined. :func:`spline_coefficients` applies it to the ``scipy.fft.rfftn`` coefficients of
the field; :func:`interpolate` evaluates the spline at points anywhere in space (the box
tiles space periodically).

A Fourier mode e^{ikx} with θ = kΔ is reproduced with a relative error of order θ^{n+1}: at
the 2/3-rule cutoff θ = 2π/3 it is 9 % rms (cubic) and 2 % rms (quintic) along one axis, but
the dissipation-range spectrum there carries little energy. Against the exact Fourier sum
of random dealiased fields with k_max η = 1.5 (tests/simulator/dns/test_interpolate.py),
the rms error over the rms of the field is, on 32³ and 64³ grids (mean of 3 fields):

========================================  ==============  ================
field, spectrum                           cubic           quintic
========================================  ==============  ================
u, E ∝ k^{-5/3} e^{−5.2kη}                0.042, 0.025 %  0.0057, 0.0037 %
u, von Kármán–Pao, peak at k = 2 (2π/L)   0.15, 0.076 %   0.021, 0.011 %
∇u, E ∝ k^{-5/3} e^{−5.2kη}               0.25, 0.23 %    0.037, 0.038 %
∇u, von Kármán–Pao                        0.50, 0.36 %    0.075, 0.059 %
========================================  ==============  ================

Against a target of 0.1 %, the cubic spline fails for velocity gradients and for the
velocity of a DNS-like spectrum on 32³; the quintic one meets all, at about twice the cost
(benchmarks/bench_interp.py), hence the default.
"""

import numpy as np
import scipy.fft

from simulator.dns import interp_kernels

#: Spline degrees available: cubic and quintic.
ORDERS = (3, 5)

#: Default degree: quintic, the one that meets 0.1 % for velocity gradients (module docstring).
DEFAULT_ORDER = 5

_KERNELS = {3: interp_kernels.interpolate_cubic, 5: interp_kernels.interpolate_quintic}

#: Beyond this many grid spacings from the origin a float64 position has no sub-cell
#: resolution left (its spacing is ≥ Δ).
_MAX_CELLS = 2.0**52


def _check_order(order: int) -> None:
    if order not in ORDERS:
        raise ValueError(f"order must be one of {ORDERS}, got {order!r}")


def bspline_symbol(order: int, theta: np.ndarray) -> np.ndarray:
    """Discrete Fourier transform of the B-spline's samples at the integers.

    Parameters
    ----------
    order : {3, 5}
        Spline degree.
    theta : ndarray
        Phase per grid spacing, θ = kΔ, rad.

    Returns
    -------
    ndarray, shape of ``theta``
        B_n(θ) = Σ_j β_n(j) e^{−ijθ} (real and even), dimensionless.
    """
    _check_order(order)
    if order == 3:
        return 2.0 / 3.0 + np.cos(theta) / 3.0
    return 11.0 / 20.0 + (13.0 / 30.0) * np.cos(theta) + np.cos(2.0 * theta) / 60.0


def spline_coefficients(
    field_hat: np.ndarray, *, order: int = DEFAULT_ORDER, workers: int | None = None
) -> np.ndarray:
    """Periodic B-spline coefficients of a field given by its Fourier coefficients.

    Parameters
    ----------
    field_hat : ndarray of complex, shape (C, N, N, N//2 + 1)
        ``scipy.fft.rfftn`` of a real (C, N, N, N) field over its three spatial axes,
        'backward' normalisation (units of the field).
    order : {3, 5}, optional
        Spline degree (default :data:`DEFAULT_ORDER`). Pass the same to :func:`interpolate`.
    workers : int, optional
        Threads for the inverse FFTs (``scipy.fft``'s ``workers``).

    Returns
    -------
    ndarray of float64, shape (N, N, N, C), C-contiguous
        Coefficients c[i_x, i_y, i_z, component] whose spline interpolates the field at the
        grid nodes (units of the field).

    Raises
    ------
    ValueError
        If ``field_hat`` is not a (C, N, N, N//2 + 1) array or ``order`` is not 3 or 5.
    """
    _check_order(order)
    field_hat = np.asarray(field_hat)
    shape = field_hat.shape
    if (
        field_hat.ndim != 4
        or shape[0] < 1
        or shape[1] < 1
        or shape[2] != shape[1]
        or shape[3] != shape[1] // 2 + 1
    ):
        raise ValueError(f"field_hat must have shape (C, N, N, N//2 + 1), got {shape}")
    n = shape[1]
    theta = 2.0 * np.pi * np.fft.fftfreq(n)
    theta_z = 2.0 * np.pi * np.fft.rfftfreq(n)
    b_xy = bspline_symbol(order, theta)
    inverse = 1.0 / (
        b_xy[:, None, None] * b_xy[None, :, None] * bspline_symbol(order, theta_z)[None, None, :]
    )
    coeffs = np.empty((n, n, n, shape[0]))
    for c in range(shape[0]):
        coeffs[..., c] = scipy.fft.irfftn(field_hat[c] * inverse, s=(n, n, n), workers=workers)
    return coeffs


def interpolate(
    coeffs: np.ndarray, box_side: float, points: np.ndarray, *, order: int = DEFAULT_ORDER
) -> np.ndarray:
    """A periodic spline field at points anywhere in space.

    Parameters
    ----------
    coeffs : ndarray of float64, shape (N, N, N, C)
        Spline coefficients from :func:`spline_coefficients` with the same ``order``
        (units of the field). Other layouts or dtypes are copied on every call.
    box_side : float
        Side L of the periodic box, m.
    points : ndarray, shape (P, 3)
        Positions, m; any finite values (the box tiles space), within 2**52 grid spacings
        of the origin.
    order : {3, 5}, optional
        Spline degree (default :data:`DEFAULT_ORDER`).

    Returns
    -------
    ndarray of float64, shape (P, C)
        The field's spline at the points (units of the field).

    Raises
    ------
    ValueError
        If an argument has the wrong shape, ``box_side`` is not positive and finite, or a
        point is not finite or too far from the origin.
    """
    _check_order(order)
    coeffs = np.ascontiguousarray(coeffs, dtype=np.float64)
    shape = coeffs.shape
    if coeffs.ndim != 4 or shape[0] < 1 or shape[3] < 1 or not shape[0] == shape[1] == shape[2]:
        raise ValueError(f"coeffs must have shape (N, N, N, C), got {shape}")
    if not (np.isfinite(box_side) and box_side > 0):
        raise ValueError(f"box_side must be positive and finite, got {box_side!r}")
    points = np.ascontiguousarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"points must have shape (P, 3), got {points.shape}")
    if not np.isfinite(points).all():
        raise ValueError("points must be finite (found NaN or inf)")
    inv_dx = shape[0] / float(box_side)
    if points.size and np.abs(points).max() * inv_dx >= _MAX_CELLS:
        raise ValueError("points must lie within 2**52 grid spacings of the origin")
    return _KERNELS[order](coeffs, inv_dx, points)
