"""Compiled (numba) least-squares refinement of particle centres (private).

Each group of nearby particles is fitted jointly, in linear intensity, with the sum of
pixel-integrated Gaussian spots and one background level over the union of their
5 × 5 windows. A lone particle is a group of one. Fitting the neighbours' light instead
of cutting it off (as the split regions and the log-quadratic fits of
:mod:`ptv.detect._kernels` do) leaves an error that does not depend on where the
neighbour is, so it does not change between the two frames of a pair as the particles
move: what stays is the photon and read noise, independent from frame to frame.
"""

from math import erf, exp, sqrt

import numpy as np
from numba import njit, prange

#: Window half-width around each particle, px (a 5 × 5 window).
HALF = 2
#: Gauss–Newton iterations at most, and the convergence of the centres: the last step
#: below 10⁻³ px. Each step shrinks by about ten on rendered spots (measured), so the
#: centre is then within ~10⁻⁴ px of the optimum: a hundredth of the best random error
#: (~0.01 px).
_ITERATIONS = 12
_TOLERANCE = 1e-3
#: Groups are refined in this many chunks of consecutive groups (neighbours on the
#: image, so that a chunk reads the image rows it has just read), in parallel.
_CHUNKS = 64
#: Accepted spot widths, px.
_WIDTH_RANGE = (0.3, 3.0)


@njit(cache=True, inline="always")
def _axis_masses(first, n, centre, s, out):  # pragma: no cover (compiled)
    """Pixel masses of a run of n pixels along one axis, and their derivatives.

    For pixels first … first + n − 1 of the unit Gaussian of width s centred at
    ``centre``, out[i] = (mass, d mass/d centre, d mass/d s); neighbouring pixels share
    their boundary, so each boundary's erf and Gaussian are computed once.
    """
    root2s = sqrt(2.0) * s
    norm = 1.0 / (sqrt(2.0 * np.pi) * s)
    lo = first - 0.5 - centre
    e_lo = erf(lo / root2s)
    g_lo = norm * exp(-0.5 * (lo / s) ** 2)
    for i in range(n):
        hi = first + i + 0.5 - centre
        e_hi = erf(hi / root2s)
        g_hi = norm * exp(-0.5 * (hi / s) ** 2)
        out[i, 0] = 0.5 * (e_hi - e_lo)
        out[i, 1] = -(g_hi - g_lo)
        out[i, 2] = -(hi * g_hi - lo * g_lo) / s
        lo, e_lo, g_lo = hi, e_hi, g_hi


@njit(cache=True, inline="always")
def _pixel_mass(u, s):  # pragma: no cover (compiled)
    """∫ over the pixel [u − ½, u + ½] of the unit Gaussian of width s centred at 0, and
    its derivatives with respect to the centre and to s."""
    root2s = sqrt(2.0) * s
    norm = 1.0 / (sqrt(2.0 * np.pi) * s)
    hi, lo = u + 0.5, u - 0.5
    g_hi = norm * exp(-0.5 * (hi / s) ** 2)
    g_lo = norm * exp(-0.5 * (lo / s) ** 2)
    mass = 0.5 * (erf(hi / root2s) - erf(lo / root2s))
    d_centre = -(g_hi - g_lo)
    d_width = -(hi * g_hi - lo * g_lo) / s
    return mass, d_centre, d_width


@njit(cache=True)
def _window_pixels(x, y, members, rows, cols, rr, cc, seen):  # pragma: no cover
    """Fill rr, cc with the pixels of the union of the members' 5 × 5 windows; their
    count (0 if a window leaves the image or the union is wider than ``seen``, a square
    scratch mask left all False)."""
    r_lo, r_hi, c_lo, c_hi = rows, -1, cols, -1
    for n in members:
        c0 = int(x[n] + 0.5)  # nearest pixel (x, y >= -0.5 on an image)
        r0 = int(y[n] + 0.5)
        if not (HALF <= c0 < cols - HALF and HALF <= r0 < rows - HALF):
            return 0
        r_lo, r_hi = min(r_lo, r0 - HALF), max(r_hi, r0 + HALF)
        c_lo, c_hi = min(c_lo, c0 - HALF), max(c_hi, c0 + HALF)
    if max(r_hi - r_lo, c_hi - c_lo) >= seen.shape[0]:
        return 0
    count = 0
    for n in members:
        c0 = int(x[n] + 0.5) - c_lo
        r0 = int(y[n] + 0.5) - r_lo
        for r in range(r0 - HALF, r0 + HALF + 1):
            for c in range(c0 - HALF, c0 + HALF + 1):
                if not seen[r, c]:
                    seen[r, c] = True
                    rr[count] = r + r_lo
                    cc[count] = c + c_lo
                    count += 1
    for k in range(count):  # clear the scratch mask
        seen[rr[k] - r_lo, cc[k] - c_lo] = False
    return count


