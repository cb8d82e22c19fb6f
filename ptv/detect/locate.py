"""Particle detection: threshold, local maxima, region splitting, sub-pixel centres, blends.

Pipeline (the compiled passes are in :mod:`ptv.detect._kernels`), made for spots of about
3 px; for larger ones, given their ``diameter``, it runs on sums of pixel blocks
(:mod:`ptv.detect._blocks`):

1. Background level B and noise σ_n (:func:`ptv.detect.estimate_background`, median and
   MAD, globally or per tile); threshold T = B + k·σ_n (k: ``threshold_sigmas``).
2. Local maxima above T (8-neighbourhood). Each seeds an 8-connected region of the
   pixels above T.
3. A region holding several maxima is split between those that are *resolved*: a
   maximum is kept when, on the straight line to every brighter kept maximum of its
   region, the intensity dips below its own peak by at least
   max(min_dip · (peak − B), dip_sigmas · σ_n). The other maxima (noise bumps on a
   spot) are dropped. Each pixel goes to the nearest kept maximum; the particles of a
   split region are flagged OVERLAP. A single-maximum region whose intensity-weighted
   second moments (plus 1/12 px² for the pixel extent) have an eigenvalue ratio above
   ``max_elongation`` is flagged ELONGATED (likely two unresolved particles). A region
   with more than 64 maxima (a blob, or a threshold inside the noise) is not split but
   reported once, at its brightest maximum, flagged ELONGATED.
4. Sub-pixel centre, ``estimator``:

   - ``"gauss"`` (default): weighted least-squares fit of a separable Gaussian,
     ln(I − B) = c₀ + c₁x + c₂y + c₃x² + c₄y², to the pixels of the 3 × 3 block around
     the maximum with I > B and the particle's pixels above T in the surrounding 5 × 5
     ring, weights (I − B)² (the inverse variance of ln I for constant noise, up to
     a factor); x̂ = i − c₁/(2c₃), ŷ = j − c₂/(2c₄). On the cross of five pixels alone
     it is the 3-point Gaussian; the other pixels lower its random error. In a split
     region the first fit leaves out the pixels nearer to another maximum; then every
     particle is refitted twice on all its pixels after subtracting the other
     particles' fitted Gaussians (deblending). Where the fit is ill-posed (singular,
     not concave, shift > 1 px) the 3-point Gaussian is used, and failing that the
     centroid (flag FALLBACK).
     The centres are then refined by least squares in linear intensity (step 5).
   - ``"gauss3"``: the 3-point Gaussian estimator along x and along y through the
     maximum pixel, on background-subtracted values (docs/imaging.md §5),
     x̂ = i + [ln I₋ − ln I₊] / [2(ln I₋ − 2 ln I₀ + ln I₊)]. Where a logarithm is
     undefined (a value <= B), the profile is not concave or the maximum is on the
     border, the centroid is used on that axis (flag FALLBACK).
   - ``"centroid"``: threshold-subtracted centre of mass, x̂ = Σ(I − T)₊x / Σ(I − T)₊,
     over the particle's pixels within ``radius`` of its maximum pixel (a
     (2·radius + 1)² window).

   Saturated particles always get the centroid (a flat top has no curvature).
5. ``"gauss"`` only: joint refinement (:mod:`ptv.detect._refine`). Each group of
   detections closer than :data:`GROUP_DISTANCE_PX` to one another (a lone one is a
   group of one) is fitted jointly, over the union of their 5 × 5 windows, with the sum
   of pixel-integrated Gaussians A·E(i − x₀)·E(j − y₀) (erf differences; amplitude,
   centre and width free per spot) and one background B, by Gauss–Newton from the log
   fits' centres. No threshold or logarithm shapes that estimate, which removes the log
   fit's pull towards pixel centres at low signal (0.008 px at 300–700 e⁻ per spot
   over 8 e⁻ of read noise, under 0.003 px refined), and a neighbour's light is fitted
   instead of cut off, so the error of a resolved pair does not depend on where the
   neighbour is (uncorrelated between the frames of a pair). A chain of more than
   :data:`MAX_GROUP` detections (common from 0.01 particles per pixel) is cut into
   pieces that are fitted with their neighbours' spots held fixed: first their
   starting spots, then, in a second pass, their fits (:mod:`ptv.detect._groups`).
   Groups holding a saturated or edge detection or a blob, or within
   :data:`GROUP_DISTANCE_PX` of one, keep the log fits.
6. ``"gauss"`` only: blends (:mod:`ptv.detect._split`). Two particles closer than about
   2σ make one spot with one maximum; the dip test cannot split it, and one fitted
   spot stands for both, at their middle. Every fitted group is asked whether one
   spot more explains its pixels significantly better:

   - The pixel variance is modelled as σ_p² = c·σ_n² + γ·m_p, m_p the light of the
     fitted spots on the pixel and γ the camera's gain in DN per photo-electron
     (Poisson shot noise), measured on the image itself from the residuals of the
     groups whose residuals are white (:func:`_noise_model`): no camera data needed.
   - A spot whose 5 × 5 window leaves a weighted residual χ² above 39 (≈ 20 degrees of
     freedom: a well-fitted spot exceeds it with probability < 10⁻²), or that was
     flagged ELONGATED, is tried: it and its neighbours within 4 px are refitted,
     weighted by 1/σ_p², once as they are and once with the spot replaced by two
     (started on either side of its light's centroid along its long axis), over the
     same pixels, the rest of the group and its neighbours held fixed.
   - The split is kept when Δχ² = χ²(one) − χ²(two) > 20 and the two spots are at
     least 0.8 px apart. Δχ² is twice the log-likelihood ratio of the two models for
     Gaussian noise of known variance; for a second spot at a fixed place it would
     follow χ²₄ under one spot (4 more parameters), and P(χ²₄ > 20) = 5·10⁻⁴. The place
     is fitted, which can only raise Δχ², so the false-split rate was measured on
     isolated single spots: 4 of 20250 (σ 0.7–1.0 px, 800–8000 e⁻) and 16 of 60750
     faint ones (800–2000 e⁻, σ 0.85–1.0 px), i.e. below 10⁻³ per spot; of the faint
     spots that noise made look elongated (1.7 %), 1 % are split. (A BIC penalty,
     4·ln n ≈ 16 for n ≈ 50 pixels, would split more; 20 keeps the rate below 10⁻³
     while pairs 1.2 px apart are still split.) A group may gain several spots (a
     triple needs two), up to :data:`ptv.detect._split.MAX_ADDED` per round.
   - Groups are tried side by side, each with its neighbours' light as it was before,
     so two of them can both add a spot for one particle hidden between them. Closer
     than 0.8 px, spots are one particle: two spots split off become one at their mean,
     one split off onto a detection is dropped, and a detection moved onto another is
     put back (:func:`_undouble`).
   - The stage runs in rounds (at most :data:`_SPLIT_ROUNDS`): after each, the groups
     are formed again, and those holding a particle split off are refitted with it and
     tried again. A spot split off is light that neither its group's first fit nor its
     neighbours' modelled; with it modelled, the faint neighbours of a blend show.
   - A particle split off a blend follows, in the result, the detection it was split
     from; both are flagged OVERLAP (no longer ELONGATED or FALLBACK), and share its
     intensity, peak and size in proportion to their fitted amplitudes.

   Measured with the test's own rendering (tests/ptv/detect/test_detect_blends.py):
   pairs 1.2, 1.5 and 1.8 px apart, σ = 0.8 px, 4000 + 4000 or 4000 + 2000 e⁻, are
   split in 59–60 of 60, their centres' errors at the Cramér–Rao bound (rms of
   error / σ_CR 0.85–1.2). On uniformly random particles (benchmarks/bench_dense.py,
   σ 0.7–1.0 px, 800–8000 e⁻): found / rms 0.998 / 0.051 px at 0.002 particles per
   pixel, 0.984 / 0.075 px at 0.01, 0.927 / 0.140 px at 0.03, false detections 0.06 /
   0.17 / 1.7 %; what is missed is mostly pairs closer than 1.2 px, which no fit can
   tell from one spot. Up to 0.01 the error is within 1.2× of the Cramér–Rao bound of
   the particles that can be located to 0.1 px, 1.7× at 0.03; over all found particles
   it is about that of an efficient detector resolving every pair from 1.0 px, at 0.01
   (0.074 px) and at 0.03 (0.139 px; it finds 0.952). The model test costs time even
   on sparse frames, where it splits about 1 % of the detections: about 60 % more on
   those of benchmarks/bench_detect.py, 80–90 % more on paper-10hz's (15–16 → 28–31 ms
   per image on one core, side by side).

Measured on pixel-integrated Gaussian spots rendered with known centres (12-bit sensor,
gain 0.4 DN/e⁻, 8 e⁻ read noise, 5 e⁻ background, k = 6), gauss / gauss3 / centroid:

- Noise-free bias, max over sub-pixel positions, float image: 0.013 / 0.013 / 0.014 px
  at σ = 0.4 px (the pixel-integration limit of docs/imaging.md §6), 0.0022 / 0.0022 /
  0.0003 at 0.6, 0.0004 / 0.0007 / 0.0001 at 0.75, 0.0001 / 0.0002 / 0.0015 at 0.9,
  0.0001 / 0.0000 / 0.017 at 1.2 (the 7 × 7 window truncates the centroid).
  Rounding to DN adds up to ~0.005 px.
- Random error per axis at σ = 0.75 px and 1000 / 3000 / 10⁴ e⁻ per spot (peak SNR
  ≈ 30 / 90 / 300): 0.049 / 0.023 / 0.011 px, 0.064 / 0.032 / 0.017 px and
  0.060 / 0.024 / 0.010 px. The 3-point Gaussian uses five pixels and is noisier.
- Peak locking under noise: the threshold cut biases the centroid periodically, with an
  amplitude of 0.02–0.05 px (towards pixel edges at peak SNR ≲ 40, towards centres at
  ~100), easily seen by :func:`ptv.detect.peak_locking`; both Gaussian estimators stay
  below 0.008 px. Hence the default.
- Pairs of spots: the dip test of step 3 alone splits 90 / 60 / 20 % of them at
  2.5 px apart and 100 / 99 / 80 % at 3 px, for σ = 0.6 / 0.75 / 0.9 px; the model
  test of step 6 splits the rest, and pairs down to ~1.2 px (above). The gauss3 and
  centroid estimators have neither step: their unsplit pairs come out as one
  detection, flagged ELONGATED for most (2 px apart: ≥ 98 % of pairs split or
  flagged), and the error of their split pairs 3 px apart is 0.08 / 0.11 px (2-D rms,
  σ = 0.75 / 0.9 px) with the centroid.
"""

