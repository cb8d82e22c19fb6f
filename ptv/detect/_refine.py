"""Compiled (numba) least-squares refinement of particle centres (private).

Each group of nearby particles is fitted jointly, in linear intensity, with the sum of
pixel-integrated Gaussian spots and one background level over the union of their
5 × 5 windows. A lone particle is a group of one. Fitting the neighbours' light instead
of cutting it off (as the split regions and the log-quadratic fits of
:mod:`ptv.detect._kernels` do) leaves an error that does not depend on where the
neighbour is, so it does not change between the two frames of a pair as the particles
move: what stays is the photon and read noise, independent from frame to frame.

The light of spots outside a group (its neighbours, when a long chain of detections is
fitted piece by piece) can be held fixed in the model, and the pixels can be weighted
(by 1/σ_p², for the model test of :mod:`ptv.detect._split`, which reuses
:func:`fit_group`). After each group's fit, :func:`refine_groups` also reports what the
noise model of :func:`ptv.detect.locate._noise_model` needs: the residuals' sum of
squares, its expected shot-noise share (through the pixels' leverages) and the
correlation of adjacent residuals.
"""

from math import erf, exp, sqrt

import numpy as np
from numba import njit

from ptv._threads import over_threads

#: Window half-width around each particle, px (a 5 × 5 window).
HALF = 2
#: Gauss–Newton iterations at most, and the convergence of the centres: the last step
#: below 10⁻³ px. Each step shrinks by about ten on rendered spots (measured), so the
#: centre is then within ~10⁻⁴ px of the optimum: a hundredth of the best random error
#: (~0.01 px). A NumPy integer, as :mod:`ptv.detect._split`'s and the ``clamp`` flags
#: passed to :func:`fit_group` (np.True_, np.False_): numba compiles a function once per
#: value of a Python constant passed to it, so a Python int and bool gave two fit_group.
_ITERATIONS = np.int64(12)
_TOLERANCE = 1e-3
#: Groups are refined in this many chunks of consecutive groups (neighbours on the
#: image, so that a chunk reads the image rows it has just read), in parallel
#: (:func:`ptv._threads.over_threads`).
_CHUNKS = 64
#: Shortest fraction of a Gauss–Newton step tried before a clamped fit gives up.
_SMALLEST_STEP = 1.0 / 64.0
#: Farthest a centre may end from its start in a clamped fit, px, and its convergence:
#: the last step below 10⁻² px (the centre then within ~10⁻³ px of the optimum, as
#: above; a clamped fit serves a model test, which needs χ² near its minimum).
_CLAMPED_REACH = 3.0
_CLAMPED_TOLERANCE = 1e-2
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
def window_pixels(x, y, members, rows, cols, rr, cc, seen):  # pragma: no cover
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


