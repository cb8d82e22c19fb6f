"""Particle detection: threshold, local maxima, region splitting, sub-pixel centres.

Pipeline (the compiled passes are in :mod:`ptv.detect._kernels`):

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
     The centres are then refined by least squares in linear intensity: each group of
     detections closer than :data:`GROUP_DISTANCE_PX` to one another (a lone one is a
     group of one) is fitted jointly, over the union of their 5 × 5 windows, with the
     sum of pixel-integrated Gaussians A·E(i − x₀)·E(j − y₀) (erf differences;
     amplitude, centre and width free per spot) and one background B, by Gauss–Newton
     from the log fits' centres and a 0.8 px width (:mod:`ptv.detect._refine`). No
     threshold or logarithm shapes that estimate, which removes the log fit's pull
     towards pixel centres at low signal (0.008 px at 300–700 e⁻ per spot over 8 e⁻ of
     read noise, under 0.003 px refined), and a neighbour's light is fitted instead of
     cut off, so the error of a resolved pair no longer depends on where the neighbour
     is (on rendered frames: 0.043 px rms, uncorrelated between the frames of a pair).
     Groups holding a saturated, edge or elongated detection, or more than
     :data:`MAX_GROUP`, keep the log fits. Unresolved blends (a neighbour 1–3 px away
     that is not detected) stay the largest error: 0.2–0.4 px, correlated between the
     frames of a pair; about half of them are flagged ELONGATED.
   - ``"gauss3"``: the 3-point Gaussian estimator along x and along y through the
     maximum pixel, on background-subtracted values (docs/imaging.md §5),
     x̂ = i + [ln I₋ − ln I₊] / [2(ln I₋ − 2 ln I₀ + ln I₊)]. Where a logarithm is
     undefined (a value <= B), the profile is not concave or the maximum is on the
     border, the centroid is used on that axis (flag FALLBACK).
   - ``"centroid"``: threshold-subtracted centre of mass, x̂ = Σ(I − T)₊x / Σ(I − T)₊,
     over the particle's pixels within ``radius`` of its maximum pixel (a
     (2·radius + 1)² window).

   Saturated particles always get the centroid (a flat top has no curvature).

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
- Pairs of spots are split in 90 / 60 / 20 % of cases at 2.5 px apart and 100 / 99 /
  80 % at 3 px, for σ = 0.6 / 0.75 / 0.9 px; unsplit pairs come out as one detection
  flagged ELONGATED (2 px apart: ≥ 98 % of pairs split or flagged). Error of split
  pairs 3 px apart at σ = 0.75 / 0.9 px (2-D rms): 0.03 / 0.07 px with the deblended
  least-squares Gaussian, 0.08 / 0.11 px with the centroid; 2.5 px apart ~0.13 px.
"""

import logging
import time
from typing import Literal

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from ptv.detect import _kernels
from ptv.detect import _refine as _refine_kernels
from ptv.detect._image import check_image, default_saturation
from ptv.detect.background import BackgroundEstimate, estimate_background
from ptv.detect.detections import DetectionFlag, Detections

logger = logging.getLogger(__name__)

Estimator = Literal["gauss", "gauss3", "centroid"]
_ESTIMATORS = {"gauss": _kernels.GAUSS, "gauss3": _kernels.GAUSS3, "centroid": _kernels.CENTROID}


#: Detections closer than this, px, are refined together (one joint fit of their
#: spots): a spot further away puts at most 4·10⁻³ of its peak on a 5 × 5 window
#: (σ = 0.9 px), mostly absorbed by the fitted background (measured noise-free: a
#: neighbour 6 px away, even 10× brighter, moves a lone fit's centre < 10⁻⁴ px).
GROUP_DISTANCE_PX = 6.0
#: Groups of more detections than this are left as the log fits gave them.
MAX_GROUP = 6
#: Starting Gaussian width of the refinement, px (d_τ ≈ 3 px spots, docs/imaging.md §1).
_REFINE_START_WIDTH = 0.8
#: Detections whose light is not one Gaussian spot: they and their groups are not refined.
_UNMODELLED = int(DetectionFlag.SATURATED | DetectionFlag.EDGE | DetectionFlag.ELONGATED)


