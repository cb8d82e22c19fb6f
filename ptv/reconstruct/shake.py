"""Shaking: each particle moved in 3-D and its intensity refitted against the residual.

For particle p with intensity E, world position X and, in camera c, image position
x_c(X) and OTF (σ_x, σ_y, ρ, I_c), the augmented residual on its window is

    A_c = R_c + E I_c g_c(x_c(X)),

R_c being the residual image (recorded minus all projected particles, p included) and
g_c the unit-integral spot (:mod:`ptv.reconstruct._spots`). Over the windows of all
cameras, a trial position X′ with the best intensity for it leaves

    J(X′) = Σ_c Σ_px (A_c − E′ I_c g_c(x_c(X′)))²,  E′ = S₁/S₂,
    S₁ = Σ_c I_c ⟨A_c, g_c(X′)⟩,  S₂ = Σ_c I_c² ⟨g_c(X′), g_c(X′)⟩,

i.e. J = Σ A² − S₁²/S₂ (S₁ > 0). J is evaluated at X and X ± δ_k e_k for the three
world axes; a parabola through the three values on each axis gives its minimum (within
±δ_k; the best of the three where the parabola is not convex); the combined move is
evaluated too, and the best of all the evaluated positions is taken (Wieneke 2013).
The intensity is then E′ = max(S₁/S₂, 0) there, and the residual is updated,
R_c ← A_c − E′ I_c g_c. Particles are shaken one after the other, each against the
residual left by the ones before (Gauss–Seidel), so that overlapping particles share
their light correctly.

The image positions of trial points are x_c(X) + J_c ΔX with J_c = ∂x_c/∂X from
central differences of ``project`` (:meth:`ptv.reconstruct.mapping.Mappings.project_with_jacobian`),
computed for all particles in one call per camera before the passes; over a few
voxels the linearisation error is far below 10⁻³ px for a smooth mapping.
"""

import numpy as np
from numba import njit

from ptv.reconstruct._spots import axis_fractions_fast, half_width, spot_block


@njit(cache=True, nogil=True)
def _window(x, y, r, rows, cols):  # pragma: no cover (compiled)
    ic = int(np.floor(x + 0.5))
    jc = int(np.floor(y + 0.5))
    i0 = max(ic - r, 0)
    i1 = min(ic + r, cols - 1)
    j0 = max(jc - r, 0)
    j1 = min(jc + r, rows - 1)
    return i0, j0, i1 - i0 + 1, j1 - j0 + 1


@njit(cache=True, nogil=True)
def _dots(a, x, y, sx, sy, rho, i0, j0, nx, ny, fx, fy, block):  # pragma: no cover
    """(⟨a, g⟩, ⟨g, g⟩) for the unit spot g at (x, y) on the window's nx × ny pixels."""
    if rho == 0.0:
        axis_fractions_fast(x, sx, i0, nx, fx)
        axis_fractions_fast(y, sy, j0, ny, fy)
        s1 = 0.0
        for j in range(ny):
            row = 0.0
            for i in range(nx):
                row += a[j, i] * fx[i]
            s1 += row * fy[j]
        gx = 0.0
        for i in range(nx):
            gx += fx[i] * fx[i]
        gy = 0.0
        for j in range(ny):
            gy += fy[j] * fy[j]
        return s1, gx * gy
    spot_block(x, y, sx, sy, rho, i0, j0, nx, ny, fx, fy, block)
    s1 = 0.0
    s2 = 0.0
    for j in range(ny):
        for i in range(nx):
            g = block[j, i]
            s1 += a[j, i] * g
            s2 += g * g
    return s1, s2


@njit(cache=True, nogil=True)
def _trial(aug, win, ncam, cams, xy, jac, sx, sy, rho, inten, p, d0, d1, d2, fx, fy, block):
    # pragma: no cover (compiled)
    s1 = 0.0
    s2 = 0.0
    for q in range(ncam):
        c = cams[q]
        x = xy[c, p, 0] + jac[c, p, 0, 0] * d0 + jac[c, p, 0, 1] * d1 + jac[c, p, 0, 2] * d2
        y = xy[c, p, 1] + jac[c, p, 1, 0] * d0 + jac[c, p, 1, 1] * d1 + jac[c, p, 1, 2] * d2
        a, b = _dots(
            aug[q],
            x,
            y,
            sx[c, p],
            sy[c, p],
            rho[c, p],
            win[q, 0],
            win[q, 1],
            win[q, 2],
            win[q, 3],
            fx,
            fy,
            block,
        )
        s1 += inten[c, p] * a
        s2 += inten[c, p] * inten[c, p] * b
    return s1, s2