import logging
import time
from typing import Literal

import numpy as np
from scipy.spatial import cKDTree
from scipy.stats import chi2

from ptv.detect import _blocks, _kernels
from ptv.detect import _refine as _refine_kernels
from ptv.detect import _split as _split_kernels
from ptv.detect._groups import GROUP_DISTANCE_PX, MAX_GROUP, Groups, fit_groups
from ptv.detect._image import check_image, check_integer, check_number, saturation_level
from ptv.detect.background import BackgroundEstimate, estimate_background
from ptv.detect.detections import DetectionFlag, Detections

logger = logging.getLogger(__name__)

Estimator = Literal["gauss", "gauss3", "centroid"]
_ESTIMATORS = {"gauss": _kernels.GAUSS, "gauss3": _kernels.GAUSS3, "centroid": _kernels.CENTROID}

__all__ = ["GROUP_DISTANCE_PX", "MAX_GROUP", "detect_particles"]

#: Starting Gaussian width of the refinement, px (d_τ ≈ 3 px spots, docs/imaging.md §1).
_REFINE_START_WIDTH = 0.8
#: Detections whose light is not one Gaussian spot: they and their groups are not refined
#: (nor are the blobs: regions with too many maxima to split).
_UNMODELLED = int(DetectionFlag.SATURATED | DetectionFlag.EDGE)
#: Fits of the groups whose neighbours are held fixed (pieces of long chains): each
#: takes the neighbours' spots of the fit before.
_DENSE_SWEEPS = 2
#: The noise model's bins (:func:`_noise_model`): at most this many, of at least this
#: many groups each; its smallest scale of σ_n².
_NOISE_BINS = 8
_NOISE_BIN_GROUPS = 20
_MIN_NOISE_SCALE = 0.05
_NOISE_ROUNDS = 3
#: Lone detections whose residual χ² is below this share of the split stage's screen
#: are not looked at there (:func:`_worth_trying`).
_PRESCREEN = 0.75
#: Groups whose adjacent residuals correlate more than this are not noise (blends).
_WHITE_LIMIT = 0.2
#: Flags a particle split from a blend no longer carries.
_EXPLAINED = int(DetectionFlag.ELONGATED | DetectionFlag.FALLBACK)
#: Rounds of the split stage at most (:func:`_refine`). At 0.03 particles per pixel,
#: 1 → 2 → 4 rounds: found 0.914 → 0.926 → 0.927, rms error 0.160 → 0.142 → 0.140 px
#: (benchmarks/bench_dense.py); most images need two or three.
_SPLIT_ROUNDS = 4


