"""Compiled (numba) kernels of the particle detector (private).

Three passes:

1. :func:`local_maxima`: one raster scan; a pixel is a maximum when it is above the
   threshold, strictly brighter than its already-scanned 8-neighbours and at least as
   bright as the others (so a plateau yields one maximum, its first pixel in raster
   order).
2. :func:`regions`: 8-connected flood fill above threshold from each maximum; the
   pixel list doubles as the breadth-first queue, so only the pixels of the particles
   are visited.
3. :func:`measure`: per region, keep the maxima separated from every brighter kept one
   by a dip (minimum on the straight line between them), give each pixel to the
   nearest kept maximum, and measure each particle (centre, integrated intensity,
   peak, size, flags); for the "gauss" estimator, fit the log-quadratics and, in split
   regions, refit each after subtracting the others' fits. The cost is linear in the
   pixels above threshold except in regions with several maxima (quadratic in their
   number, which is capped by :data:`MAX_SPLIT`).

The least-squares refinement that follows is in :mod:`ptv.detect._refine`.

Flag bits and estimator codes mirror :class:`ptv.detect.DetectionFlag` and the
estimator names of :func:`ptv.detect.detect_particles`.
"""

from math import exp, floor, log, sqrt

import numpy as np
from numba import njit, types

OVERLAP = 1
ELONGATED = 2
SATURATED = 4
EDGE = 8
FALLBACK = 16

CENTROID = 0
GAUSS3 = 1
GAUSS = 2

#: Regions with more local maxima than this are not split (one detection, ELONGATED):
#: splitting costs O(maxima²) line scans and O(pixels × maxima) assignments.
MAX_SPLIT = 64
#: Deblending passes of the "gauss" estimator in regions split between several maxima.
_DEBLEND_PASSES = 2
#: Beyond this many px from its maximum a fitted spot is taken as dark (deblending).
_MODEL_REACH = 4

#: Entries of the packed normal equations of the 5-parameter fits: 15 of the
#: symmetric 5 × 5 matrix (upper triangle, row by row) and 5 of the right-hand side.
_N_LSQ = 20


@njit(cache=True, inline="always")
def _axis(pos, n_tiles, n_px):  # pragma: no cover (compiled)
    """Lower node, upper node and weight of the upper, between tile centres."""
    t = (pos + 0.5) * (n_tiles / n_px) - 0.5
    if t < 0.0:
        t = 0.0
    top = n_tiles - 1.0
    if t > top:
        t = top
    i0 = int(t)
    if i0 > n_tiles - 2:
        i0 = max(n_tiles - 2, 0)
    i1 = min(i0 + 1, n_tiles - 1)
    return i0, i1, t - i0


@njit(cache=True)
def grid_at(grid, r, c, rows, cols):  # pragma: no cover (compiled)
    """Bilinear value of a tile grid at pixel (row r, column c)."""
    gy, gx = grid.shape
    if gy == 1 and gx == 1:
        return grid[0, 0]
    y0, y1, a = _axis(r, gy, rows)
    x0, x1, b = _axis(c, gx, cols)
    top = grid[y0, x0] * (1.0 - b) + grid[y0, x1] * b
    bottom = grid[y1, x0] * (1.0 - b) + grid[y1, x1] * b
    return top * (1.0 - a) + bottom * a


@njit(cache=True)
def _grow(arr, size):  # pragma: no cover (compiled)
    out = np.empty(size, arr.dtype)
    out[: arr.size] = arr
    return out


@njit(cache=True)
def local_maxima(img, thr_grid, t_min):  # pragma: no cover (compiled)
    """Rows and columns of the local maxima above threshold, in raster order."""
    rows, cols = img.shape
    cap = 4096
    out_r = np.empty(cap, np.int64)
    out_c = np.empty(cap, np.int64)
    n = 0
    for r in range(rows):
        for c in range(cols):
            v = img[r, c]
            if v <= t_min:
                continue
            if v <= grid_at(thr_grid, r, c, rows, cols):
                continue
            ok = True
            for dr in range(-1, 2):
                rr = r + dr
                if rr < 0 or rr >= rows:
                    continue
                for dc in range(-1, 2):
                    cc = c + dc
                    if cc < 0 or cc >= cols or (dr == 0 and dc == 0):
                        continue
                    w = img[rr, cc]
                    if dr < 0 or (dr == 0 and dc < 0):
                        if w >= v:
                            ok = False
                            break
                    elif w > v:
                        ok = False
                        break
                if not ok:
                    break
            if ok:
                if n == cap:
                    cap *= 2
                    out_r = _grow(out_r, cap)
                    out_c = _grow(out_c, cap)
                out_r[n] = r
                out_c[n] = c
                n += 1
    return out_r[:n], out_c[:n]