@njit(cache=True)
def _normal_equations(
    img, rr, cc, r_lo, c_lo, params, ex, ey, jac, normal, rhs, root_w, fixed
):  # pragma: no cover
    """Upper triangle of JᵀWJ and JᵀW(I − model) of a group's fit, over its pixels.

    ``jac`` (n_par + 1, ≥ n_pix) receives the Jacobian, one row per parameter, and the
    residuals in its last row, each scaled by the pixel's √weight (``root_w``, n_pix);
    each sum is then one dot product over the pixels. ``fixed`` (n_pix): light of spots
    held fixed, DN, part of the model.

    No fastmath here, nor in :func:`_lone_spot_stats`: with reassociation allowed, the
    code numba loads from its cache gave detections that differed in the last bits from
    those of freshly compiled code, so that a run's results depended on which of its
    processes had compiled the kernels (measured: up to 3·10⁻⁹ px on paper-10hz
    images); without it, no slower (side by side on paper-10hz and 0.03 ppp images).
    """
    n_par = params.size
    n_spots = (n_par - 1) // 4
    n_pix = rr.size
    resid = jac[n_par]
    for p in range(n_pix):
        i, j = cc[p] - c_lo, rr[p] - r_lo
        w = root_w[p]
        model = params[n_par - 1] + fixed[p]
        jac[n_par - 1, p] = w
        for k in range(n_spots):
            a = params[4 * k]
            mx, dxc, dxw = ex[k, i, 0], ex[k, i, 1], ex[k, i, 2]
            my, dyc, dyw = ey[k, j, 0], ey[k, j, 1], ey[k, j, 2]
            model += a * mx * my
            jac[4 * k, p] = w * (mx * my)
            jac[4 * k + 1, p] = w * (a * dxc * my)
            jac[4 * k + 2, p] = w * (a * mx * dyc)
            jac[4 * k + 3, p] = w * (a * (dxw * my + mx * dyw))
        resid[p] = w * (float(img[rr[p], cc[p]]) - model)
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
def _normal_equations_one(
    img, rr, cc, r_lo, c_lo, params, ex, ey, normal, rhs, root_w, fixed
):  # pragma: no cover
    """:func:`_normal_equations` for a lone spot, the sums held in registers, pixel by
    pixel (5 × 5 pixels: too few to gain from vectorising)."""
    a, b = params[0], params[4]
    r0 = r1 = r2 = r3 = r4 = 0.0
    n00 = n01 = n02 = n03 = n04 = n11 = n12 = n13 = n14 = 0.0
    n22 = n23 = n24 = n33 = n34 = n44 = 0.0
    for p in range(rr.size):
        i, j = cc[p] - c_lo, rr[p] - r_lo
        w = root_w[p]
        mx, dxc, dxw = ex[i, 0], ex[i, 1], ex[i, 2]
        my, dyc, dyw = ey[j, 0], ey[j, 1], ey[j, 2]
        model = b + fixed[p] + a * mx * my
        j0 = w * (mx * my)
        j1 = w * (a * dxc * my)
        j2 = w * (a * mx * dyc)
        j3 = w * (a * (dxw * my + mx * dyw))
        resid = w * (float(img[rr[p], cc[p]]) - model)
        r0 += j0 * resid
        n00 += j0 * j0
        n01 += j0 * j1
        n02 += j0 * j2
        n03 += j0 * j3
        n04 += j0 * w
        r1 += j1 * resid
        n11 += j1 * j1
        n12 += j1 * j2
        n13 += j1 * j3
        n14 += j1 * w
        r2 += j2 * resid
        n22 += j2 * j2
        n23 += j2 * j3
        n24 += j2 * w
        r3 += j3 * resid
        n33 += j3 * j3
        n34 += j3 * w
        r4 += resid * w
        n44 += w * w
    rhs[0], rhs[1], rhs[2], rhs[3], rhs[4] = r0, r1, r2, r3, r4
    normal[0, 0], normal[0, 1], normal[0, 2], normal[0, 3], normal[0, 4] = n00, n01, n02, n03, n04
    normal[1, 1], normal[1, 2], normal[1, 3], normal[1, 4] = n11, n12, n13, n14
    normal[2, 2], normal[2, 3], normal[2, 4] = n22, n23, n24
    normal[3, 3], normal[3, 4] = n33, n34
    normal[4, 4] = n44


@njit(cache=True, inline="always")
def _spot_masses(params, n_spots, r_lo, c_lo, n_rows, n_cols, ex, ey):  # pragma: no cover
    """Pixel masses and their derivatives of every spot of ``params`` over the bounding
    box (rows r_lo …, columns c_lo …) into ex (n_spots, ≥ n_cols, 3) and ey."""
    for k in range(n_spots):
        x0, y0, s = params[4 * k + 1], params[4 * k + 2], params[4 * k + 3]
        _axis_masses(c_lo, n_cols, x0, s, ex[k])
        _axis_masses(r_lo, n_rows, y0, s, ey[k])


