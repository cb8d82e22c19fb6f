"""Compiled (numba) splitting of blended particle images by model selection (private).

After the refinement (:mod:`ptv.detect._refine`) every group of detections has a
fitted model: one pixel-integrated Gaussian spot per detection. Here each group is
asked whether one more spot explains its pixels significantly better, with the fitting
of :mod:`ptv.detect._refine` (:func:`~ptv.detect._refine.fit_group`), now weighted by
1/σ_p², σ_p² = c·σ_n² + γ·m_p (read and background noise from the background estimate,
shot noise γ·m_p of the model's light m_p; c and γ measured on the image by
:func:`ptv.detect.locate._noise_model`). Per group (:func:`split_groups`):

1. Rescue: a group whose refinement failed (a blend's one-spot fit converges slowly,
   its width, amplitude and background strongly correlated) is fitted again, weighted,
   with longer, clamped Gauss–Newton.
2. Screen: the weighted residual χ² over each spot's 5 × 5 window. A spot is a candidate
   when it exceeds :data:`SCREEN_CHI2` or when the detector flagged it ELONGATED; the
   worst candidate is tried.
3. Trial (:func:`_trial`): the spot and the group's spots within
   :data:`_LOCAL_DISTANCE` of it are fitted over their windows and the 7 × 7 pixels
   around it, the group's other spots and its neighbours held fixed: as they are, and
   with the spot replaced by two, started on either side of its light's centroid along
   the principal axis of its second moments (failing that: the spot as it is and one
   more at the largest weighted residual).
4. Test: the split is kept when it lowers χ² by more than :data:`SPLIT_CHI2` and its
   two spots are at least :data:`MIN_SEPARATION` px apart. Then the next candidate is
   tried, up to :data:`MAX_ADDED` spots added to a group and :data:`_MAX_TRIALS`
   trials.

The threshold and the false-split rate it gives are discussed in
:mod:`ptv.detect.locate` (step 6).

These functions call :mod:`ptv.detect._refine`'s compiled functions, which numba
compiles into this module's cached code; its cache notices changes to this file only:
after editing ``_refine.py``, delete ``ptv/detect/__pycache__`` (an installed package
is fresh either way).
"""

from math import sqrt

import numpy as np
from numba import njit

from ptv._threads import over_threads
from ptv.detect._refine import (
    HALF,
    _pixel_mass,
    fit_group,
    fixed_light,
    model_light,
    window_pixels,
    workspace,
)

#: A split is kept when it lowers the weighted χ² by more than this (module docstring).
SPLIT_CHI2 = 20.0
#: A spot whose 5 × 5 window has a weighted residual χ² above this is tried for a split
#: (≈ 20 degrees of freedom: exceeded with probability < 10⁻² by a well-fitted spot).
SCREEN_CHI2 = 39.0
#: Split spots closer than this, px, are one spot of another shape, not two particles
#: (and a spot split off this close to any other detection is a duplicate, which
#: :func:`ptv.detect.locate._undouble` drops or merges).
MIN_SEPARATION = 0.8
#: At most this many spots are added to a group in one round of the split stage (a
#: triple blend needs two; a group of six detections at 0.03 particles per pixel often
#: holds two blends). From 2 to 4 with 4 to 10 trials, in a single round: rms error
#: 0.082 → 0.078 px at 0.01 particles per pixel, 0.175 → 0.158 at 0.03
#: (benchmarks/bench_dense.py).
MAX_ADDED = 4
#: Gauss–Newton steps at most of the trial fits: a blend's one-spot fit can take many,
#: its width, amplitude and background being strongly correlated on a few pixels
#: (a NumPy integer: see :data:`ptv.detect._refine._ITERATIONS`).
_ITERATIONS = np.int64(25)
#: A trial frees the spots closer than this to the one it splits, px; the group's
#: other spots are held fixed (their light on its pixels is small, and already fitted).
_LOCAL_DISTANCE = 4.0
#: Split trials per group at most (each costs two or three weighted fits); more than 10
#: (20, with 8 spots added) changed the dense benchmark's figures by under 0.003 px.
_MAX_TRIALS = 10
#: Separation of the two starting spots of a trial, px: from the second moments,
#: within these bounds.
_START_SEPARATION = (0.8, 2.0)
#: Width of the starting spots of a trial, px: from the second moments, within these.
_START_WIDTH = (0.5, 1.5)
_CHUNKS = 64