@njit(cache=True)
def regions(img, max_r, max_c, max_thr, labels):  # pragma: no cover (compiled)
    """8-connected regions above threshold grown from the maxima.

    ``labels`` (H, W) int32 must be zero on entry; it receives region index + 1.
    Returns the region of each maximum, the pixels of all regions (rows, columns,
    region after region) and the start of each region's pixels (n_regions + 1).
    """
    rows, cols = img.shape
    n = max_r.size
    comp = np.empty(n, np.int64)
    cap = max(1024, 16 * n)
    pix_r = np.empty(cap, np.int64)
    pix_c = np.empty(cap, np.int64)
    starts = np.zeros(n + 1, np.int64)
    n_comp = 0
    n_pix = 0
    for m in range(n):
        lab = labels[max_r[m], max_c[m]]
        if lab > 0:
            comp[m] = lab - 1
            continue
        n_comp += 1
        thr = max_thr[m]
        labels[max_r[m], max_c[m]] = n_comp
        if n_pix == cap:
            cap *= 2
            pix_r = _grow(pix_r, cap)
            pix_c = _grow(pix_c, cap)
        pix_r[n_pix] = max_r[m]
        pix_c[n_pix] = max_c[m]
        n_pix += 1
        head = n_pix - 1
        while head < n_pix:
            r = pix_r[head]
            c = pix_c[head]
            head += 1
            for dr in range(-1, 2):
                rr = r + dr
                if rr < 0 or rr >= rows:
                    continue
                for dc in range(-1, 2):
                    cc = c + dc
                    if cc < 0 or cc >= cols or labels[rr, cc] != 0:
                        continue
                    if img[rr, cc] > thr:
                        labels[rr, cc] = n_comp
                        if n_pix == cap:
                            cap *= 2
                            pix_r = _grow(pix_r, cap)
                            pix_c = _grow(pix_c, cap)
                        pix_r[n_pix] = rr
                        pix_c[n_pix] = cc
                        n_pix += 1
        starts[n_comp] = n_pix
        comp[m] = n_comp - 1
    return comp, pix_r[:n_pix], pix_c[:n_pix], starts[: n_comp + 1]


@njit(cache=True)
def _line_min(img, r1, c1, r2, c2):  # pragma: no cover (compiled)
    """Smallest pixel value on the straight segment between two pixels (inclusive)."""
    dr = r2 - r1
    dc = c2 - c1
    steps = max(abs(dr), abs(dc))
    lowest = float(img[r1, c1])
    for s in range(1, steps + 1):
        r = r1 + floor(dr * s / steps + 0.5)
        c = c1 + floor(dc * s / steps + 0.5)
        v = float(img[r, c])
        if v < lowest:
            lowest = v
    return lowest


@njit(cache=True)
def _nearest(kept, n_kept, max_r, max_c, r, c):  # pragma: no cover (compiled)
    """Index in ``kept`` of the maximum nearest to pixel (r, c) (first one on ties)."""
    best = 0
    best_d = 1 << 62
    for a in range(n_kept):
        o = kept[a]
        d = (r - max_r[o]) ** 2 + (c - max_c[o]) ** 2
        if d < best_d:
            best_d = d
            best = a
    return best


@njit(cache=True)
def _gauss3(lo, mid, hi):  # pragma: no cover (compiled)
    """3-point Gaussian offset of the peak from the middle sample; NaN where undefined."""
    if lo <= 0.0 or mid <= 0.0 or hi <= 0.0:
        return np.nan
    l0 = log(lo)
    l1 = log(mid)
    l2 = log(hi)
    den = l0 - 2.0 * l1 + l2
    if not den < 0.0:
        return np.nan
    d = (l0 - l2) / (2.0 * den)
    if abs(d) > 1.0:
        return np.nan
    return d