@njit(cache=True)
def fit_group(img, rr, cc, params, work, root_w, fixed, iterations, clamp):  # pragma: no cover
    """Gauss–Newton on (A, x₀, y₀, s) per spot and one background; True if converged.

    Parameters
    ----------
    img : ndarray (H, W)
        The image, DN.
    rr, cc : ndarray of int (n_pix,)
        Rows and columns of the pixels fitted.
    params : ndarray (4·n_spots + 1,)
        A, x₀, y₀, s of each spot (DN·px², px, px, px) and the background B (DN): the
        start, updated in place (left part-way where the fit fails).
    work : tuple
        Scratch arrays of :func:`workspace`, wide enough for the pixels' bounding box
        (:func:`window_pixels` checks).
    root_w : ndarray (n_pix,)
        √weight of each pixel (1/σ_p for a maximum-likelihood fit; 1 for least squares).
    fixed : ndarray (n_pix,)
        Light of other spots held fixed, DN, added to the model.
    iterations : int
        Gauss–Newton steps at most (:data:`_ITERATIONS` for the refinement).
    clamp : bool
        A step that would move a centre by more than ½ px is shortened to ½ px, and one
        that would take a width out of 0.3–3 px or an amplitude to <= 0 is halved until
        it does not (at most down to :data:`_SMALLEST_STEP` of it), a centre may end up
        to :data:`_CLAMPED_REACH` px from its start, and the fit has converged when the
        last step is below :data:`_CLAMPED_TOLERANCE` (True: fits that start far, as the
        trials of a split); otherwise either step, or a centre more than 1 px from its
        start, ends the fit as failed, and convergence is a step below :data:`_TOLERANCE`
        (False: the refinement, which starts close).

    Returns
    -------
    bool
        Whether the fit converged.
    """
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
    for _ in range(iterations):
        _spot_masses(params, n_spots, r_lo, c_lo, n_rows, n_cols, ex, ey)
        if n_spots == 1:
            _normal_equations_one(
                img, rr, cc, r_lo, c_lo, params, ex[0], ey[0], normal, rhs, root_w, fixed
            )
        else:
            _normal_equations(
                img, rr, cc, r_lo, c_lo, params, ex, ey, jac, normal, rhs, root_w, fixed
            )
        for u in range(n_par):
            for v in range(u + 1, n_par):
                normal[v, u] = normal[u, v]
        if not _solve(normal, rhs, step, scale):
            return False
        move = 0.0
        for k in range(n_spots):
            move = max(move, abs(step[4 * k + 1]), abs(step[4 * k + 2]))
        if move > 0.5 and not clamp:
            return False
        fraction = min(1.0, 0.5 / move) if move > 0.0 else 1.0
        while not _valid_step(params, step, fraction, n_spots):
            fraction *= 0.5
            if not clamp or fraction < _SMALLEST_STEP:
                return False
        for u in range(n_par):
            params[u] += fraction * step[u]
        if fraction == 1.0 and move < (_CLAMPED_TOLERANCE if clamp else _TOLERANCE):
            for k in range(n_spots):
                shift_x = abs(params[4 * k + 1] - start[k, 0])
                reach = _CLAMPED_REACH if clamp else 1.0
                if max(shift_x, abs(params[4 * k + 2] - start[k, 1])) > reach:
                    return False
            return True
    return False


@njit(cache=True, inline="always")
def _valid_step(params, step, fraction, n_spots):  # pragma: no cover (compiled)
    """Whether every spot keeps a positive amplitude and a width within
    :data:`_WIDTH_RANGE` after ``fraction`` of the step."""
    for k in range(n_spots):
        s = params[4 * k + 3] + fraction * step[4 * k + 3]
        if not (
            _WIDTH_RANGE[0] < s < _WIDTH_RANGE[1] and params[4 * k] + fraction * step[4 * k] > 0.0
        ):
            return False
    return True