@njit(cache=True)
def _weights(light, noise2, gamma, count, root_w):  # pragma: no cover (compiled)
    """root_w = 1/σ_p with σ_p² = noise2 + γ·max(light, 0), DN⁻¹."""
    for p in range(count):
        root_w[p] = 1.0 / sqrt(noise2 + gamma * max(light[p], 0.0))


@njit(cache=True)
def _chi2(img, rr, cc, params, work, fixed, root_w, resid, light):  # pragma: no cover
    """Σ (root_w·(I − model))² of ``params`` over the pixels (rr, cc)."""
    model_light(img, rr, cc, params, work, fixed, resid, light)
    total = 0.0
    for p in range(rr.size):
        total += (root_w[p] * resid[p]) ** 2
    return total


@njit(cache=True)
def _worst(rr, cc, resid, root_w, lx, ly, n_loc, candidate, tested):  # pragma: no cover
    """The untested spot whose 5 × 5 window has the largest weighted χ², if it is a
    candidate (flagged, or χ² above :data:`SCREEN_CHI2`); -1 if none."""
    best, best_chi = -1, -1.0
    for k in range(n_loc):
        if tested[k]:
            continue
        c0, r0 = int(lx[k] + 0.5), int(ly[k] + 0.5)
        chi = 0.0
        for p in range(rr.size):
            if abs(cc[p] - c0) <= HALF and abs(rr[p] - r0) <= HALF:
                chi += (root_w[p] * resid[p]) ** 2
        if (candidate[k] or chi > SCREEN_CHI2) and chi > best_chi:
            best, best_chi = k, chi
    return best


@njit(cache=True)
def _starts(rr, cc, resid, root_w, params, k, work, out):  # pragma: no cover (compiled)
    """Two starts of a split of spot k, into ``out`` (2, 2, 4): per start, the spot k
    becomes and the spot added (A, x₀, y₀, s).

    From the residuals and the masses (in ``work``) of the last
    :func:`~ptv.detect._refine.model_light` call, over the 7 × 7 pixels around spot k.
    Start 0: two halves of spot k on either side of the centroid of its own light
    (residual plus its model) along the principal axis of its second moments, as wide
    as the moments across that axis make them. Start 1: spot k as it is and a spot at
    the largest weighted residual."""
    ex, ey = work[0][k], work[1][k]
    r_lo, c_lo = rr.min(), cc.min()
    a, x0, y0, s = params[4 * k], params[4 * k + 1], params[4 * k + 2], params[4 * k + 3]
    c0, r0 = int(x0 + 0.5), int(y0 + 0.5)
    m0 = mx = my = mxx = myy = mxy = 0.0
    top, top_p = -np.inf, -1
    for p in range(rr.size):
        dx, dy = cc[p] - c0, rr[p] - r0
        if abs(dx) > HALF + 1 or abs(dy) > HALF + 1:
            continue
        own = resid[p] + a * ex[cc[p] - c_lo, 0] * ey[rr[p] - r_lo, 0]
        if own > 0.0:
            m0 += own
            mx += own * dx
            my += own * dy
            mxx += own * dx * dx
            myy += own * dy * dy
            mxy += own * dx * dy
        if root_w[p] * resid[p] > top:
            top, top_p = root_w[p] * resid[p], p
    if not m0 > 0.0 or top_p < 0:
        return False
    mx, my = mx / m0, my / m0
    vxx, vyy, vxy = mxx / m0 - mx * mx, myy / m0 - my * my, mxy / m0 - mx * my
    root = sqrt(0.25 * (vxx - vyy) ** 2 + vxy * vxy)  # half the eigenvalues' difference
    ux, uy = (1.0, 0.0) if vxx >= vyy else (0.0, 1.0)
    if abs(vxy) > 1e-9:
        ux, uy = vxy, 0.5 * (vyy - vxx) + root  # along the larger eigenvalue's axis
    norm = sqrt(ux * ux + uy * uy)
    lo, hi = _START_SEPARATION
    d = 0.5 * min(max(2.0 * sqrt(2.0 * root), lo), hi)
    across = 0.5 * (vxx + vyy) - root - 1.0 / 12.0  # σ² across the axis, less the pixel's
    width = min(max(sqrt(max(across, 0.0)), _START_WIDTH[0]), _START_WIDTH[1])
    for side in range(2):
        sign = 1.0 if side == 0 else -1.0
        out[0, side, 0] = 0.5 * a
        out[0, side, 1] = c0 + mx + sign * d * ux / norm
        out[0, side, 2] = r0 + my + sign * d * uy / norm
        out[0, side, 3] = width
    out[1, 0, 0], out[1, 0, 1], out[1, 0, 2], out[1, 0, 3] = a, x0, y0, s
    out[1, 1, 0] = max(resid[top_p], 1.0) / _pixel_mass(0.0, width)[0] ** 2
    out[1, 1, 1], out[1, 1, 2], out[1, 1, 3] = cc[top_p], rr[top_p], width
    return True


