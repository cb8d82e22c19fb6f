"""The compiled kernels of the plate renderer (:mod:`simulator.render.plate`): which dot
a sub-sample's plate point falls in, and the anti-aliased coverage of a dot's edge."""

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def _nearest(u, v, cells, pitch, off_i, off_j, dot_xy):  # pragma: no cover (compiled)
    """(dot index, distance) of the dot in the nominal cell (clipped to the grid) at uv."""
    rows, cols = cells.shape
    ci = min(max(int(np.rint(u / pitch)) + off_i, 0), cols - 1)
    cj = min(max(int(np.rint(v / pitch)) + off_j, 0), rows - 1)
    k = cells[cj, ci]
    du = u - dot_xy[k, 0]
    dv = v - dot_xy[k, 1]
    return k, np.sqrt(du * du + dv * dv)


@njit(cache=True, nogil=True)
def classify(  # pragma: no cover (compiled)
    uv, factor, cells, pitch, off_i, off_j, dot_xy, radius, edge_width, state, label,
):
    """Per pixel: 0 dark, 1 wholly inside dot ``label``, 2 needs supersampling."""
    height, width = uv.shape[0], uv.shape[1]
    half_edge = 0.5 * edge_width
    for r in range(height):
        for c in range(width):
            label[r, c] = -1
            u = uv[r, c, 0]
            v = uv[r, c, 1]
            if not np.isfinite(u):
                near = False
                if c > 0 and np.isfinite(uv[r, c - 1, 0]):
                    near = True
                if c < width - 1 and np.isfinite(uv[r, c + 1, 0]):
                    near = True
                if r > 0 and np.isfinite(uv[r - 1, c, 0]):
                    near = True
                if r < height - 1 and np.isfinite(uv[r + 1, c, 0]):
                    near = True
                state[r, c] = 2 if near else 0
                continue
            # largest distance in uv to a neighbouring pixel centre, along x and along y
            step_x = 0.0
            step_y = 0.0
            broken = False
            for dr, dc in ((0, -1), (0, 1), (-1, 0), (1, 0)):
                rr = r + dr
                cc = c + dc
                if rr < 0 or rr >= height or cc < 0 or cc >= width:
                    continue
                nu = uv[rr, cc, 0]
                nv = uv[rr, cc, 1]
                if not np.isfinite(nu):
                    broken = True
                    break
                d = np.sqrt((nu - u) ** 2 + (nv - v) ** 2)
                if dr == 0:
                    step_x = max(step_x, d)
                else:
                    step_y = max(step_y, d)
            if broken:
                state[r, c] = 2
                continue
            reach = 0.5 * (step_x + step_y) * factor + half_edge
            k, dist = _nearest(u, v, cells, pitch, off_i, off_j, dot_xy)
            if dist < radius[k] - reach:
                state[r, c] = 1
                label[r, c] = k
            elif dist > radius[k] + reach:
                state[r, c] = 0
            else:
                state[r, c] = 2


@njit(cache=True, nogil=True)
def _box_fraction(t, alpha, beta):  # pragma: no cover (compiled)
    """P(X + Y < t) for independent X ~ U(−α, α), Y ~ U(−β, β), α, β ≥ 0."""
    if alpha < beta:
        alpha, beta = beta, alpha
    if t <= -alpha - beta:
        return 0.0
    if t >= alpha + beta:
        return 1.0
    if beta <= 1e-9 * alpha:
        return (t + alpha) / (2.0 * alpha)
    if t < beta - alpha:
        return (t + alpha + beta) ** 2 / (8.0 * alpha * beta)
    if t <= alpha - beta:
        return (t + alpha) / (2.0 * alpha)
    return 1.0 - (alpha + beta - t) ** 2 / (8.0 * alpha * beta)


@njit(cache=True, nogil=True)
def coverage(  # pragma: no cover (compiled)
    uv, jac, n_sub, side, cells, pitch, off_i, off_j, dot_xy, radius, edge_width, label, weight,
):
    """Dot index and coverage in [0, 1] of every sample (−1 and 0 where none).

    Sample i belongs to pixel i // n_sub, whose Jacobian ∂(u, v)/∂(x, y) is jac[i // n_sub]
    (m/px). With a hard edge and a finite Jacobian, the coverage is the exact fraction of
    the sample's side × side square (px) inside the dot, the edge taken as straight across
    it; otherwise the dot indicator (or soft-edge ramp) at the sample point.
    """
    for i in range(uv.shape[0]):
        label[i] = -1
        weight[i] = 0.0
        u = uv[i, 0]
        v = uv[i, 1]
        if not np.isfinite(u):
            continue
        k, dist = _nearest(u, v, cells, pitch, off_i, off_j, dot_xy)
        if edge_width > 0.0:
            cover = min(max(0.5 - (dist - radius[k]) / edge_width, 0.0), 1.0)
        else:
            p = i // n_sub
            j00 = jac[p, 0, 0]
            j01 = jac[p, 0, 1]
            j10 = jac[p, 1, 0]
            j11 = jac[p, 1, 1]
            cover = 1.0 if dist < radius[k] else 0.0
            if dist > 0.0 and np.isfinite(j00 + j01 + j10 + j11):
                n0 = (u - dot_xy[k, 0]) / dist
                n1 = (v - dot_xy[k, 1]) / dist
                gx = j00 * n0 + j10 * n1  # ∂r/∂x, m/px
                gy = j01 * n0 + j11 * n1
                g = np.sqrt(gx * gx + gy * gy)
                if g > 0.0:
                    delta = (dist - radius[k]) / g  # px, > 0 outside the dot
                    half = 0.5 * side / g
                    cover = _box_fraction(-delta, half * abs(gx), half * abs(gy))
        if cover > 0.0:
            label[i] = k
            weight[i] = cover