@njit(cache=True)
def _lsq_add(acc, a, phi, w, y):  # pragma: no cover (compiled)
    """Add one observation y of weight w, with the 5 basis values phi, to the packed
    normal equations of row ``a``."""
    e = 0
    for u in range(5):
        wu = w * phi[u]
        for v in range(u, 5):
            acc[a, e] += wu * phi[v]
            e += 1
        acc[a, 15 + u] += wu * y


@njit(cache=True)
def _lsq_solve(acc, a, coef):  # pragma: no cover (compiled)
    """Solve the packed normal equations of row ``a`` into ``coef`` (5); False if singular."""
    m = np.empty((5, 6))
    e = 0
    for u in range(5):
        for v in range(u, 5):
            m[u, v] = acc[a, e]
            m[v, u] = acc[a, e]
            e += 1
        m[u, 5] = acc[a, 15 + u]
    scale = 0.0
    for u in range(5):
        scale = max(scale, abs(m[u, u]))
    if not scale > 0.0:
        return False
    for col in range(5):  # Gaussian elimination with partial pivoting
        piv = col
        for u in range(col + 1, 5):
            if abs(m[u, col]) > abs(m[piv, col]):
                piv = u
        if abs(m[piv, col]) < 1e-9 * scale:
            return False
        if piv != col:
            for v in range(col, 6):
                t = m[col, v]
                m[col, v] = m[piv, v]
                m[piv, v] = t
        for u in range(col + 1, 5):
            f = m[u, col] / m[col, col]
            for v in range(col, 6):
                m[u, v] -= f * m[col, v]
    for u in range(4, -1, -1):
        t = m[u, 5]
        for v in range(u + 1, 5):
            t -= m[u, v] * coef[v]
        coef[u] = t / m[u, u]
    return True


@njit(cache=True)
def _others(a, kept, n_kept, max_r, max_c, coef, fitted, r, c):  # pragma: no cover
    """Light of the fitted Gaussians of the other kept maxima at pixel (r, c), DN."""
    total = 0.0
    for b in range(n_kept):
        if b == a or not fitted[b]:
            continue
        dx = float(c - max_c[kept[b]])
        dy = float(r - max_r[kept[b]])
        if abs(dx) > _MODEL_REACH or abs(dy) > _MODEL_REACH:
            continue
        cb = coef[b]
        total += exp(cb[0] + cb[1] * dx + cb[2] * dy + cb[3] * dx * dx + cb[4] * dy * dy)
    return total


@njit(cache=True)
def _fit_pixel(
    img, bg, a, kept, n_kept, max_r, max_c, coef, fitted, deblend, ref, r, c, acc
):  # pragma: no cover (compiled)
    """Add pixel (r, c) to particle a's log-quadratic fit (skipped when not usable)."""
    rows, cols = img.shape
    if not (0 <= r < rows and 0 <= c < cols):
        return
    h = float(img[r, c]) - bg
    if deblend:
        h -= _others(a, kept, n_kept, max_r, max_c, coef, fitted, r, c)
    elif n_kept > 1 and _nearest(kept, n_kept, max_r, max_c, r, c) != a:
        return
    if h > 0.0:
        w = h / ref
        dx = float(c - max_c[kept[a]])
        dy = float(r - max_r[kept[a]])
        _lsq_add(acc, 0, (1.0, dx, dy, dx * dx, dy * dy), w * w, log(h))