@njit(cache=True)
def model_light(img, rr, cc, params, work, fixed, resid, light):  # pragma: no cover
    """Residuals I − model (``resid``, n_pix, DN) and the model's light above the
    background, fitted and fixed spots together (``light``, n_pix, DN), of ``params``
    (as :func:`fit_group`)."""
    ex_all, ey_all = work[0], work[1]
    n_spots = (params.size - 1) // 4
    r_lo, c_lo = rr.min(), cc.min()
    n_rows, n_cols = rr.max() - r_lo + 1, cc.max() - c_lo + 1
    _spot_masses(params, n_spots, r_lo, c_lo, n_rows, n_cols, ex_all, ey_all)
    for p in range(rr.size):
        i, j = cc[p] - c_lo, rr[p] - r_lo
        total = fixed[p]
        for k in range(n_spots):
            total += params[4 * k] * ex_all[k, i, 0] * ey_all[k, j, 0]
        light[p] = total
        resid[p] = float(img[rr[p], cc[p]]) - params[-1] - total


@njit(cache=True)
def _scaled_cholesky(normal, low, scale, inverse, n):  # pragma: no cover (compiled)
    """Cholesky factor L of D·N·D, D = diag(``scale``), scale_u = 1/√N_uu (Jacobi
    scaling), N the n × n symmetric matrix whose upper triangle ``normal`` holds.

    L goes into the lower triangle of ``low``, which may be ``normal`` itself (only the
    upper triangle is read, each diagonal entry before it is overwritten), and 1/L_uu
    into ``inverse``, so that triangular solves multiply instead of divide. Returns
    False if N is not positive definite."""
    for u in range(n):
        scale[u] = 1.0 / sqrt(normal[u, u])
    for v in range(n):
        for u in range(v, n):
            total = normal[v, u] * scale[u] * scale[v]
            for t in range(v):
                total -= low[u, t] * low[v, t]
            if u == v:
                if not total > 0.0:
                    return False
                low[v, v] = sqrt(total)
                inverse[v] = 1.0 / low[v, v]
            else:
                low[u, v] = total * inverse[v]
    return True


@njit(cache=True)
def _residual_light(img, rr, cc, params, work, ones, fixed, light):  # pragma: no cover
    """Σ_p (1 − h_p)·light_p, h_p = j_pᵀ(JᵀJ)⁻¹j_p the leverage of pixel p in the
    least-squares fit at ``params`` (j_p: its row of the Jacobian J): the shot-noise
    share of the expected squared residuals, Σ (1 − h_p)·σ_p², per unit of γ.

    h_p = |L⁻¹ j_p|² with JᵀJ = LLᵀ (Cholesky, after Jacobi scaling); 0 if JᵀJ is not
    positive definite. Takes the spots' masses from the :func:`model_light` call that
    gave ``light`` (in ``work``)."""
    ex, ey, jac_all, normal_all, rhs_all, z_all, scale_all = work[:7]
    n_par = params.size
    r_lo, c_lo = rr.min(), cc.min()
    jac, low, z, scale = jac_all[: n_par + 1], normal_all[:n_par, :n_par], z_all, scale_all
    _normal_equations(img, rr, cc, r_lo, c_lo, params, ex, ey, jac, low, rhs_all, ones, fixed)
    inverse = rhs_all  # 1 / L's diagonal (the right-hand side is not needed here)
    if not _scaled_cholesky(low, low, scale, inverse, n_par):
        return 0.0
    total = 0.0
    for p in range(rr.size):
        h = 0.0
        for u in range(n_par):  # z = L⁻¹ (scaled j_p), by multiplications only (speed)
            t = jac[u, p] * scale[u]
            for v in range(u):
                t -= low[u, v] * z[v]
            z[u] = t * inverse[u]
            h += z[u] * z[u]
        total += (1.0 - h) * light[p]
    return total


