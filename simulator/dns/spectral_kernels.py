"""Compiled elementwise kernels of the pseudo-spectral solver (docs/dns.md §3, §4).

Each kernel fuses what NumPy would do with several full-size temporaries: the curl and the
copy of the velocity into the buffer transformed back, the cross product u × ω in place,
the projection with the 2/3 cut, and the four stage updates of the integrating-factor RK4.

Spectral arrays have shape (C, N, N, M), M = N//2 + 1, complex128. The kernels visit only
the modes kept by the 2/3 rule: rows (i, j) with ``keep_x[i] and keep_y[j]`` and, in a
row, m < ``kept_z``. Every other entry of a field is zero and stays so. Within a row the
components are swept one after the other: interleaving them in the innermost loop puts
several streams at addresses a multiple of 4 KiB apart, which was measured 5× slower.
"""

import numba
import numpy as np


@numba.njit(cache=True, nogil=True)
def velocity_and_vorticity(uh, kx, ky, kz, keep_x, keep_y, kept_z, out):
    """out[0:3] = û and out[3:6] = ik × û (the vorticity's coefficients) for m < kept_z.

    Parameters
    ----------
    uh : ndarray, shape (3, N, N, M), complex128
        Velocity coefficients (zero outside the kept modes).
    kx, ky, kz : ndarray, shapes (N,), (N,), (M,)
        Wavenumbers, 1/m.
    keep_x, keep_y : ndarray of bool, shape (N,)
        2/3-rule masks of the first two axes.
    kept_z : int
        Modes kept along the last axis (m < kept_z).
    out : ndarray, shape (6, N, N, M), complex128
        Filled in place for m < kept_z (zero on the rows cut); m ≥ kept_z is not touched.
    """
    for i in range(uh.shape[1]):
        a = kx[i]
        for j in range(uh.shape[2]):
            if not (keep_x[i] and keep_y[j]):
                for c in range(6):
                    for m in range(kept_z):
                        out[c, i, j, m] = 0.0
                continue
            b = ky[j]
            for c in range(3):
                for m in range(kept_z):
                    out[c, i, j, m] = uh[c, i, j, m]
            for m in range(kept_z):
                z = b * uh[2, i, j, m] - kz[m] * uh[1, i, j, m]
                out[3, i, j, m] = complex(-z.imag, z.real)
            for m in range(kept_z):
                z = kz[m] * uh[0, i, j, m] - a * uh[2, i, j, m]
                out[4, i, j, m] = complex(-z.imag, z.real)
            for m in range(kept_z):
                z = a * uh[1, i, j, m] - b * uh[0, i, j, m]
                out[5, i, j, m] = complex(-z.imag, z.real)


@numba.njit(cache=True, nogil=True)
def cross_in_place(p):
    """p[3:6] ← p[0:3] × p[3:6] point by point (u × ω); returns max(|u| + |v| + |w|).

    Parameters
    ----------
    p : ndarray, shape (6, P), float64
        Velocity (rows 0–2, m/s) and vorticity (rows 3–5, 1/s) at P points.
    """
    speed = 0.0
    for q in range(p.shape[1]):
        u, v, w = p[0, q], p[1, q], p[2, q]
        a, b, c = p[3, q], p[4, q], p[5, q]
        p[3, q] = v * c - w * b
        p[4, q] = w * a - u * c
        p[5, q] = u * b - v * a
        speed = max(speed, abs(u) + abs(v) + abs(w))
    return speed


@numba.njit(cache=True, nogil=True)
def speed_sum_max(u):
    """max(|u| + |v| + |w|) over the points of u, shape (3, P), m/s."""
    speed = 0.0
    for q in range(u.shape[1]):
        speed = max(speed, abs(u[0, q]) + abs(u[1, q]) + abs(u[2, q]))
    return speed


@numba.njit(cache=True, nogil=True)
def project_dealias(ch, kx, ky, kz, keep_x, keep_y, kept_z):
    """ĉ ← P(k) ĉ on the kept modes, 0 on every other entry and at k = 0, in place.

    P(k) = I − k kᵀ/|k|² removes the gradient part (the pressure).

    Parameters
    ----------
    ch : ndarray, shape (3, N, N, M), complex128
        Coefficients of u × ω (any values outside the kept modes), replaced by the
        nonlinear tendency.
    kx, ky, kz : ndarray, shapes (N,), (N,), (M,)
        Wavenumbers, 1/m.
    keep_x, keep_y : ndarray of bool, shape (N,)
        2/3-rule masks of the first two axes.
    kept_z : int
        Modes kept along the last axis.
    """
    dot = np.empty(kept_z, np.complex128)
    for i in range(ch.shape[1]):
        a = kx[i]
        for j in range(ch.shape[2]):
            if not (keep_x[i] and keep_y[j]):
                ch[:, i, j, :] = 0.0
                continue
            b = ky[j]
            for m in range(kept_z):
                k2 = a * a + b * b + kz[m] * kz[m]
                if k2 > 0.0:
                    dot[m] = (a * ch[0, i, j, m] + b * ch[1, i, j, m] + kz[m] * ch[2, i, j, m]) / k2
                else:
                    dot[m] = 0.0
            for m in range(kept_z):
                ch[0, i, j, m] -= a * dot[m]
            for m in range(kept_z):
                ch[1, i, j, m] -= b * dot[m]
            for m in range(kept_z):
                ch[2, i, j, m] -= kz[m] * dot[m]
            ch[:, i, j, kept_z:] = 0.0
    ch[:, 0, 0, 0] = 0.0