@njit(cache=True)
def _gauss_fit(
    img, bg, a, kept, n_kept, max_r, max_c, pix_r, pix_c, p0, p1, coef, fitted, deblend, acc
):  # pragma: no cover (compiled)
    """Fit particle a (see :func:`ptv.detect.detect_particles`, "gauss"); True if it worked.

    Pixels: the 3 × 3 block around its maximum and the region's pixels on the 5 × 5 ring.
    Without ``deblend`` the pixels nearer to another kept maximum are left out; with it
    every pixel is used after subtracting the other particles' fitted Gaussians.
    On success the coefficients go to ``coef[a]`` and ``fitted[a]`` is set.
    """
    r0 = max_r[kept[a]]
    c0 = max_c[kept[a]]
    ref = float(img[r0, c0]) - bg
    if deblend:
        ref -= _others(a, kept, n_kept, max_r, max_c, coef, fitted, r0, c0)
    if not ref > 0.0:
        return False
    acc[0, :] = 0.0
    for dy in range(-1, 2):
        for dx in range(-1, 2):
            _fit_pixel(
                img,
                bg,
                a,
                kept,
                n_kept,
                max_r,
                max_c,
                coef,
                fitted,
                deblend,
                ref,
                r0 + dy,
                c0 + dx,
                acc,
            )
    for p in range(p0, p1):
        if max(abs(pix_r[p] - r0), abs(pix_c[p] - c0)) == 2:
            _fit_pixel(
                img,
                bg,
                a,
                kept,
                n_kept,
                max_r,
                max_c,
                coef,
                fitted,
                deblend,
                ref,
                pix_r[p],
                pix_c[p],
                acc,
            )
    trial = np.empty(5)
    if not _lsq_solve(acc, 0, trial):
        return False
    if not (trial[3] < 0.0 and trial[4] < 0.0):
        return False
    if abs(trial[1] / (2.0 * trial[3])) > 1.0 or abs(trial[2] / (2.0 * trial[4])) > 1.0:
        return False
    coef[a, :] = trial
    fitted[a] = True
    return True


