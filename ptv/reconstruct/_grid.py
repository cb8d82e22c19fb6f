"""Image points bucketed on a square grid, and the compiled searches on it (private).

Two searches: the points within a distance of a polyline segment (epipolar search) and
the nearest point within a radius of each query point (the other cameras' check).
"""

from dataclasses import dataclass
from math import floor

import numpy as np
from numba import njit


@dataclass(frozen=True, eq=False)
class PointGrid:
    """Points of one image in cells of ``cell`` px.

    Attributes
    ----------
    xy : ndarray, shape (P, 2)
        The points, px.
    order : ndarray of int64, shape (P,)
        Point indices sorted by cell (row-major cells).
    start : ndarray of int64, shape (ncy · ncx + 1,)
        Cell k holds ``order[start[k]:start[k + 1]]``.
    ncx, ncy : int
        Cells along x and y.
    cell : float
        Cell size, px.
    """

    xy: np.ndarray
    order: np.ndarray
    start: np.ndarray
    ncx: int
    ncy: int
    cell: float


def point_grid(xy: np.ndarray, shape: tuple[int, int], *, cell: float = 2.0) -> PointGrid:
    """Bucket points of an image of ``shape`` (H, W) px into square cells of ``cell`` px."""
    rows, cols = shape
    ncx = int(np.ceil((cols + 1) / cell)) + 1
    ncy = int(np.ceil((rows + 1) / cell)) + 1
    xy = np.ascontiguousarray(xy, dtype=np.float64).reshape(-1, 2)
    cx = np.clip(np.floor((xy[:, 0] + 0.5) / cell).astype(np.int64), 0, ncx - 1)
    cy = np.clip(np.floor((xy[:, 1] + 0.5) / cell).astype(np.int64), 0, ncy - 1)
    key = cy * ncx + cx
    order = np.argsort(key, kind="stable").astype(np.int64)
    start = np.zeros(ncx * ncy + 1, dtype=np.int64)
    np.cumsum(np.bincount(key, minlength=ncx * ncy), out=start[1:])
    return PointGrid(xy=xy, order=order, start=start, ncx=ncx, ncy=ncy, cell=float(cell))


@njit(cache=True, nogil=True)
def _cell_range(lo, hi, cell, n):  # pragma: no cover (compiled)
    a = floor((lo + 0.5) / cell)
    b = floor((hi + 0.5) / cell)
    return max(a, 0), min(b, n - 1)


@njit(cache=True, nogil=True)
def segment_pairs(polylines, tol, xy, order, start, ncx, ncy, cell):  # pragma: no cover
    """Points within ``tol`` px of the polylines (n, K, 2), each found on one segment.

    Returns (line index, point index, segment k, fraction u ∈ [0, 1) along it, distance).
    """
    n_lines, n_knots = polylines.shape[0], polylines.shape[1]
    cap = 4 * n_lines + 16
    li = np.empty(cap, dtype=np.int64)
    pi = np.empty(cap, dtype=np.int64)
    ki = np.empty(cap, dtype=np.int64)
    uu = np.empty(cap)
    dd = np.empty(cap)
    m = 0
    tol2 = tol * tol
    for n in range(n_lines):
        for k in range(n_knots - 1):
            ax = polylines[n, k, 0]
            ay = polylines[n, k, 1]
            bx = polylines[n, k + 1, 0]
            by = polylines[n, k + 1, 1]
            if not (np.isfinite(ax) and np.isfinite(ay) and np.isfinite(bx) and np.isfinite(by)):
                continue
            sx = bx - ax
            sy = by - ay
            len2 = sx * sx + sy * sy
            if len2 <= 0.0:
                continue
            last = k == n_knots - 2
            x0, x1 = _cell_range(min(ax, bx) - tol, max(ax, bx) + tol, cell, ncx)
            y0, y1 = _cell_range(min(ay, by) - tol, max(ay, by) + tol, cell, ncy)
            for cy in range(y0, y1 + 1):
                for cx in range(x0, x1 + 1):
                    c = cy * ncx + cx
                    for q in range(start[c], start[c + 1]):
                        p = order[q]
                        dx = xy[p, 0] - ax
                        dy = xy[p, 1] - ay
                        u = (dx * sx + dy * sy) / len2
                        if u < 0.0 or u > 1.0 or (u == 1.0 and not last):
                            continue
                        ex = dx - u * sx
                        ey = dy - u * sy
                        d2 = ex * ex + ey * ey
                        if d2 > tol2:
                            continue
                        if m == cap:
                            cap *= 2
                            li2 = np.empty(cap, dtype=np.int64)
                            pi2 = np.empty(cap, dtype=np.int64)
                            ki2 = np.empty(cap, dtype=np.int64)
                            uu2 = np.empty(cap)
                            dd2 = np.empty(cap)
                            li2[:m] = li[:m]
                            pi2[:m] = pi[:m]
                            ki2[:m] = ki[:m]
                            uu2[:m] = uu[:m]
                            dd2[:m] = dd[:m]
                            li, pi, ki, uu, dd = li2, pi2, ki2, uu2, dd2
                        li[m] = n
                        pi[m] = p
                        ki[m] = k
                        uu[m] = u
                        dd[m] = np.sqrt(d2)
                        m += 1
    return li[:m].copy(), pi[:m].copy(), ki[:m].copy(), uu[:m].copy(), dd[:m].copy()


@njit(cache=True, nogil=True)
def nearest(queries, radius, xy, order, start, ncx, ncy, cell):  # pragma: no cover
    """Index of the nearest point within ``radius[q]`` px of each query (−1: none; NaN
    queries give −1), and its distance (inf where none)."""
    nq = queries.shape[0]
    best = np.full(nq, -1, dtype=np.int64)
    dist = np.full(nq, np.inf)
    for q in range(nq):
        x = queries[q, 0]
        y = queries[q, 1]
        if not (np.isfinite(x) and np.isfinite(y)):
            continue
        r = radius[q]
        r2 = r * r
        x0, x1 = _cell_range(x - r, x + r, cell, ncx)
        y0, y1 = _cell_range(y - r, y + r, cell, ncy)
        bd = r2
        bi = -1
        for cy in range(y0, y1 + 1):
            for cx in range(x0, x1 + 1):
                c = cy * ncx + cx
                for s in range(start[c], start[c + 1]):
                    p = order[s]
                    dx = xy[p, 0] - x
                    dy = xy[p, 1] - y
                    d2 = dx * dx + dy * dy
                    if d2 <= bd:
                        bd = d2
                        bi = p
        if bi >= 0:
            best[q] = bi
            dist[q] = np.sqrt(bd)
    return best, dist