def _fit_spots(
    img: np.ndarray, xy: np.ndarray, unmodelled: np.ndarray, level: np.ndarray
) -> tuple[np.ndarray, Groups, np.ndarray]:
    """Refine the detections by groups: their spots (N, 4: A, x₀, y₀, s; the starting
    spots where not refined), the groups and the groups' fit statistics
    (:func:`ptv.detect._refine.refine_groups`)."""
    x, y = np.ascontiguousarray(xy[:, 0]), np.ascontiguousarray(xy[:, 1])
    spots = _refine_kernels.start_spots(img, x, y, level, _REFINE_START_WIDTH)
    spots[unmodelled, 0] = 0.0  # their light is not modelled, nor held fixed
    groups = fit_groups(xy, unmodelled)
    refined, stats = _refine_kernels.refine_groups(img, spots, level, *groups, spots.copy())
    dense = groups.has_near
    if dense.any():
        pieces = groups.subset(dense)
        for _ in range(_DENSE_SWEEPS - 1):
            again, piece_stats = _refine_kernels.refine_groups(
                img, spots, level, *pieces, spots.copy()
            )
            refined |= again
            ok = piece_stats[:, 2] > 0
            stats[np.flatnonzero(dense)[ok]] = piece_stats[ok]
    logger.debug(
        "%d of %d detections refined in %d groups (%d with neighbours held fixed)",
        int(refined.sum()),
        len(xy),
        len(groups.offsets) - 1,
        int(dense.sum()),
    )
    return spots, groups, stats