# n_kept typed int64 from the start: inferred from its first value, 0, numba compiled
# the functions it is passed to once more for that constant.
@njit(cache=True, locals={"n_kept": types.int64})
def measure(
    img,
    order,
    comp,
    max_r,
    max_c,
    pix_r,
    pix_c,
    starts,
    bg_grid,
    noise_grid,
    thr_grid,
    estimator,
    radius,
    min_dip,
    dip_sigmas,
    max_elongation,
    elongation_min_size,
    saturation,
):  # pragma: no cover (compiled)
    """Split regions between their resolved maxima and measure every particle.

    ``order`` lists the maxima grouped by region (``comp``) and, within a region, by
    decreasing peak. Returns x, y, intensity, peak, size, flags and crowded (one row per
    particle; crowded: the region had too many maxima to split).
    """
    rows, cols = img.shape
    n = order.size
    out_x = np.empty(n)
    out_y = np.empty(n)
    out_int = np.empty(n)
    out_peak = np.empty(n)
    out_size = np.empty(n, np.int64)
    out_flags = np.empty(n, np.uint8)
    out_crowded = np.empty(n, np.bool_)
    kept = np.empty(n, np.int64)
    sw = np.empty(n)
    swx = np.empty(n)
    swy = np.empty(n)
    swxx = np.empty(n)
    swyy = np.empty(n)
    swxy = np.empty(n)
    inten = np.empty(n)
    size = np.empty(n, np.int64)
    flags = np.empty(n, np.uint8)
    acc = np.zeros((1, _N_LSQ))
    coef = np.zeros((n, 5))
    fitted = np.zeros(n, np.bool_)
    n_out = 0
    i = 0
    while i < n:
        k = comp[order[i]]
        j = i
        while j < n and comp[order[j]] == k:
            j += 1
        top = order[i]
        bg = grid_at(bg_grid, max_r[top], max_c[top], rows, cols)
        noise = grid_at(noise_grid, max_r[top], max_c[top], rows, cols)
        thr = grid_at(thr_grid, max_r[top], max_c[top], rows, cols)
        # Keep the maxima separated from every brighter kept one by a dip; a region with
        # too many maxima to split (a blob, or a threshold in the noise) stays whole.
        n_kept = 0
        crowded = j - i > MAX_SPLIT
        for q in range(i, i + 1 if crowded else j):
            m = order[q]
            v = float(img[max_r[m], max_c[m]])
            need = max(min_dip * (v - bg), dip_sigmas * noise)
            ok = True
            for a in range(n_kept):
                o = kept[a]
                saddle = _line_min(img, max_r[m], max_c[m], max_r[o], max_c[o])
                if v - saddle < need:
                    ok = False
                    break
            if ok:
                kept[n_kept] = m
                n_kept += 1
        for a in range(n_kept):
            sw[a] = 0.0
            swx[a] = 0.0
            swy[a] = 0.0
            swxx[a] = 0.0
            swyy[a] = 0.0
            swxy[a] = 0.0
            inten[a] = 0.0
            size[a] = 0
            flags[a] = OVERLAP if n_kept > 1 else (ELONGATED if crowded else 0)
            fitted[a] = False
        # Give each pixel to the nearest kept maximum and accumulate.
        for p in range(starts[k], starts[k + 1]):
            r = pix_r[p]
            c = pix_c[p]
            best = 0
            if n_kept > 1:
                best = _nearest(kept, n_kept, max_r, max_c, r, c)
            v = float(img[r, c])
            size[best] += 1
            inten[best] += v - bg
            if v >= saturation:
                flags[best] |= SATURATED
            if r == 0 or c == 0 or r == rows - 1 or c == cols - 1:
                flags[best] |= EDGE
            o = kept[best]
            dy = r - max_r[o]
            dx = c - max_c[o]
            if abs(dx) <= radius and abs(dy) <= radius:
                w = v - thr
                if w > 0.0:
                    sw[best] += w
                    swx[best] += w * dx
                    swy[best] += w * dy
                    swxx[best] += w * dx * dx
                    swyy[best] += w * dy * dy
                    swxy[best] += w * dx * dy
        # Least-squares Gaussians; in split regions, refitted after subtracting the
        # other particles' fits.
        if estimator == GAUSS:
            p0 = starts[k]
            p1 = starts[k + 1]
            for rep in range(1 + (_DEBLEND_PASSES if n_kept > 1 else 0)):
                for a in range(n_kept):
                    if (flags[a] & SATURATED) == 0:
                        _gauss_fit(
                            img,
                            bg,
                            a,
                            kept,
                            n_kept,
                            max_r,
                            max_c,
                            pix_r,
                            pix_c,
                            p0,
                            p1,
                            coef,
                            fitted,
                            rep > 0,
                            acc,
                        )
        # Centre and flags of each particle.
        for a in range(n_kept):
            o = kept[a]
            r0 = max_r[o]
            c0 = max_c[o]
            f = flags[a]
            if sw[a] > 0.0:
                mx = swx[a] / sw[a]
                my = swy[a] / sw[a]
                vxx = swxx[a] / sw[a] - mx * mx + 1.0 / 12.0
                vyy = swyy[a] / sw[a] - my * my + 1.0 / 12.0
                vxy = swxy[a] / sw[a] - mx * my
                half = 0.5 * (vxx + vyy)
                root = sqrt(0.25 * (vxx - vyy) ** 2 + vxy * vxy)
                lam_min = half - root
                if (
                    n_kept == 1
                    and size[a] >= elongation_min_size
                    and (lam_min <= 0.0 or (half + root) > max_elongation * lam_min)
                ):
                    f |= ELONGATED
            else:
                mx = 0.0
                my = 0.0
            gx = np.nan
            gy = np.nan
            if estimator != CENTROID and (f & SATURATED) == 0:
                mid = float(img[r0, c0]) - bg
                if estimator == GAUSS and fitted[a]:
                    gx = -coef[a, 1] / (2.0 * coef[a, 3])
                    gy = -coef[a, 2] / (2.0 * coef[a, 4])
                if not (gx == gx and gy == gy):
                    gx = np.nan
                    gy = np.nan
                    if 0 < c0 < cols - 1:
                        gx = _gauss3(float(img[r0, c0 - 1]) - bg, mid, float(img[r0, c0 + 1]) - bg)
                    if 0 < r0 < rows - 1:
                        gy = _gauss3(float(img[r0 - 1, c0]) - bg, mid, float(img[r0 + 1, c0]) - bg)
                    if estimator == GAUSS:
                        f |= FALLBACK
            if estimator != CENTROID:
                if gx == gx:
                    mx = gx
                else:
                    f |= FALLBACK
                if gy == gy:
                    my = gy
                else:
                    f |= FALLBACK
            out_x[n_out] = c0 + mx
            out_y[n_out] = r0 + my
            out_int[n_out] = inten[a]
            out_peak[n_out] = float(img[r0, c0]) - bg
            out_size[n_out] = size[a]
            out_flags[n_out] = f
            out_crowded[n_out] = crowded
            n_out += 1
        i = j
    return (
        out_x[:n_out],
        out_y[:n_out],
        out_int[:n_out],
        out_peak[:n_out],
        out_size[:n_out],
        out_flags[:n_out],
        out_crowded[:n_out],
    )