@njit(cache=True)
def _neighbour_products(rr, cc, resid, seen, grid):  # pragma: no cover (compiled)
    """Σ r_p·r_q over the pairs of horizontally or vertically adjacent pixels p, q of
    the set (rr, cc), residuals ``resid``; ``seen`` (a scratch mask left all False)
    and ``grid`` cover the set's bounding box."""
    r_lo, c_lo = rr.min(), cc.min()
    for p in range(rr.size):
        seen[rr[p] - r_lo, cc[p] - c_lo] = True
        grid[rr[p] - r_lo, cc[p] - c_lo] = resid[p]
    total = 0.0
    for p in range(rr.size):
        i, j = rr[p] - r_lo, cc[p] - c_lo
        if j + 1 < seen.shape[1] and seen[i, j + 1]:
            total += resid[p] * grid[i, j + 1]
        if i + 1 < seen.shape[0] and seen[i + 1, j]:
            total += resid[p] * grid[i + 1, j]
    for p in range(rr.size):
        seen[rr[p] - r_lo, cc[p] - c_lo] = False
    return total


@njit(cache=True)
def _lone_spot_stats(img, rr, cc, params, work, fixed, out):  # pragma: no cover
    """:func:`refine_groups`' statistics of a lone spot (its 5 × 5 window, parameters
    A, x₀, y₀, s, B) into out[0], out[1] and out[4]: Σ r², Σ (1 − h_p)·m_p and the
    products of adjacent residuals, as :func:`model_light`, :func:`_residual_light`
    and :func:`_neighbour_products` give them for any group, in one pass over the
    pixels, about 1.5 times faster (most groups of a sparse image are lone spots).

    Σ_p h_p·m_p = tr((JᵀJ)⁻¹·Σ_p m_p·j_p·j_pᵀ), both matrices summed in the same pass
    (after Jacobi scaling, with JᵀJ = LLᵀ: the trace of W·M·Wᵀ, W = L⁻¹); Σ (1 − h_p)·m_p
    is 0 if JᵀJ is not positive definite."""
    n_par = 5
    side = 2 * HALF + 1
    ex, ey = work[0][0], work[1][0]
    a, b = params[0], params[4]
    r_lo, c_lo = rr.min(), cc.min()
    _axis_masses(c_lo, side, params[1], params[3], ex)
    _axis_masses(r_lo, side, params[2], params[3], ey)
    normal = np.zeros((n_par, n_par))
    shot = np.zeros((n_par, n_par))
    grid = np.zeros((side + 1, side + 1))  # residuals, and a zero border right and below
    j = np.empty(n_par)
    square = light_sum = 0.0
    for p in range(rr.size):
        col, row = cc[p] - c_lo, rr[p] - r_lo
        mx, dxc, dxw = ex[col, 0], ex[col, 1], ex[col, 2]
        my, dyc, dyw = ey[row, 0], ey[row, 1], ey[row, 2]
        j[0], j[1], j[2] = mx * my, a * dxc * my, a * mx * dyc
        j[3], j[4] = a * (dxw * my + mx * dyw), 1.0
        light = fixed[p] + a * j[0]
        resid = float(img[rr[p], cc[p]]) - b - light
        grid[row, col] = resid
        square += resid * resid
        light_sum += light
        for u in range(n_par):
            for v in range(u, n_par):
                normal[u, v] += j[u] * j[v]
                shot[u, v] += light * j[u] * j[v]
    out[0] = square
    adjacent = 0.0
    for row in range(side):
        for col in range(side):
            adjacent += grid[row, col] * (grid[row, col + 1] + grid[row + 1, col])
    out[4] = adjacent
    out[1] = 0.0
    scale, diagonal = np.empty(n_par), np.empty(n_par)
    low = np.zeros((n_par, n_par))
    if not _scaled_cholesky(normal, low, scale, diagonal, n_par):
        return
    inverse = np.zeros((n_par, n_par))  # W = L⁻¹, lower triangular
    for u in range(n_par):
        for v in range(u + 1):
            total = 1.0 if u == v else 0.0
            for t in range(v, u):
                total -= low[u, t] * inverse[t, v]
            inverse[u, v] = total * diagonal[u]
    trace = 0.0
    for u in range(n_par):
        for v in range(u + 1):
            for t in range(u + 1):
                m_vt = shot[min(v, t), max(v, t)] * scale[v] * scale[t]
                trace += inverse[u, v] * m_vt * inverse[u, t]
    out[1] = light_sum - trace