def _noise_model(stats: np.ndarray, groups: Groups, noise2: np.ndarray) -> tuple[float, float]:
    """(c, γ): a pixel's variance is c·σ_n² + γ·m (DN²), σ_n the background estimate's
    noise there and m the light of the fitted spots on it, DN; γ is the gain in DN per
    photo-electron, c ≈ 1 (below 1 where the tails of dense spots raise σ_n).

    Measured on the residuals of the fitted groups (a photon-transfer curve): a group's
    Σ r² is expected to be c·σ_n²·dof + γ·L, L = Σ (1 − h_p)·m_p
    (:func:`ptv.detect._refine.refine_groups`), so y = Σ r² / (σ_n²·dof) is c + γ·x
    with x = L / (σ_n²·dof). Only groups whose residuals look like white noise count:
    the correlation of adjacent residuals below :data:`_WHITE_LIMIT` (single spots:
    −0.73 to 0.13, 5–95 %; a blend leaves residuals of one sign over several pixels,
    0.4–0.6). The line is fitted through the medians of x and of y / (1 − 2/(9 dof))³
    (the median of χ²_dof/dof: robust to the blends left) in at most
    :data:`_NOISE_BINS` bins of x of at least :data:`_NOISE_BIN_GROUPS` groups, then
    again :data:`_NOISE_ROUNDS` − 1 times through the bins' means of y (unbiased,
    whatever the spread of the pixel variances within a group) without the groups
    whose y is above the 0.999 quantile of χ²_dof/dof times the line.
    Where the bins' x span less than a factor 2, c and γ cannot be told apart: c = 1.
    With too few groups for two bins, c = 1 and γ is the median of (y′ − 1)/x; (1, 0)
    when no fitted group's residuals look white. That happens when every particle image
    is blended or not a Gaussian spot (an image holding only pairs 1.5 px apart): the
    split test then takes the spots' shot noise for structure, and how many blends it
    splits varies from image to image.
    """
    sizes = np.diff(groups.offsets)
    dof, light, square = stats[:, 2], stats[:, 1], stats[:, 0]
    ok = (dof > 0) & (light > 0) & (stats[:, 4] < _WHITE_LIMIT * square)
    if not ok.any():
        return 1.0, 0.0
    var_n = np.add.reduceat(noise2[groups.members], groups.offsets[:-1])[ok] / sizes[ok]
    order = np.argsort(light[ok] / (var_n * dof[ok]))  # by x, so that bins are runs
    var_n, dof = var_n[order], dof[ok][order]
    x = light[ok][order] / (var_n * dof)
    y = square[ok][order] / (var_n * dof)
    y_median = y / (1.0 - 2.0 / (9.0 * dof)) ** 3
    c, gamma = 1.0, max(float(np.median((y_median - 1.0) / x)), 0.0)
    levels, index = np.unique(dof, return_inverse=True)
    limit = (chi2.ppf(0.999, levels) / levels)[index]
    keep = np.arange(x.size)  # the first round keeps every group
    for step in range(_NOISE_ROUNDS):
        n_bins = min(_NOISE_BINS, keep.size // _NOISE_BIN_GROUPS)
        if n_bins < 2:
            break
        bins = keep[: keep.size - keep.size % n_bins].reshape(n_bins, -1)  # runs of x
        bx = np.median(x[bins], axis=1)
        by = np.median(y_median[bins], axis=1) if step == 0 else np.mean(y[bins], axis=1)
        gamma, c = np.polyfit(bx, by, 1)
        if bx[-1] < 2.0 * bx[0] or c <= _MIN_NOISE_SCALE:  # refit γ alone
            c = 1.0 if bx[-1] < 2.0 * bx[0] else _MIN_NOISE_SCALE
            gamma = float(np.sum((by - c) * bx) / np.sum(bx**2))
        gamma = max(float(gamma), 0.0)
        keep = np.flatnonzero(y <= limit * (c + gamma * x))
    return float(c), gamma


def _worth_trying(
    stats: np.ndarray, groups: Groups, var_n: np.ndarray, gamma: float, candidate: np.ndarray
) -> np.ndarray:
    """(n_groups,) bool: the groups the split stage looks at: all but the lone, fitted
    detections not flagged ELONGATED whose residual is unremarkable, Σ r² below
    :data:`_PRESCREEN` × :data:`ptv.detect._split.SCREEN_CHI2` / dof times its
    expectation c·σ_n²·dof + γ·L (:func:`_noise_model`). For a lone spot its group is its
    window, so this is the split stage's own screen, but unweighted, with a margin."""
    sizes = np.diff(groups.offsets)
    first = groups.members[groups.offsets[:-1]]
    square, light, dof = stats[:, 0], stats[:, 1], stats[:, 2]
    expected = var_n[first] * dof + gamma * light
    quiet = square * dof <= _PRESCREEN * _split_kernels.SCREEN_CHI2 * expected
    return ~((sizes == 1) & (dof > 0) & quiet & ~candidate[first])


def _with_split(
    columns: tuple, spots: np.ndarray, added: np.ndarray, parent: np.ndarray
) -> tuple[tuple, np.ndarray, np.ndarray, np.ndarray]:
    """The detections with the particles split off inserted after the detection each
    was split from.

    Parameters
    ----------
    columns : tuple
        x, y, intensity, peak, size, flags of the N detections.
    spots : ndarray, shape (N, 4)
        Their fitted spots (A, x₀, y₀, s).
    added : ndarray, shape (M, 4)
        The spots split off.
    parent : ndarray of int, shape (M,)
        The detection each was split from.

    Returns
    -------
    columns : tuple
        The N + M rows, with the centres of the spots; the intensity, peak and size of a
        detection shared with the spots split from it in proportion to the fitted
        amplitudes, and all of them flagged OVERLAP (no longer ELONGATED or FALLBACK).
    spots : ndarray, shape (N + M, 4)
        The spot of each row.
    origin : ndarray of int, shape (N + M,)
        The detection each row comes from (its own, or the one it was split from).
    split_off : ndarray of bool, shape (N + M,)
        The rows of the spots ``added``.
    """
    _, _, inten, peak, size, flags = columns
    n = len(spots)
    total = spots[:, 0].copy()
    np.add.at(total, parent, added[:, 0])
    order = np.argsort(parent, kind="stable")
    rank = np.empty(len(parent), np.int64)
    rank[order] = np.arange(len(parent)) - np.searchsorted(parent[order], parent[order])
    key = np.concatenate((np.arange(n) * (_split_kernels.MAX_ADDED + 1), 0 * parent))
    key[n:] = parent * (_split_kernels.MAX_ADDED + 1) + 1 + rank
    src = np.concatenate((np.arange(n), parent))
    every = np.concatenate((spots, added))
    share = np.ones(len(src))
    family = np.zeros(n, bool)
    family[parent] = True
    in_family = family[src]
    share[in_family] = every[in_family, 0] / total[src[in_family]]
    new_flags = flags[src].copy()
    new_flags[in_family] = (new_flags[in_family] & ~np.uint8(_EXPLAINED)) | DetectionFlag.OVERLAP
    out = (
        every[:, 1],
        every[:, 2],
        inten[src] * share,
        peak[src] * share,
        np.maximum(np.rint(size[src] * share), 1).astype(np.int64),
        new_flags,
    )
    sort = np.argsort(key, kind="stable")
    return tuple(col[sort] for col in out), every[sort], src[sort], sort >= n


def _split_round(
    img: np.ndarray,
    columns: tuple,
    spots: np.ndarray,
    groups: Groups,
    backgrounds: np.ndarray,
    level: np.ndarray,
    var_n: np.ndarray,
    gamma: float,
) -> tuple[tuple, np.ndarray, np.ndarray, np.ndarray]:
    """One round of the split stage (:mod:`ptv.detect._split`) over ``groups``, their
    fitted backgrounds ``backgrounds`` (NaN: refit them first), the N detections'
    ``columns`` and ``spots`` (N, 4; updated in place), background ``level`` and c·σ_n²
    ``var_n`` (N,), DN and DN². Returns :func:`_with_split`'s columns, spots, origin and
    split_off, after :func:`_undouble`."""
    candidate = (columns[5] & DetectionFlag.ELONGATED) != 0
    fitted = spots.copy()
    added, parent = _split_kernels.split_groups(
        img, spots, backgrounds, level, var_n, gamma, candidate, *groups
    )
    used = np.flatnonzero(parent >= 0)
    added = added[used]
    added[:, 1:3] = _undouble(spots, fitted, added[:, 1:3])
    kept = np.isfinite(added[:, 1])
    return _with_split(columns, spots, added[kept], parent[used][kept])


def _holding(groups: Groups, rows: np.ndarray) -> np.ndarray:
    """(n_groups,) bool: the groups with a member among ``rows`` (bool, per detection)."""
    sizes = np.diff(groups.offsets)
    group_of = np.repeat(np.arange(sizes.size), sizes)
    return np.bincount(group_of, weights=rows[groups.members], minlength=sizes.size) > 0


def _refine(
    img: np.ndarray, columns: tuple, crowded: np.ndarray, background: BackgroundEstimate
) -> tuple:
    """Refine the centres of groups of nearby detections and split the blends that the
    model test resolves (module docstring, steps 5 and 6): the columns x, y, intensity,
    peak, size, flags, with a row for each particle split off.

    The split stage runs in rounds, at most :data:`_SPLIT_ROUNDS`: after each, the
    detections are grouped again, and the groups holding a particle split off in it are
    refitted with it (weighted, as the trials are) and tried again, since a spot split
    off is a neighbour the first fits of its group and of the groups around did not
    model."""
    x, y, _, _, _, flags = columns
    xy = np.column_stack((x, y))
    level, noise = background.at(xy)
    unmodelled = ((flags & _UNMODELLED) != 0) | crowded
    spots, groups, stats = _fit_spots(img, xy, unmodelled, level)
    scale, gamma = _noise_model(stats, groups, noise**2)
    candidate = (flags & DetectionFlag.ELONGATED) != 0
    tried = _worth_trying(stats, groups, scale * noise**2, gamma, candidate)
    backgrounds = stats[tried, 3]
    logger.debug(
        "pixel variance %.3g σ_n² + %.3g DN × light; %d of %d groups tried",
        scale,
        gamma,
        int(tried.sum()),
        tried.size,
    )
    for split_round in range(_SPLIT_ROUNDS):
        columns, spots, origin, split_off = _split_round(
            img, columns, spots, groups.subset(tried), backgrounds, level, scale * noise**2, gamma
        )
        logger.debug("split round %d: %d particles split off", split_round + 1, split_off.sum())
        if not split_off.any() or split_round == _SPLIT_ROUNDS - 1:
            break
        unmodelled = unmodelled[origin]
        xy = np.column_stack(columns[:2])
        level, noise = background.at(xy)
        groups = fit_groups(xy, unmodelled)
        tried = _holding(groups, split_off)
        backgrounds = np.full(int(tried.sum()), np.nan)
    return columns


def _undouble(spots: np.ndarray, fitted: np.ndarray, new: np.ndarray) -> np.ndarray:
    """Undo what the split stage put on a particle that already had a detection.

    Groups are tried side by side, each with its neighbours' light as it was before the
    trials, so two neighbouring groups can both add a spot for one particle hidden
    between them, and a group can add a spot, or move one of its own (a refit may move
    a centre by up to 3 px), where a neighbour's spot misfits. Closer than
    :data:`ptv.detect._split.MIN_SEPARATION`, two spots are one particle:

    - a detection the split stage moved that close to another one is put back where the
      refinement left it (``fitted``: the spots before the split stage; ``spots``, after
      it, updated in place);
    - a spot split off (``new``, (M, 2), px) that close to a detection is dropped;
    - two spots split off that close to each other (one particle found from two sides)
      become one, at their mean.

    Returns the centres of the spots split off, (M, 2), px; NaN for those dropped.
    """
    limit = _split_kernels.MIN_SEPARATION
    moved = np.flatnonzero((spots != fitted).any(axis=1))
    if moved.size:
        gap = _tree(spots[:, 1:3]).query(spots[moved, 1:3], k=2)[0][:, 1]
        back = moved[gap < limit]
        spots[back] = fitted[back]
    new = new.copy()
    if len(new) == 0:
        return new
    new[_tree(spots[:, 1:3]).query(new)[0] < limit] = np.nan
    alive = np.flatnonzero(np.isfinite(new[:, 0]))
    for a, b in alive[cKDTree(new[alive]).query_pairs(limit, output_type="ndarray")]:
        if np.isfinite(new[a, 0]) and np.isfinite(new[b, 0]):
            new[a] = 0.5 * (new[a] + new[b])
            new[b] = np.nan
    return new


def _tree(xy: np.ndarray) -> cKDTree:
    """A KD-tree of points (N, 2) queried a few times: built unbalanced, in half the time
    of a balanced one."""
    return cKDTree(xy, balanced_tree=False, compact_nodes=False)


def _image_background(
    background: BackgroundEstimate | None, img: np.ndarray, tiles: tuple[int, int]
) -> BackgroundEstimate:
    """``background`` checked against the image, or one estimated from it."""
    if background is None:
        return estimate_background(img, tiles=tiles)
    if not isinstance(background, BackgroundEstimate):
        raise ValueError(f"background must be a BackgroundEstimate, got {type(background)}")
    if background.shape != img.shape:
        raise ValueError(
            f"background was estimated on an image of shape {background.shape}, "
            f"but the image has shape {img.shape}"
        )
    return background


def _no_detections(shape: tuple[int, int]) -> Detections:
    """The detections of an image without a particle."""
    empty = np.empty(0)
    return Detections(
        xy=np.empty((0, 2)),
        intensity=empty,
        peak=empty,
        size=np.empty(0, np.int64),
        flags=np.empty(0, np.uint8),
        shape=shape,
    )


def _measure_regions(
    img: np.ndarray, background: BackgroundEstimate, threshold_sigmas: float, options: tuple
) -> tuple[np.ndarray, ...]:
    """Local maxima above B + k·σ_n, their connected regions, and every particle measured
    in them (split at dips, flagged): the columns x, y, intensity, peak, size, flags and
    crowded (bool: the region had too many maxima to split). ``options``: estimator
    code, radius, min_dip, dip_sigmas, max_elongation, saturation.
    """
    thr_grid = background.threshold(threshold_sigmas)
    max_r, max_c = _kernels.local_maxima(img, thr_grid, float(thr_grid.min()))
    if max_r.size == 0:
        empty = _no_detections(img.shape)
        columns = (*empty.xy.T, empty.intensity, empty.peak, empty.size, empty.flags)
        return (*columns, np.empty(0, np.bool_))
    max_thr = background.at(np.column_stack((max_c, max_r)).astype(np.float64))
    max_thr = max_thr[0] + threshold_sigmas * max_thr[1]
    labels = np.zeros(img.shape, dtype=np.int32)
    comp, pix_r, pix_c, starts = _kernels.regions(img, max_r, max_c, max_thr, labels)
    order = np.lexsort((-img[max_r, max_c].astype(np.float64), comp))
    estimator, radius, min_dip, dip_sigmas, max_elongation, saturation = options
    logger.debug("%d maxima in %d regions", max_r.size, starts.size - 1)
    return _kernels.measure(
        img,
        order,
        comp,
        max_r,
        max_c,
        pix_r,
        pix_c,
        starts,
        background.level,
        background.noise,
        thr_grid,
        estimator,
        radius,
        min_dip,
        dip_sigmas,
        max_elongation,
        5,  # the fewest pixels of a particle whose elongation is judged
        saturation,
    )


def detect_particles(
    image: object,
    *,
    threshold_sigmas: float = 6.0,
    estimator: Estimator = "gauss",
    radius: int = 3,
    min_dip: float = 0.1,
    dip_sigmas: float = 3.0,
    max_elongation: float = 1.8,
    min_size: int = 1,
    saturation: float | None = None,
    tiles: tuple[int, int] = (1, 1),
    background: BackgroundEstimate | None = None,
    diameter: float | None = None,
) -> Detections:
    """Detect particles on a camera image and locate their centres to sub-pixel accuracy.

    Parameters
    ----------
    image : array_like, shape (H, W)
        Camera image, integers (DN) or floats; see :func:`ptv.detect.check_image`.
    threshold_sigmas : float
        k: the threshold in noise units above the background, T = B + k·σ_n, > 0. The default
        6 gives a false-alarm rate of ~1e-9 per pixel for Gaussian noise (~0.002 false
        maxima per 2048 × 1088 frame).
    estimator : {"gauss", "gauss3", "centroid"}
        Sub-pixel estimator (module docstring): least-squares Gaussian on 3 × 3 to
        5 × 5 pixels, refined by joint fits of pixel-integrated spots, blends split by
        a model test; 3-point Gaussian along x and y; or threshold-subtracted centroid.
    radius : int
        Half-width of the window of the centroid and of the second moments, px, >= 1
        (3 → 7 × 7).
    min_dip : float
        Dip between two maxima of one region, as a fraction of the fainter one's peak
        above background, needed to split them, >= 0.
    dip_sigmas : float
        The same dip in noise units, >= 0 (both conditions must hold).
    max_elongation : float
        Eigenvalue ratio of the second moments above which an unsplit particle of at
        least 5 pixels is flagged ELONGATED, >= 1.
    min_size : int
        Particles with fewer pixels above threshold are dropped, >= 1.
    saturation : float or None
        Level at which a pixel counts as saturated (e.g. 4095 for a 12-bit camera
        stored in uint16). None: the dtype's maximum for integer images, none for
        floats.
    tiles : (gy, gx)
        Tiles of the background estimate (ignored when ``background`` is given).
    background : BackgroundEstimate or None
        A background estimate to use instead of estimating one from ``image`` (e.g. from
        a set of frames); its shape must match the image.
    diameter : float or None
        Expected particle image diameter, px (e⁻² diameter, σ = diameter/4), > 0, at
        most the image's smaller side. None (default) or below 6 px: the detector's own
        scale, spots of about 3 px. From 6 px it runs on sums of b × b pixels,
        b = ⌊diameter/3⌋ (:mod:`ptv.detect._blocks`), where ``radius`` counts blocks and
        ``min_size`` pixels: a large particle is one detection, two are split down to
        about 0.4 diameters apart, and a much smaller one is located to about a block.

    Returns
    -------
    Detections
        One row per particle, grouped by connected region (regions in raster order of
        their first maximum; within a split region, by decreasing peak); a particle
        split off a blend by the model test ("gauss" only) follows the detection it was
        split from.

    Raises
    ------
    ValueError
        Bad image (not 2-D, empty, non-real dtype, NaN or inf) or bad option value.

    Examples
    --------
    A Gaussian spot (σ = 1 px, 1000 DN) centred at (15.3, 16.7) px on a background of
    100 DN with 2 DN of noise is found at its centre. The first call in a fresh
    environment compiles the detector (tens of seconds; then cached on disk).

    >>> import numpy as np
    >>> import ptv
    >>> rows, cols = np.mgrid[:32, :32]
    >>> spot = 1000 * np.exp(-((cols - 15.3) ** 2 + (rows - 16.7) ** 2) / 2)
    >>> image = 100 + spot + np.random.default_rng(0).normal(0, 2, (32, 32))
    >>> found = ptv.detect_particles(image)
    >>> len(found), bool(np.all(np.abs(found.xy - [15.3, 16.7]) < 0.05))
    (1, True)
    >>> found.flags  # a clean detection
    array([0], dtype=uint8)
    """
    t0 = time.perf_counter()
    img = check_image(image)
    threshold_sigmas = check_number("threshold_sigmas", threshold_sigmas, low=0.0, strict=True)
    if estimator not in _ESTIMATORS:
        raise ValueError(f"estimator must be one of {sorted(_ESTIMATORS)}, got {estimator!r}")
    radius = check_integer("radius", radius, low=1)
    min_dip = check_number("min_dip", min_dip, low=0.0)
    dip_sigmas = check_number("dip_sigmas", dip_sigmas, low=0.0)
    max_elongation = check_number("max_elongation", max_elongation, low=1.0)
    min_size = check_integer("min_size", min_size, low=1)
    sat = saturation_level(saturation, np.asarray(image).dtype)
    block = 1
    if diameter is not None:
        diameter = check_number("diameter", diameter, low=0.0, strict=True)
        block = _blocks.block_size(diameter, img.shape)
    if block > 1:
        given = _image_background(background, img, tiles)
        sums, summed_saturation = _blocks.block_sums(img, block, sat, given)
        summed = _blocks.block_background(None if background is None else given, sums, block, tiles)
        found = detect_particles(
            sums,
            threshold_sigmas=threshold_sigmas,
            estimator=estimator,
            radius=radius,
            min_dip=min_dip,
            dip_sigmas=dip_sigmas,
            max_elongation=max_elongation,
            min_size=-(-min_size // block**2),
            saturation=summed_saturation,
            background=summed,
        )
        return _blocks.from_blocks(found, img, block, summed.at(found.xy)[0])
    background = _image_background(background, img, tiles)
    options = (_ESTIMATORS[estimator], radius, min_dip, dip_sigmas, max_elongation, sat)
    *columns, crowded = _measure_regions(img, background, threshold_sigmas, options)
    keep = columns[4] >= min_size
    if not keep.all():
        columns, crowded = [a[keep] for a in columns], crowded[keep]
    if estimator == "gauss" and crowded.size:
        columns = _refine(img, tuple(columns), crowded, background)
    x, y, inten, peak, size, flags = columns
    det = Detections(
        xy=np.column_stack((x, y)),
        intensity=inten,
        peak=peak,
        size=size,
        flags=flags,
        shape=img.shape,
    )
    logger.debug(
        "%d particles on a %dx%d image in %.1f ms",
        len(det),
        img.shape[1],
        img.shape[0],
        (time.perf_counter() - t0) * 1e3,
    )
    return det