@njit(cache=True)
def _local(p, n_loc, k, sc):  # pragma: no cover (compiled)
    """Spot k and the group's spots within :data:`_LOCAL_DISTANCE` of it, the spots a
    trial frees: their indices into ``sc[15]``, the others' spots into ``sc[16]``,
    their positions and the corners of the 7 × 7 around spot k into ``sc[8:10]``.
    Returns the number freed, spot k's place among them and the number held."""
    lx, ly, free, held = sc[8], sc[9], sc[15], sc[16]
    n_free = n_held = 0
    xk, yk = p[4 * k + 1], p[4 * k + 2]
    for j in range(n_loc):
        x0, y0 = p[4 * j + 1], p[4 * j + 2]
        if (x0 - xk) ** 2 + (y0 - yk) ** 2 < _LOCAL_DISTANCE**2:
            if j == k:
                place = n_free
            free[n_free] = j
            lx[n_free], ly[n_free] = x0, y0
            n_free += 1
        else:
            held[n_held] = p[4 * j : 4 * j + 4]
            n_held += 1
    for j in range(4):
        lx[n_free + j] = xk + (1.0 if j % 2 else -1.0)
        ly[n_free + j] = yk + (1.0 if j // 2 else -1.0)
    return n_free, place, n_held


@njit(cache=True)
def _trial(img, p, n_loc, k, near, noise2, gamma, snapshot, sc):  # pragma: no cover
    """Fit spot k and its close neighbours (:func:`_local`; the group's other spots and
    its neighbours held fixed), and the same with spot k split in two, over the same
    pixels (their windows and the 7 × 7 around spot k) and weights (from ``p``'s
    light). When the split passes the test, ``p`` (n_loc spots) takes the fit's spots
    and the one added, and True is returned."""
    work, seen, rr, cc, fixed, resid, light, root_w, lx, ly, idx, starts, p1, p2, best = sc[:15]
    free, held = sc[15], sc[16]
    n_free, kf, n_held = _local(p, n_loc, k, sc)
    rows, cols = img.shape
    count = window_pixels(lx, ly, idx[: n_free + 4], rows, cols, rr, cc, seen)
    if count == 0:
        return False
    r, c, f = rr[:count], cc[:count], fixed[:count]
    fixed_light(held, idx[:n_held], r, c, work, light)
    fixed_light(snapshot, near, r, c, work, fixed)
    f += light[:count]
    n_par = 4 * n_free + 1
    q1 = p1[:n_par]
    for i in range(n_free):
        q1[4 * i : 4 * i + 4] = p[4 * free[i] : 4 * free[i] + 4]
    q1[-1] = p[4 * n_loc]
    model_light(img, r, c, q1, work, fixed, resid, light)
    _weights(light, noise2, gamma, count, root_w)
    w = root_w[:count]
    if not fit_group(img, r, c, q1, work, w, f, _ITERATIONS, np.True_):
        return False
    chi_one = _chi2(img, r, c, q1, work, fixed, w, resid, light)
    if not _starts(r, c, resid, w, q1, kf, work, starts):
        return False
    chi_best = np.inf
    q2 = p2[: n_par + 4]
    for start in range(2):
        q2[: 4 * n_free] = q1[: 4 * n_free]
        q2[4 * kf : 4 * kf + 4] = starts[start, 0]
        q2[4 * n_free : 4 * n_free + 4] = starts[start, 1]
        q2[-1] = q1[-1]
        if not fit_group(img, r, c, q2, work, w, f, _ITERATIONS, np.True_):
            continue
        gap_x = q2[4 * kf + 1] - q2[4 * n_free + 1]
        gap = sqrt(gap_x**2 + (q2[4 * kf + 2] - q2[4 * n_free + 2]) ** 2)
        chi = _chi2(img, r, c, q2, work, fixed, w, resid, light)
        if gap >= MIN_SEPARATION and chi < chi_best:
            chi_best = chi
            best[: n_par + 4] = q2
        if chi_one - chi_best > SPLIT_CHI2:
            break  # the second start is for when the first does not pass
    if not chi_one - chi_best > SPLIT_CHI2:
        return False
    for i in range(n_free):
        p[4 * free[i] : 4 * free[i] + 4] = best[4 * i : 4 * i + 4]
    p[4 * n_loc : 4 * n_loc + 4] = best[4 * n_free : 4 * n_free + 4]
    p[4 * n_loc + 4] = best[n_par + 3]
    return True


@njit(cache=True)
def _split_group(img, group, p, fitted, near, noise2, gamma, candidate, snapshot, sc, origin):
    """Split the spots of one group (:func:`split_groups`) while the test says so.

    ``p`` holds the group's spots and background on entry (fitted or not) and its model
    on return; ``origin`` (≥ n + MAX_ADDED) receives each spot's detection (an added
    spot: the detection it was split from). Returns the number of spots added, -1 when
    ``p`` is unchanged."""
    work, seen, rr, cc, fixed, resid, light, root_w, lx, ly, idx = sc[:11]
    rows, cols = img.shape
    n_loc = group.size
    if not fitted and not _rescue(img, p, n_loc, near, noise2, gamma, snapshot, sc):
        return -1
    tested = np.zeros(n_loc + MAX_ADDED, np.bool_)
    flagged = np.zeros(n_loc + MAX_ADDED, np.bool_)
    for k in range(n_loc):
        origin[k] = group[k]
        flagged[k] = candidate[group[k]]
    for _ in range(_MAX_TRIALS):
        if n_loc == group.size + MAX_ADDED:
            break
        for k in range(n_loc):
            lx[k], ly[k] = p[4 * k + 1], p[4 * k + 2]
        count = window_pixels(lx, ly, idx[:n_loc], rows, cols, rr, cc, seen)
        if count == 0:
            break
        r, c = rr[:count], cc[:count]
        fixed_light(snapshot, near, r, c, work, fixed)
        model_light(img, r, c, p[: 4 * n_loc + 1], work, fixed, resid, light)
        _weights(light, noise2, gamma, count, root_w)
        k = _worst(r, c, resid, root_w, lx, ly, n_loc, flagged, tested)
        if k < 0:
            break
        tested[k] = True
        if _trial(img, p, n_loc, k, near, noise2, gamma, snapshot, sc):
            origin[n_loc] = origin[k]
            tested[k] = flagged[k] = False  # the two may hide a third
            n_loc += 1
    return n_loc - group.size if n_loc > group.size or not fitted else -1


@njit(cache=True)
def _rescue(img, p, n_loc, near, noise2, gamma, snapshot, sc):  # pragma: no cover
    """Fit a group whose refinement failed, weighted and with the trials' longer and
    clamped Gauss–Newton (a blend's one-spot fit, slow to converge, is the usual
    case); True, and ``p`` fitted, if it converged."""
    work, seen, rr, cc, fixed, resid, light, root_w, lx, ly, idx = sc[:11]
    rows, cols = img.shape
    for k in range(n_loc):
        lx[k], ly[k] = p[4 * k + 1], p[4 * k + 2]
    count = window_pixels(lx, ly, idx[:n_loc], rows, cols, rr, cc, seen)
    if count == 0:
        return False
    r, c = rr[:count], cc[:count]
    fixed_light(snapshot, near, r, c, work, fixed)
    model_light(img, r, c, p[: 4 * n_loc + 1], work, fixed, resid, light)
    _weights(light, noise2, gamma, count, root_w)
    q = sc[12][: 4 * n_loc + 1]
    q[:] = p[: 4 * n_loc + 1]
    if not fit_group(img, r, c, q, work, root_w[:count], fixed[:count], _ITERATIONS, np.True_):
        return False
    p[: 4 * n_loc + 1] = q
    return True


def split_groups(
    img, spots, background, level, noise2, gamma, candidate, members, offsets, near, near_offsets
):
    """Split blended spots of the fitted groups by the test of the module docstring.

    Parameters
    ----------
    img : ndarray (H, W)
        The image, DN.
    spots : ndarray (N, 4)
        Fitted A, x₀, y₀, s of each detection (DN·px², px, px, px); updated in place for
        the members of the groups split.
    background : ndarray (n_groups,)
        Fitted background of each group, DN; NaN where the refinement failed: the group
        is then fitted again first, weighted, from the spots given and ``level``.
    level : ndarray (N,)
        Background at each detection, DN.
    noise2 : ndarray (N,)
        σ_n² at each detection, DN².
    gamma : float
        Shot-noise variance per DN of light, DN.
    candidate : ndarray of bool (N,)
        Detections tried for a split whatever their residuals (flagged ELONGATED).
    members, offsets, near, near_offsets : ndarray of int
        The groups and their neighbours held fixed, as in
        :func:`ptv.detect._refine.refine_groups`.

    Returns
    -------
    added : ndarray (n_groups · MAX_ADDED, 4)
        The spots added, group after group, MAX_ADDED slots each.
    parent : ndarray of int (n_groups · MAX_ADDED,)
        The detection each added spot was split from; -1 for an unused slot.
    """
    n_groups = offsets.size - 1
    added = np.zeros((n_groups * MAX_ADDED, 4))
    parent = np.full(n_groups * MAX_ADDED, -1, np.int64)
    largest = int(np.diff(offsets).max(initial=1))
    over_threads(
        _split_chunks,
        _CHUNKS,
        img,
        spots,
        background,
        level,
        noise2,
        gamma,
        candidate,
        members,
        offsets,
        near,
        near_offsets,
        spots.copy(),
        largest,
        added,
        parent,
    )
    return added, parent


@njit(cache=True, nogil=True, error_model="numpy")
def _split_chunks(
    first,
    stop,
    img,
    spots,
    background,
    level,
    noise2,
    gamma,
    candidate,
    members,
    offsets,
    near,
    near_offsets,
    snapshot,
    largest,
    added,
    parent,
):  # pragma: no cover (compiled)
    """Chunks ``first … stop − 1`` of :func:`split_groups` (of groups of at most
    ``largest`` detections; ``snapshot``: the spots before any split), into ``spots``,
    ``added`` and ``parent``."""
    n_groups = offsets.size - 1
    for chunk in range(first, stop):
        n_spots = largest + MAX_ADDED
        work = workspace(n_spots + 4)
        span = work[0].shape[1]
        n_max = (n_spots + 4) * (2 * HALF + 1) ** 2
        sc = (
            work,
            np.zeros((span, span), np.bool_),
            np.empty(n_max, np.int64),
            np.empty(n_max, np.int64),
            np.empty(n_max),
            np.empty(n_max),
            np.empty(n_max),
            np.empty(n_max),
            np.empty(n_spots + 4),
            np.empty(n_spots + 4),
            np.arange(n_spots + 4),
            np.empty((2, 2, 4)),
            np.empty(4 * n_spots + 1),
            np.empty(4 * n_spots + 1),
            np.empty(4 * n_spots + 1),
            np.empty(n_spots, np.int64),
            np.empty((n_spots, 4)),
        )
        p = np.empty(4 * n_spots + 1)
        origin = np.empty(n_spots, np.int64)
        for g in range(chunk * n_groups // _CHUNKS, (chunk + 1) * n_groups // _CHUNKS):
            group = members[offsets[g] : offsets[g + 1]]
            fitted = background[g] == background[g]
            var_n = bg = 0.0
            for k in range(group.size):
                p[4 * k : 4 * k + 4] = spots[group[k]]
                var_n += noise2[group[k]] / group.size
                bg += level[group[k]] / group.size
            p[4 * group.size] = background[g] if fitted else bg
            around = near[near_offsets[g] : near_offsets[g + 1]]
            n_new = _split_group(
                img, group, p, fitted, around, var_n, gamma, candidate, snapshot, sc, origin
            )
            if n_new < 0:
                continue
            for k in range(group.size):
                spots[group[k]] = p[4 * k : 4 * k + 4]
            for j in range(n_new):
                k = group.size + j
                added[g * MAX_ADDED + j] = p[4 * k : 4 * k + 4]
                parent[g * MAX_ADDED + j] = origin[k]