@njit(cache=True)
def _solve(normal, rhs, out, scale):  # pragma: no cover (compiled)
    """Solve the symmetric system in place (Gaussian elimination with partial pivoting)
    after Jacobi scaling (``scale``: scratch); False when a pivot falls below 10⁻¹⁰ of
    the unit diagonal."""
    n = rhs.size
    for u in range(n):
        if not normal[u, u] > 0.0:
            return False
        scale[u] = sqrt(normal[u, u])
    for u in range(n):
        rhs[u] /= scale[u]
        for v in range(n):
            normal[u, v] /= scale[u] * scale[v]
    for col in range(n):
        piv = col
        for u in range(col + 1, n):
            if abs(normal[u, col]) > abs(normal[piv, col]):
                piv = u
        if abs(normal[piv, col]) < 1e-10:
            return False
        if piv != col:
            for v in range(col, n):
                normal[col, v], normal[piv, v] = normal[piv, v], normal[col, v]
            rhs[col], rhs[piv] = rhs[piv], rhs[col]
        for u in range(col + 1, n):
            f = normal[u, col] / normal[col, col]
            for v in range(col, n):
                normal[u, v] -= f * normal[col, v]
            rhs[u] -= f * rhs[col]
    for u in range(n - 1, -1, -1):
        t = rhs[u]
        for v in range(u + 1, n):
            t -= normal[u, v] * out[v]
        out[u] = t / normal[u, u]
    for u in range(n):
        out[u] /= scale[u]
    return True


@njit(cache=True, fastmath={"reassoc", "contract"})
def _normal_equations(
    img, rr, cc, r_lo, c_lo, params, ex, ey, jac, normal, rhs
):  # pragma: no cover
    """Upper triangle of JᵀJ and Jᵀ(I − model) of a group's fit, over its pixels.

    ``jac`` (n_par + 1, ≥ n_pix) receives the Jacobian, one row per parameter, and the
    residuals in its last row; each sum is then one dot product over the pixels, which
    the compiler vectorises (hence the reassociation allowed here: the sums differ from
    the pixel-by-pixel order only by rounding).
    """
    n_par = params.size
    n_spots = (n_par - 1) // 4
    n_pix = rr.size
    resid = jac[n_par]
    for p in range(n_pix):
        i, j = cc[p] - c_lo, rr[p] - r_lo
        model = params[n_par - 1]
        jac[n_par - 1, p] = 1.0
        for k in range(n_spots):
            a = params[4 * k]
            mx, dxc, dxw = ex[k, i, 0], ex[k, i, 1], ex[k, i, 2]
            my, dyc, dyw = ey[k, j, 0], ey[k, j, 1], ey[k, j, 2]
            model += a * mx * my
            jac[4 * k, p] = mx * my
            jac[4 * k + 1, p] = a * dxc * my
            jac[4 * k + 2, p] = a * mx * dyc
            jac[4 * k + 3, p] = a * (dxw * my + mx * dyw)
        resid[p] = float(img[rr[p], cc[p]]) - model
    for u in range(n_par):
        ju = jac[u]
        total = 0.0
        for p in range(n_pix):
            total += ju[p] * resid[p]
        rhs[u] = total
        for v in range(u, n_par):
            jv = jac[v]
            total = 0.0
            for p in range(n_pix):
                total += ju[p] * jv[p]
            normal[u, v] = total


