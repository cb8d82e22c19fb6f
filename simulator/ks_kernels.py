"""Compiled kernels for kinematic-simulation fields (numba).

The field is u(x, t) = Σ_n A_n cos θ_n + B_n sin θ_n with θ_n = k_n·x + φ_n(t), where the
caller supplies the temporal phase φ_n = ω_n t reduced modulo 2π.

Particles are processed in blocks: the outer loop runs over modes and the inner loop over
the particles of a block, which LLVM vectorises without reassociating any reduction. The
sine and cosine come from :func:`_sincos`, an inline branch-free routine (Cody–Waite
reduction by π/2 in three 33-bit pieces, then the minimax kernels of fdlibm on
[−π/4, π/4]), accurate to a few ulp for |θ| < 2^20 rad. Blocks are distributed over
threads: with ``prange`` in :func:`velocity`, and by :func:`simulator._threads.over_threads`
in the two kernels a run compiles, :func:`velocity_derivatives` and
:func:`rk4_trajectories`, which compile 2-3 times faster that way (same bits, same speed).
"""

import numpy as np
from numba import njit, prange

from simulator._threads import over_threads

#: Particles per block: the block's coordinates and accumulators stay in L1.
BLOCK = 128

_TWO_OVER_PI = 6.36619772367581382433e-01
_PIO2_1 = 1.57079632673412561417e00
_PIO2_2 = 6.07710050630396597660e-11
_PIO2_3 = 2.02226624871116645580e-21
_S1 = -1.66666666666666324348e-01
_S2 = 8.33333333332248946124e-03
_S3 = -1.98412698298579493134e-04
_S4 = 2.75573137070700676789e-06
_S5 = -2.50507602534068634195e-08
_S6 = 1.58969099521155010221e-10
_C1 = 4.16666666666666019037e-02
_C2 = -1.38888888888741095749e-03
_C3 = 2.48015872894767294178e-05
_C4 = -2.75573143513906633035e-07
_C5 = 2.08757232129817482790e-09
_C6 = -1.13596475577881948265e-11

_FLAGS = {"contract", "nsz", "arcp"}


@njit(inline="always", fastmath=_FLAGS)
def _sincos(theta):
    n = np.floor(theta * _TWO_OVER_PI + 0.5)
    r = ((theta - n * _PIO2_1) - n * _PIO2_2) - n * _PIO2_3
    z = r * r
    s = r + r * z * (_S1 + z * (_S2 + z * (_S3 + z * (_S4 + z * (_S5 + z * _S6)))))
    c = 1.0 - 0.5 * z + z * z * (_C1 + z * (_C2 + z * (_C3 + z * (_C4 + z * (_C5 + z * _C6)))))
    q = np.int64(n) & 3
    swap = q & 1
    sin_r = c if swap else s
    cos_r = s if swap else c
    sin_sign = 1.0 - 2.0 * ((q >> 1) & 1)
    cos_sign = 1.0 - 2.0 * (((q + 1) >> 1) & 1)
    return sin_sign * sin_r, cos_sign * cos_r


@njit(fastmath=_FLAGS, cache=True)
def sincos_array(theta):
    """Sine and cosine of a 1-D float64 array (for tests of :func:`_sincos`)."""
    s = np.empty_like(theta)
    c = np.empty_like(theta)
    for i in range(theta.size):
        s[i], c[i] = _sincos(theta[i])
    return s, c


@njit(inline="always", fastmath=_FLAGS)
def _block_velocity(xs, ys, zs, m, phase, k, a, b, ux, uy, uz):
    """u at the first m particles of a block (xs, ys, zs) into (ux, uy, uz)."""
    for i in range(m):
        ux[i] = 0.0
        uy[i] = 0.0
        uz[i] = 0.0
    for n in range(k.shape[0]):
        kx, ky, kz, ph = k[n, 0], k[n, 1], k[n, 2], phase[n]
        ax, ay, az = a[n, 0], a[n, 1], a[n, 2]
        bx, by, bz = b[n, 0], b[n, 1], b[n, 2]
        for i in range(m):
            s, c = _sincos(kx * xs[i] + ky * ys[i] + kz * zs[i] + ph)
            ux[i] += ax * c + bx * s
            uy[i] += ay * c + by * s
            uz[i] += az * c + bz * s