@njit(cache=True)
def fixed_light(spots, near, rr, cc, work, out):  # pragma: no cover (compiled)
    """Light on each pixel (rr, cc) of the spots ``near`` (indices into ``spots``, rows
    A, x₀, y₀, s; those with A <= 0 are not modelled and skipped), DN, into ``out``."""
    ex, ey = work[0][0], work[1][0]
    r_lo, c_lo = rr.min(), cc.min()
    n_rows, n_cols = rr.max() - r_lo + 1, cc.max() - c_lo + 1
    out[: rr.size] = 0.0
    for n in near:
        a, x0, y0, s = spots[n, 0], spots[n, 1], spots[n, 2], spots[n, 3]
        if not a > 0.0:
            continue
        _axis_masses(c_lo, n_cols, x0, s, ex)
        _axis_masses(r_lo, n_rows, y0, s, ey)
        for p in range(rr.size):
            out[p] += a * ex[cc[p] - c_lo, 0] * ey[rr[p] - r_lo, 0]


def refine_groups(img, spots, level, members, offsets, near, near_offsets, snapshot):
    """Refine groups of particles by a joint integrated-Gaussian fit.

    The model of pixel (i, j) is Σ_k A_k·E(i − x_k)·E(j − y_k) + F + B, E the light of a
    Gaussian of width s_k falling on the pixel (erf differences), F the light of the
    group's neighbours held fixed, over the union of the members' 5 × 5 windows, fitted
    with uniform weights by Gauss–Newton from the members' spots and their mean
    background ``level``. Every pixel counts whatever its value, so no threshold or
    logarithm shapes the estimate. A group whose fit fails (a window off the image,
    singular, a step beyond ½ px, a width outside 0.3–3 px, no convergence, a centre
    moved more than 1 px) keeps its spots.

    Parameters
    ----------
    img : ndarray (H, W)
        The image, DN.
    spots : ndarray (N, 4)
        A, x₀, y₀, s of each particle (DN·px², px, px, px): the start, updated in place
        for the particles refined.
    level : ndarray (N,)
        Background at each particle, DN.
    members : ndarray of int (G,)
        Particle indices, group after group.
    offsets : ndarray of int (n_groups + 1,)
        Group g is ``members[offsets[g]:offsets[g + 1]]``.
    near, near_offsets : ndarray of int
        The same for the neighbours of each group whose light is held fixed.
    snapshot : ndarray (N, 4)
        The spots the neighbours' light is taken from (read only: a copy of ``spots``
        made before the call, so the result does not depend on the order of the groups).

    Returns
    -------
    refined : ndarray of bool (N,)
        The particles refined.
    stats : ndarray (n_groups, 5)
        Per group: Σ (I − model)², DN²; Σ (1 − h_p)·m_p, DN, the model's light above
        background m_p weighted by the pixels' share of the residual (h_p: leverage); the
        degrees of freedom, pixels − parameters; the fitted background B, DN; the sum of
        the products of the residuals of horizontally and vertically adjacent pixels,
        DN² (0, 0, 0, NaN, 0 where the fit failed). The expected Σ (I − model)² is
        Σ (1 − h_p)·σ_p²; the last is near 0 for white noise, and large for a misfit (a
        blend leaves residuals of one sign over several pixels).
    """
    refined = np.zeros(spots.shape[0], np.bool_)
    stats = np.zeros((offsets.size - 1, 5))
    stats[:, 3] = np.nan
    largest = int(np.diff(offsets).max(initial=1))
    over_threads(
        _refine_chunks,
        _CHUNKS,
        img,
        spots,
        level,
        members,
        offsets,
        near,
        near_offsets,
        snapshot,
        largest,
        refined,
        stats,
    )
    return refined, stats