def _refine(
    img: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    flags: np.ndarray,
    background: BackgroundEstimate,
) -> None:
    """Refine the centres (x, y updated in place) of groups of nearby detections."""
    xy = np.column_stack((x, y))
    pairs = cKDTree(xy).query_pairs(GROUP_DISTANCE_PX, output_type="ndarray")
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(x),) * 2)
    _, label = connected_components(graph, directed=False)
    size = np.bincount(label)
    unmodelled = np.bincount(label, weights=(flags & _UNMODELLED) != 0) > 0
    fit = (size[label] <= MAX_GROUP) & ~unmodelled[label]
    members = np.flatnonzero(fit)
    members = members[np.argsort(label[members], kind="stable")]
    starts = np.flatnonzero(np.diff(label[members], prepend=-1))
    offsets = np.append(starts, members.size).astype(np.int64)
    level = background.at(xy)[0]
    refined = _refine_kernels.refine_groups(
        img, x, y, _REFINE_START_WIDTH, level, members.astype(np.int64), offsets
    )
    logger.debug("%d of %d detections refined", int(refined.sum()), x.size)


def _number(name: str, value: object, *, low: float, strict: bool = False) -> float:
    ok = isinstance(value, int | float | np.integer | np.floating) and not isinstance(value, bool)
    if ok and np.isfinite(value) and (value > low or (not strict and value == low)):
        return float(value)
    bound = f"> {low:g}" if strict else f">= {low:g}"
    raise ValueError(f"{name} must be a finite number {bound}, got {value!r}")


def _integer(name: str, value: object, *, low: int) -> int:
    if isinstance(value, int | np.integer) and not isinstance(value, bool) and value >= low:
        return int(value)
    raise ValueError(f"{name} must be an integer >= {low}, got {value!r}")


def _saturation_level(saturation: float | None, dtype: np.dtype) -> float:
    """The level of a saturated pixel: ``saturation``, or the dtype's default."""
    if saturation is None:
        return default_saturation(dtype)
    if (
        isinstance(saturation, int | float | np.integer | np.floating)
        and not isinstance(saturation, bool)
        and not np.isnan(saturation)
    ):
        return float(saturation)
    raise ValueError(f"saturation must be a number or None, got {saturation!r}")


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
    in them (split at dips, flagged): the columns x, y, intensity, peak, size, flags.
    ``options``: estimator code, radius, min_dip, dip_sigmas, max_elongation, saturation.
    """
    thr_grid = background.threshold(threshold_sigmas)
    max_r, max_c = _kernels.local_maxima(img, thr_grid, float(thr_grid.min()))
    if max_r.size == 0:
        empty = _no_detections(img.shape)
        return (*empty.xy.T, empty.intensity, empty.peak, empty.size, empty.flags)
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
        5 × 5 pixels, 3-point Gaussian along x and y, or threshold-subtracted centroid.
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

    Returns
    -------
    Detections
        One row per particle, grouped by connected region (regions in raster order of
        their first maximum; within a split region, by decreasing peak).

    Raises
    ------
    ValueError
        Bad image (not 2-D, empty, non-real dtype, NaN or inf) or bad option value.
    """
    t0 = time.perf_counter()
    img = check_image(image)
    threshold_sigmas = _number("threshold_sigmas", threshold_sigmas, low=0.0, strict=True)
    if estimator not in _ESTIMATORS:
        raise ValueError(f"estimator must be one of {sorted(_ESTIMATORS)}, got {estimator!r}")
    radius = _integer("radius", radius, low=1)
    min_dip = _number("min_dip", min_dip, low=0.0)
    dip_sigmas = _number("dip_sigmas", dip_sigmas, low=0.0)
    max_elongation = _number("max_elongation", max_elongation, low=1.0)
    min_size = _integer("min_size", min_size, low=1)
    sat = _saturation_level(saturation, np.asarray(image).dtype)
    background = _image_background(background, img, tiles)
    options = (_ESTIMATORS[estimator], radius, min_dip, dip_sigmas, max_elongation, sat)
    x, y, inten, peak, size, flags = _measure_regions(img, background, threshold_sigmas, options)
    keep = size >= min_size
    if not keep.all():
        x, y, inten, peak, size, flags = (a[keep] for a in (x, y, inten, peak, size, flags))
    if estimator == "gauss" and x.size:
        _refine(img, x, y, flags, background)
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