@njit(parallel=True, fastmath=_FLAGS, cache=True)
def velocity(x, phase, k, a, b):
    """Velocity at points.

    Parameters
    ----------
    x : ndarray, shape (P, 3)
        Positions, m.
    phase : ndarray, shape (N,)
        Temporal phases ω_n t mod 2π, rad.
    k, a, b : ndarray, shape (N, 3)
        Wavevectors (1/m) and the cosine and sine amplitudes (m/s).

    Returns
    -------
    ndarray, shape (P, 3)
        u(x, t), m/s.
    """
    p = x.shape[0]
    out = np.empty((p, 3))
    for blk in prange((p + BLOCK - 1) // BLOCK):
        lo = blk * BLOCK
        m = min(BLOCK, p - lo)
        xs, ys, zs = np.empty(BLOCK), np.empty(BLOCK), np.empty(BLOCK)
        ux, uy, uz = np.empty(BLOCK), np.empty(BLOCK), np.empty(BLOCK)
        for i in range(m):
            xs[i], ys[i], zs[i] = x[lo + i, 0], x[lo + i, 1], x[lo + i, 2]
        _block_velocity(xs, ys, zs, m, phase, k, a, b, ux, uy, uz)
        for i in range(m):
            out[lo + i, 0], out[lo + i, 1], out[lo + i, 2] = ux[i], uy[i], uz[i]
    return out


def velocity_derivatives(x, phase, k, a, b, omega, u, dudt, grad, accel):
    """Velocity, ∂u/∂t, gradient and Lagrangian acceleration at points, from one sincos.

    Parameters
    ----------
    x : ndarray, shape (P, 3)
        Positions, m.
    phase : ndarray, shape (N,)
        Temporal phases ω_n t mod 2π, rad.
    k, a, b : ndarray, shape (N, 3)
        Wavevectors (1/m) and amplitudes (m/s).
    omega : ndarray, shape (N,)
        Angular frequencies ω_n, rad/s.
    u : ndarray, shape (P, 3)
        Output: velocity, m/s.
    dudt : ndarray, shape (P, 3)
        Output: ∂u/∂t = Σ ω_n (B_n cos θ_n − A_n sin θ_n), m/s².
    grad : ndarray, shape (P, 3, 3)
        Output: grad[p, i, j] = ∂u_i/∂x_j = Σ k_nj (B_ni cos θ_n − A_ni sin θ_n), 1/s.
    accel : ndarray, shape (P, 3)
        Output: a = ∂u/∂t + (u·∇)u, m/s².
    """
    over_threads(
        _derivative_blocks,
        (x.shape[0] + BLOCK - 1) // BLOCK,
        x,
        phase,
        k,
        a,
        b,
        omega,
        u,
        dudt,
        grad,
        accel,
    )


@njit(fastmath=_FLAGS, cache=True, nogil=True, error_model="numpy")
def _derivative_blocks(first, stop, x, phase, k, a, b, omega, u, dudt, grad, accel):
    """Blocks ``first … stop − 1`` of :func:`velocity_derivatives`."""
    p = x.shape[0]
    for blk in range(first, stop):
        lo = blk * BLOCK
        m = min(BLOCK, p - lo)
        xs, ys, zs = np.empty(BLOCK), np.empty(BLOCK), np.empty(BLOCK)
        acc = np.zeros((15, BLOCK))
        for i in range(m):
            xs[i], ys[i], zs[i] = x[lo + i, 0], x[lo + i, 1], x[lo + i, 2]
        for n in range(k.shape[0]):
            kx, ky, kz, ph, w = k[n, 0], k[n, 1], k[n, 2], phase[n], omega[n]
            ax, ay, az = a[n, 0], a[n, 1], a[n, 2]
            bx, by, bz = b[n, 0], b[n, 1], b[n, 2]
            for i in range(m):
                s, c = _sincos(kx * xs[i] + ky * ys[i] + kz * zs[i] + ph)
                acc[0, i] += ax * c + bx * s
                acc[1, i] += ay * c + by * s
                acc[2, i] += az * c + bz * s
                dx = bx * c - ax * s
                dy = by * c - ay * s
                dz = bz * c - az * s
                acc[3, i] += w * dx
                acc[4, i] += w * dy
                acc[5, i] += w * dz
                acc[6, i] += kx * dx
                acc[7, i] += ky * dx
                acc[8, i] += kz * dx
                acc[9, i] += kx * dy
                acc[10, i] += ky * dy
                acc[11, i] += kz * dy
                acc[12, i] += kx * dz
                acc[13, i] += ky * dz
                acc[14, i] += kz * dz
        for i in range(m):
            for j in range(3):
                u[lo + i, j] = acc[j, i]
                dudt[lo + i, j] = acc[3 + j, i]
                advection = 0.0
                for q in range(3):
                    grad[lo + i, j, q] = acc[6 + 3 * j + q, i]
                    advection += acc[6 + 3 * j + q, i] * acc[q, i]
                accel[lo + i, j] = acc[3 + j, i] + advection


def rk4_trajectories(x0, phases, steps, record, k, a, b):
    """Integrate dX/dt = u(X, t) with classical RK4 and record positions.

    Parameters
    ----------
    x0 : ndarray, shape (P, 3)
        Initial positions, m.
    phases : ndarray, shape (2 S + 1, N)
        Temporal phases (ω_n t mod 2π) at the stage times of the S steps: row 2s is the
        start of step s, row 2s + 1 its midpoint, row 2s + 2 its end.
    steps : ndarray, shape (S,)
        Step lengths h_s, s.
    record : ndarray of int64, shape (R,)
        Indices of the step ends to record, in increasing order (0 = the start).

    Returns
    -------
    ndarray, shape (R, P, 3)
        Positions at the recorded times, m.
    """
    p = x0.shape[0]
    out = np.empty((record.shape[0], p, 3))
    over_threads(_rk4_blocks, (p + BLOCK - 1) // BLOCK, x0, phases, steps, record, k, a, b, out)
    return out


@njit(fastmath=_FLAGS, cache=True, nogil=True, error_model="numpy")
def _rk4_blocks(first, stop, x0, phases, steps, record, k, a, b, out):
    """Blocks ``first … stop − 1`` of :func:`rk4_trajectories`, into ``out``."""
    p = x0.shape[0]
    for blk in range(first, stop):
        lo = blk * BLOCK
        m = min(BLOCK, p - lo)
        pos = np.empty((3, BLOCK))
        tmp = np.empty((3, BLOCK))
        acc = np.empty((3, BLOCK))
        kv = np.empty((3, BLOCK))
        for i in range(m):
            for j in range(3):
                pos[j, i] = x0[lo + i, j]
        r = 0
        if record[0] == 0:
            for i in range(m):
                for j in range(3):
                    out[0, lo + i, j] = pos[j, i]
            r = 1
        for s in range(steps.shape[0]):
            h = steps[s]
            _block_velocity(pos[0], pos[1], pos[2], m, phases[2 * s], k, a, b, kv[0], kv[1], kv[2])
            for j in range(3):
                for i in range(m):
                    acc[j, i] = kv[j, i]
                    tmp[j, i] = pos[j, i] + 0.5 * h * kv[j, i]
            _block_velocity(
                tmp[0], tmp[1], tmp[2], m, phases[2 * s + 1], k, a, b, kv[0], kv[1], kv[2]
            )
            for j in range(3):
                for i in range(m):
                    acc[j, i] += 2.0 * kv[j, i]
                    tmp[j, i] = pos[j, i] + 0.5 * h * kv[j, i]
            _block_velocity(
                tmp[0], tmp[1], tmp[2], m, phases[2 * s + 1], k, a, b, kv[0], kv[1], kv[2]
            )
            for j in range(3):
                for i in range(m):
                    acc[j, i] += 2.0 * kv[j, i]
                    tmp[j, i] = pos[j, i] + h * kv[j, i]
            _block_velocity(
                tmp[0], tmp[1], tmp[2], m, phases[2 * s + 2], k, a, b, kv[0], kv[1], kv[2]
            )
            for j in range(3):
                for i in range(m):
                    pos[j, i] += h / 6.0 * (acc[j, i] + kv[j, i])
            if r < record.shape[0] and record[r] == s + 1:
                for i in range(m):
                    for j in range(3):
                        out[r, lo + i, j] = pos[j, i]
                r += 1