@njit(cache=True, nogil=True)
def _cost(s1, s2):  # pragma: no cover (compiled)
    if s1 <= 0.0 or s2 <= 0.0:
        return 0.0
    return -s1 * s1 / s2


@njit(cache=True, nogil=True)
def shake_pass(
    residual,
    shapes,
    points,
    energy,
    xy,
    jac,
    sx,
    sy,
    rho,
    inten,
    steps,
    active,
    radius_sigmas,
    margin,
    move_position,
):  # pragma: no cover (compiled)
    """One Gauss–Seidel pass over the active particles (module docstring).

    residual (C, H, W) and the particle arrays are updated in place: points (N, 3) m,
    energy (N,), xy (C, N, 2) px. Returns the number of cameras that saw each particle
    (N,) and its largest move, px, over the cameras.
    """
    n_cams = residual.shape[0]
    n = points.shape[0]
    wmax = 2 * (int(np.ceil(radius_sigmas * 8.0)) + margin) + 3
    aug = np.empty((n_cams, wmax, wmax))
    win = np.empty((n_cams, 4), dtype=np.int64)
    cams = np.empty(n_cams, dtype=np.int64)
    fx = np.empty(wmax)
    fy = np.empty(wmax)
    block = np.empty((wmax, wmax))
    seen = np.zeros(n, dtype=np.int64)
    moved = np.zeros(n)
    costs = np.empty(7)
    for p in range(n):
        if not active[p]:
            continue
        ncam = 0
        e_old = energy[p]
        for c in range(n_cams):
            x = xy[c, p, 0]
            y = xy[c, p, 1]
            if not (np.isfinite(x) and np.isfinite(y)) or inten[c, p] <= 0.0:
                continue
            r = min(half_width(sx[c, p], sy[c, p], radius_sigmas) + margin, (wmax - 1) // 2)
            i0, j0, nx, ny = _window(x, y, r, shapes[c, 0], shapes[c, 1])
            if nx <= 0 or ny <= 0:
                continue
            win[ncam, 0] = i0
            win[ncam, 1] = j0
            win[ncam, 2] = nx
            win[ncam, 3] = ny
            cams[ncam] = c
            spot_block(x, y, sx[c, p], sy[c, p], rho[c, p], i0, j0, nx, ny, fx, fy, block)
            f = e_old * inten[c, p]
            for j in range(ny):
                for i in range(nx):
                    aug[ncam, j, i] = residual[c, j0 + j, i0 + i] + f * block[j, i]
            ncam += 1
        seen[p] = ncam
        if ncam == 0:
            continue
        best0 = 0.0
        best1 = 0.0
        best2 = 0.0
        s1, s2 = _trial(
            aug, win, ncam, cams, xy, jac, sx, sy, rho, inten, p, 0.0, 0.0, 0.0, fx, fy, block
        )
        c0 = _cost(s1, s2)
        best_cost = c0
        best_s1 = s1
        best_s2 = s2
        if move_position:
            d = np.zeros(3)
            for k in range(3):
                for sgn in range(2):
                    dk = steps[k] if sgn == 0 else -steps[k]
                    t0 = dk if k == 0 else 0.0
                    t1 = dk if k == 1 else 0.0
                    t2 = dk if k == 2 else 0.0
                    a, b = _trial(
                        aug,
                        win,
                        ncam,
                        cams,
                        xy,
                        jac,
                        sx,
                        sy,
                        rho,
                        inten,
                        p,
                        t0,
                        t1,
                        t2,
                        fx,
                        fy,
                        block,
                    )
                    cc = _cost(a, b)
                    costs[1 + 2 * k + sgn] = cc
                    if cc < best_cost:
                        best_cost = cc
                        best_s1 = a
                        best_s2 = b
                        best0, best1, best2 = t0, t1, t2
                cp = costs[1 + 2 * k]
                cm = costs[2 + 2 * k]
                den = cp - 2.0 * c0 + cm
                if den > 0.0:
                    d[k] = min(max(0.5 * steps[k] * (cm - cp) / den, -steps[k]), steps[k])
                else:
                    d[k] = 0.0
            if d[0] != 0.0 or d[1] != 0.0 or d[2] != 0.0:
                a, b = _trial(
                    aug,
                    win,
                    ncam,
                    cams,
                    xy,
                    jac,
                    sx,
                    sy,
                    rho,
                    inten,
                    p,
                    d[0],
                    d[1],
                    d[2],
                    fx,
                    fy,
                    block,
                )
                cc = _cost(a, b)
                if cc < best_cost:
                    best_cost = cc
                    best_s1 = a
                    best_s2 = b
                    best0, best1, best2 = d[0], d[1], d[2]
        e_new = best_s1 / best_s2 if (best_s1 > 0.0 and best_s2 > 0.0) else 0.0
        points[p, 0] += best0
        points[p, 1] += best1
        points[p, 2] += best2
        energy[p] = e_new
        for q in range(ncam):
            c = cams[q]
            dx = jac[c, p, 0, 0] * best0 + jac[c, p, 0, 1] * best1 + jac[c, p, 0, 2] * best2
            dy = jac[c, p, 1, 0] * best0 + jac[c, p, 1, 1] * best1 + jac[c, p, 1, 2] * best2
            xy[c, p, 0] += dx
            xy[c, p, 1] += dy
            moved[p] = max(moved[p], np.sqrt(dx * dx + dy * dy))
            i0 = win[q, 0]
            j0 = win[q, 1]
            nx = win[q, 2]
            ny = win[q, 3]
            spot_block(
                xy[c, p, 0],
                xy[c, p, 1],
                sx[c, p],
                sy[c, p],
                rho[c, p],
                i0,
                j0,
                nx,
                ny,
                fx,
                fy,
                block,
            )
            f = e_new * inten[c, p]
            for j in range(ny):
                for i in range(nx):
                    residual[c, j0 + j, i0 + i] = aug[q, j, i] - f * block[j, i]
    return seen, moved


@njit(cache=True, nogil=True)
def camera_intensities(
    residual, shapes, energy, xy, sx, sy, rho, inten, radius_sigmas
):  # pragma: no cover (compiled)
    """Each particle's intensity as each camera alone sees it, (C, N); NaN where unseen.

    E_c = ⟨A_c, g_c⟩ / (I_c ⟨g_c, g_c⟩) on the augmented residual A_c = R_c + E I_c g_c
    (module docstring): equal to E where every camera agrees; a ghost made of other
    particles' light is much fainter in a camera where no light falls on it.
    """
    n_cams = residual.shape[0]
    n = energy.shape[0]
    wmax = 2 * int(np.ceil(radius_sigmas * 8.0)) + 3
    fx = np.empty(wmax)
    fy = np.empty(wmax)
    block = np.empty((wmax, wmax))
    out = np.full((n_cams, n), np.nan)
    for p in range(n):
        for c in range(n_cams):
            x = xy[c, p, 0]
            y = xy[c, p, 1]
            if not (np.isfinite(x) and np.isfinite(y)) or inten[c, p] <= 0.0:
                continue
            r = min(half_width(sx[c, p], sy[c, p], radius_sigmas), (wmax - 1) // 2)
            i0, j0, nx, ny = _window(x, y, r, shapes[c, 0], shapes[c, 1])
            if nx <= 0 or ny <= 0:
                continue
            spot_block(x, y, sx[c, p], sy[c, p], rho[c, p], i0, j0, nx, ny, fx, fy, block)
            f = energy[p] * inten[c, p]
            s1 = 0.0
            s2 = 0.0
            for j in range(ny):
                for i in range(nx):
                    g = block[j, i]
                    s1 += (residual[c, j0 + j, i0 + i] + f * g) * g
                    s2 += g * g
            if s2 > 0.0:
                out[c, p] = s1 / (s2 * inten[c, p])
    return out