@njit(cache=True)
def _normal_equations_one(img, rr, cc, r_lo, c_lo, params, ex, ey, normal, rhs):  # pragma: no cover
    """:func:`_normal_equations` for a lone spot, the sums held in registers, pixel by
    pixel (5 × 5 pixels: too few to gain from vectorising)."""
    a, b = params[0], params[4]
    r0 = r1 = r2 = r3 = r4 = 0.0
    n00 = n01 = n02 = n03 = n04 = n11 = n12 = n13 = n14 = 0.0
    n22 = n23 = n24 = n33 = n34 = n44 = 0.0
    for p in range(rr.size):
        i, j = cc[p] - c_lo, rr[p] - r_lo
        mx, dxc, dxw = ex[i, 0], ex[i, 1], ex[i, 2]
        my, dyc, dyw = ey[j, 0], ey[j, 1], ey[j, 2]
        model = b + a * mx * my
        j0 = mx * my
        j1 = a * dxc * my
        j2 = a * mx * dyc
        j3 = a * (dxw * my + mx * dyw)
        resid = float(img[rr[p], cc[p]]) - model
        r0 += j0 * resid
        n00 += j0 * j0
        n01 += j0 * j1
        n02 += j0 * j2
        n03 += j0 * j3
        n04 += j0
        r1 += j1 * resid
        n11 += j1 * j1
        n12 += j1 * j2
        n13 += j1 * j3
        n14 += j1
        r2 += j2 * resid
        n22 += j2 * j2
        n23 += j2 * j3
        n24 += j2
        r3 += j3 * resid
        n33 += j3 * j3
        n34 += j3
        r4 += resid
        n44 += 1.0
    rhs[0], rhs[1], rhs[2], rhs[3], rhs[4] = r0, r1, r2, r3, r4
    normal[0, 0], normal[0, 1], normal[0, 2], normal[0, 3], normal[0, 4] = n00, n01, n02, n03, n04
    normal[1, 1], normal[1, 2], normal[1, 3], normal[1, 4] = n11, n12, n13, n14
    normal[2, 2], normal[2, 3], normal[2, 4] = n22, n23, n24
    normal[3, 3], normal[3, 4] = n33, n34
    normal[4, 4] = n44


@njit(cache=True)
def _fit_group(img, rr, cc, params, work):  # pragma: no cover (compiled)
    """Gauss–Newton on (A, x₀, y₀, s) per spot and one background; True if converged.

    ``work`` holds the scratch arrays (:func:`_workspace`), wide enough for the group's
    pixels (:func:`_window_pixels` checks)."""
    ex_all, ey_all, jac_all, normal_all, rhs_all, step_all, scale_all, start = work
    n_par = params.size
    n_spots = (n_par - 1) // 4
    r_lo, c_lo = rr.min(), cc.min()
    n_rows, n_cols = rr.max() - r_lo + 1, cc.max() - c_lo + 1
    ex = ex_all[:n_spots, :n_cols]  # pixel mass and its derivatives, per column
    ey = ey_all[:n_spots, :n_rows]  # and per row: the model is separable per spot
    jac = jac_all[: n_par + 1]
    normal = normal_all[:n_par, :n_par]
    rhs = rhs_all[:n_par]
    step = step_all[:n_par]
    scale = scale_all[:n_par]
    for k in range(n_spots):
        start[k, 0] = params[4 * k + 1]
        start[k, 1] = params[4 * k + 2]
    for _ in range(_ITERATIONS):
        for k in range(n_spots):
            x0, y0, s = params[4 * k + 1], params[4 * k + 2], params[4 * k + 3]
            _axis_masses(c_lo, n_cols, x0, s, ex[k])
            _axis_masses(r_lo, n_rows, y0, s, ey[k])
        if n_spots == 1:
            _normal_equations_one(img, rr, cc, r_lo, c_lo, params, ex[0], ey[0], normal, rhs)
        else:
            _normal_equations(img, rr, cc, r_lo, c_lo, params, ex, ey, jac, normal, rhs)
        for u in range(n_par):
            for v in range(u + 1, n_par):
                normal[v, u] = normal[u, v]
        if not _solve(normal, rhs, step, scale):
            return False
        move = 0.0
        for k in range(n_spots):
            move = max(move, abs(step[4 * k + 1]), abs(step[4 * k + 2]))
        if move > 0.5:
            return False
        for u in range(n_par):
            params[u] += step[u]
        for k in range(n_spots):
            s = params[4 * k + 3]
            if not (_WIDTH_RANGE[0] < s < _WIDTH_RANGE[1] and params[4 * k] > 0.0):
                return False
        if move < _TOLERANCE:
            for k in range(n_spots):
                shift_x = abs(params[4 * k + 1] - start[k, 0])
                if max(shift_x, abs(params[4 * k + 2] - start[k, 1])) > 1.0:
                    return False
            return True
    return False