@njit(cache=True, nogil=True, error_model="numpy")
def _refine_chunks(
    first,
    stop,
    img,
    spots,
    level,
    members,
    offsets,
    near,
    near_offsets,
    snapshot,
    largest,
    refined,
    stats,
):  # pragma: no cover (compiled)
    """Chunks ``first … stop − 1`` of :func:`refine_groups` (of groups of at most
    ``largest`` particles), into ``spots``, ``refined`` and ``stats``. Each chunk has its
    own scratch; groups are disjoint, so the chunks write disjoint entries."""
    rows, cols = img.shape
    n_groups = offsets.size - 1
    for chunk in range(first, stop):
        work = workspace(largest)
        span = work[0].shape[1]
        seen = np.zeros((span, span), np.bool_)
        grid = np.empty((span, span))
        n_max = largest * (2 * HALF + 1) ** 2
        rr, cc = np.empty(n_max, np.int64), np.empty(n_max, np.int64)
        fixed, resid, light = np.empty(n_max), np.empty(n_max), np.empty(n_max)
        root_w = np.ones(n_max)
        params = np.empty(4 * largest + 1)
        for g in range(chunk * n_groups // _CHUNKS, (chunk + 1) * n_groups // _CHUNKS):
            group = members[offsets[g] : offsets[g + 1]]
            count = window_pixels(spots[:, 1], spots[:, 2], group, rows, cols, rr, cc, seen)
            if count == 0:
                continue
            p = params[: 4 * group.size + 1]
            p[-1] = 0.0
            for k in range(group.size):
                p[4 * k : 4 * k + 4] = spots[group[k]]
                p[-1] += level[group[k]] / group.size
            fixed_light(
                snapshot,
                near[near_offsets[g] : near_offsets[g + 1]],
                rr[:count],
                cc[:count],
                work,
                fixed,
            )
            w, f = root_w[:count], fixed[:count]
            if fit_group(img, rr[:count], cc[:count], p, work, w, f, _ITERATIONS, np.False_):
                for k in range(group.size):
                    spots[group[k]] = p[4 * k : 4 * k + 4]
                    refined[group[k]] = True
                if group.size == 1:
                    _lone_spot_stats(img, rr[:count], cc[:count], p, work, fixed, stats[g])
                else:
                    model_light(img, rr[:count], cc[:count], p, work, fixed, resid, light)
                    stats[g, 0] = np.sum(resid[:count] ** 2)
                    stats[g, 1] = _residual_light(
                        img, rr[:count], cc[:count], p, work, root_w[:count], fixed, light
                    )
                    stats[g, 4] = _neighbour_products(rr[:count], cc[:count], resid, seen, grid)
                stats[g, 2] = count - p.size
                stats[g, 3] = p[-1]


@njit(cache=True)
def start_spots(img, x, y, level, width):  # pragma: no cover (compiled)
    """Starting spots of the fits, (N, 4): A, x₀, y₀, s (DN·px², px, px, px).

    s from :func:`_start_width` (``width`` where it cannot be had) and A such that the
    spot's central pixel holds the particle's maximum pixel above its ``level``; x₀, y₀
    are the particles' centres (x, y)."""
    rows, cols = img.shape
    out = np.empty((x.size, 4))
    for n in range(x.size):
        c0 = min(max(int(x[n] + 0.5), 0), cols - 1)
        r0 = min(max(int(y[n] + 0.5), 0), rows - 1)
        s0 = width
        if 0 < r0 < rows - 1 and 0 < c0 < cols - 1:
            s0 = _start_width(img, r0, c0, level[n], width)
        mass = _pixel_mass(0.0, s0)[0]  # of the centre pixel, per unit amplitude
        out[n, 0] = max(float(img[r0, c0]) - level[n], 1.0) / (mass * mass)
        out[n, 1] = x[n]
        out[n, 2] = y[n]
        out[n, 3] = s0
    return out


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
def workspace(spots):  # pragma: no cover (compiled)
    """Scratch arrays of :func:`fit_group` for groups of up to ``spots`` particles."""
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