@numba.njit(cache=True, nogil=True)
def rk_first(u0, k1, e_full, e_half, h, keep_x, keep_y, kept_z, acc, us):
    """After stage 1: acc = E(h)(û₀ + h/6 k₁), us = E(h/2)(û₀ + h/2 k₁) on the kept modes.

    E = exp(−ν|k|²τ) are the integrating factors, shape (N, N, M); the others are
    spectral vector fields, shape (3, N, N, M). acc and us are zero elsewhere already.
    """
    for i in range(u0.shape[1]):
        for j in range(u0.shape[2]):
            if keep_x[i] and keep_y[j]:
                for c in range(3):
                    for m in range(kept_z):
                        a, k = u0[c, i, j, m], k1[c, i, j, m]
                        acc[c, i, j, m] = e_full[i, j, m] * (a + (h / 6.0) * k)
                        us[c, i, j, m] = e_half[i, j, m] * (a + (h / 2.0) * k)


@numba.njit(cache=True, nogil=True)
def rk_second(u0, k2, e_half, h, keep_x, keep_y, kept_z, acc, us):
    """After stage 2: acc += h/3 E(h/2) k₂, us = E(h/2) û₀ + h/2 k₂ on the kept modes."""
    for i in range(u0.shape[1]):
        for j in range(u0.shape[2]):
            if keep_x[i] and keep_y[j]:
                for c in range(3):
                    for m in range(kept_z):
                        e, k = e_half[i, j, m], k2[c, i, j, m]
                        acc[c, i, j, m] += (h / 3.0) * e * k
                        us[c, i, j, m] = e * u0[c, i, j, m] + (h / 2.0) * k


@numba.njit(cache=True, nogil=True)
def rk_third(u0, k3, e_full, e_half, h, keep_x, keep_y, kept_z, acc, us):
    """After stage 3: acc += h/3 E(h/2) k₃, us = E(h) û₀ + h E(h/2) k₃ on the kept modes."""
    for i in range(u0.shape[1]):
        for j in range(u0.shape[2]):
            if keep_x[i] and keep_y[j]:
                for c in range(3):
                    for m in range(kept_z):
                        e, k = e_half[i, j, m], k3[c, i, j, m]
                        acc[c, i, j, m] += (h / 3.0) * e * k
                        us[c, i, j, m] = e_full[i, j, m] * u0[c, i, j, m] + h * e * k


@numba.njit(cache=True, nogil=True)
def rk_fourth(k4, h, keep_x, keep_y, kept_z, acc):
    """After stage 4: acc += h/6 k₄ on the kept modes (acc is then û at t + h)."""
    for i in range(acc.shape[1]):
        for j in range(acc.shape[2]):
            if keep_x[i] and keep_y[j]:
                for c in range(3):
                    for m in range(kept_z):
                        acc[c, i, j, m] += (h / 6.0) * k4[c, i, j, m]


@numba.njit(cache=True, nogil=True)
def weighted_sums(uh, kx, ky, kz, weights):
    """Σ w|û|², Σ w|k|²|û|² and Σ w|û|²/|k| over the half spectrum (k ≠ 0 for the last).

    weights (shape (M,)) counts each coefficient with its complex conjugate.
    """
    energy = 0.0
    enstrophy = 0.0
    inverse = 0.0
    for i in range(uh.shape[1]):
        for j in range(uh.shape[2]):
            for m in range(uh.shape[3]):
                a = 0.0
                for c in range(3):
                    z = uh[c, i, j, m]
                    a += z.real * z.real + z.imag * z.imag
                a *= weights[m]
                k2 = kx[i] * kx[i] + ky[j] * ky[j] + kz[m] * kz[m]
                energy += a
                enstrophy += k2 * a
                if k2 > 0.0:
                    inverse += a / np.sqrt(k2)
    return energy, enstrophy, inverse