@njit(cache=True, parallel=True)
def refine_groups(img, x, y, width, level, members, offsets):  # pragma: no cover
    """Refine the centres of groups of particles by a joint integrated-Gaussian fit.

    The model of pixel (i, j) is Σ_k A_k·E(i − x_k)·E(j − y_k) + B, E the light of a
    Gaussian of width s_k falling on the pixel (erf differences), over the union of the
    members' 5 × 5 windows, fitted with uniform weights by Gauss–Newton from the given
    centres, ``width`` and the members' mean background ``level``. Every pixel counts
    whatever its value, so no threshold or logarithm shapes the estimate. A group whose
    fit fails (a window off the image, singular, a step beyond ½ px, a width outside
    0.3–3 px, no convergence, a centre moved more than 1 px) keeps its centres.

    Parameters
    ----------
    img : ndarray (H, W)
        The image, DN.
    x, y : ndarray (N,)
        Centres, px (updated in place for the particles refined).
    width : float
        Starting Gaussian width s, px.
    level : ndarray (N,)
        Background at each particle, DN.
    members : ndarray of int (G,)
        Particle indices, group after group.
    offsets : ndarray of int (n_groups + 1,)
        Group g is ``members[offsets[g]:offsets[g + 1]]``.

    Returns
    -------
    ndarray of bool (N,)
        The particles refined.
    """
    rows, cols = img.shape
    refined = np.zeros(x.size, np.bool_)
    largest = 1
    for g in range(offsets.size - 1):
        largest = max(largest, offsets[g + 1] - offsets[g])
    # Each chunk has its own scratch; groups are disjoint, so the chunks write disjoint
    # entries of x, y and refined.
    n_groups = offsets.size - 1
    for chunk in prange(_CHUNKS):
        work = _workspace(largest)
        span = work[0].shape[1]
        seen = np.zeros((span, span), np.bool_)
        rr = np.empty(largest * (2 * HALF + 1) ** 2, np.int64)
        cc = np.empty_like(rr)
        params = np.empty(4 * largest + 1)
        for g in range(chunk * n_groups // _CHUNKS, (chunk + 1) * n_groups // _CHUNKS):
            group = members[offsets[g] : offsets[g + 1]]
            count = _window_pixels(x, y, group, rows, cols, rr, cc, seen)
            if count == 0:
                continue
            p = params[: 4 * group.size + 1]
            background = 0.0
            for k in range(group.size):
                n = group[k]
                c0, r0 = int(x[n] + 0.5), int(y[n] + 0.5)
                s0 = _start_width(img, r0, c0, level[n], width)
                mass = _pixel_mass(0.0, s0)[0]  # of the centre pixel, per unit amplitude
                p[4 * k] = max(float(img[r0, c0]) - level[n], 1.0) / (mass * mass)
                p[4 * k + 1] = x[n]
                p[4 * k + 2] = y[n]
                p[4 * k + 3] = s0
                background += level[n] / group.size
            p[-1] = background
            if _fit_group(img, rr[:count], cc[:count], p, work):
                for k in range(group.size):
                    x[group[k]] = p[4 * k + 1]
                    y[group[k]] = p[4 * k + 2]
                    refined[group[k]] = True
    return refined


@njit(cache=True)
def _start_width(img, r0, c0, level, default):  # pragma: no cover (compiled)
    """A starting Gaussian width from the log-curvature of the 3-pixel profiles through
    the maximum pixel (r0, c0): 1/curvature is σ² plus the pixel's 1/12 px²; ``default``
    where a value is not above ``level`` or the profile is not concave. Starting near
    the solution saves the Gauss–Newton steps that would first move the width."""
    centre = float(img[r0, c0]) - level
    left = float(img[r0, c0 - 1]) - level
    right = float(img[r0, c0 + 1]) - level
    up = float(img[r0 - 1, c0]) - level
    down = float(img[r0 + 1, c0]) - level
    if min(centre, left, right, up, down) <= 0.0:
        return default
    log_c = np.log(centre)
    curve_x = 2.0 * log_c - np.log(left) - np.log(right)
    curve_y = 2.0 * log_c - np.log(up) - np.log(down)
    if curve_x <= 0.0 or curve_y <= 0.0:
        return default
    variance = 0.5 * (1.0 / curve_x + 1.0 / curve_y) - 1.0 / 12.0
    if not _WIDTH_RANGE[0] ** 2 < variance < _WIDTH_RANGE[1] ** 2:
        return default
    return sqrt(variance)


@njit(cache=True)
def _workspace(spots):  # pragma: no cover (compiled)
    """Scratch arrays of :func:`_fit_group` for groups of up to ``spots`` particles."""
    n_par = 4 * spots + 1
    span = 8 * spots + 2 * HALF + 1  # wider than any chain of windows < 6 px apart
    return (
        np.empty((spots, span, 3)),
        np.empty((spots, span, 3)),
        np.empty((n_par + 1, spots * (2 * HALF + 1) ** 2)),
        np.empty((n_par, n_par)),
        np.empty(n_par),
        np.empty(n_par),
        np.empty(n_par),
        np.empty((spots, 2)),
    )
