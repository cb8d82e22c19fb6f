"""Steps 1 to 3 of finding a plate's dots (:mod:`ptv.calibration.targets`): the
threshold, the blobs and their centroids, without knowing the grid; alone, the dot-like
blobs of a target of scattered points (:func:`find_blobs`).

1. **Background and threshold.** Level and noise are estimated as for particle images
   (:func:`ptv.detect.estimate_background`), on tiles of about ``background_tile`` px:
   the median of each tile, bilinear between tile centres, so a slowly varying
   background is followed; the noise σ is 1.4826·MAD of horizontal pixel differences /
   √2 (a smooth background cancels; the dots' edges are too few to matter), the median
   over the tiles. The signal is the 99.9th percentile above the background. Pixels brighter
   than background + max(k·σ, f·signal) (k = ``threshold_sigmas``, f = ``threshold_fraction``)
   form the dot mask: a low fraction of the signal keeps dimly back-lit dots (uneven
   lighting) whole. Dark dots on a bright plate are handled by inverting the image.
   With ``threshold="local"`` both terms are local instead: the background is a
   morphological opening (a minimum then a maximum filter over ``background_tile`` px)
   of the lightly smoothed image, which follows any structure wider than a dot, a
   saturated window included, and the signal is the largest value above it within
   ``background_tile`` px, saturated pixels left out. A saturated region then raises
   neither the background nor the threshold of the dots beside it.
2. **Blobs.** 8-connected components (OpenCV). Specks smaller than ``min_area`` px are
   dropped. A blob is rejected when its measurement window (the blob grown by
   ``margin`` px) leaves the image (a dot cut by the edge), when two windows touch
   (crowded), or when its area is implausible next to the median area of its 12
   nearest blobs: below 0.4× (fragments) or above 1.6 × (D_mark/D_dot)² (merged blobs,
   reflections).
3. **Centroids.** Intensity-weighted centre of mass over the window, with the local
   background (the mean of a ring of ``ring`` px around the window, outside every
   blob) subtracted and the signed values kept (clipping the noise at zero would bias
   the centroid). The window holds all of the dot's light, blurred edges included.

Errors: :class:`NoTargetError` when too few dot-like blobs are seen.
"""

import logging
from dataclasses import dataclass

import cv2
import numpy as np
from scipy.spatial import cKDTree

from ptv.detect.background import bilinear, estimate_background

log = logging.getLogger("ptv.calibration.targets")

#: Fewest dot-like blobs an image of a target must show (three marks and neighbours).
MIN_BLOBS = 12
#: Neighbours whose median area is a blob's reference area.
_AREA_NEIGHBOURS = 12
#: Plausible blob area relative to its neighbours' median: below → fragment.
_MIN_AREA_RATIO = 0.4
#: Above this times the expected mark/dot area ratio → not a dot.
_MAX_MARK_RATIO = 1.6
#: Box filter before the local background's opening, px: its minimum filter would
#: otherwise follow the noise down (by ~4 σ over a 64 px square; by ~σ after the box).
_LOCAL_SMOOTHING = 5
#: How the dot mask's threshold is set (:func:`find_dots`).
THRESHOLDS = ("global", "local")


class NoTargetError(ValueError):
    """The image shows no calibration target (too few dot-like blobs)."""


def _check_image(image: object, source: str) -> np.ndarray:
    arr = np.asarray(image)
    if arr.ndim != 2:
        raise ValueError(
            f"{source}: a plate image must be 2-D (rows, columns) grey levels, got "
            f"ndim={arr.ndim} with shape {arr.shape}"
        )
    if arr.size == 0 or min(arr.shape) < 8:
        raise ValueError(f"{source}: image of shape {arr.shape} is too small")
    dt = arr.dtype
    if dt == np.bool_ or not (np.issubdtype(dt, np.integer) or np.issubdtype(dt, np.floating)):
        raise ValueError(
            f"{source}: a plate image must hold real numbers (integers or floats), got dtype {dt}"
        )
    out = arr.astype(np.float64)
    if not np.isfinite(out).all():
        bad = ~np.isfinite(out)
        r, c = np.unravel_index(int(np.flatnonzero(bad)[0]), arr.shape)
        raise ValueError(
            f"{source}: image has {int(bad.sum())} NaN or infinite pixel(s), first at "
            f"(row {r}, column {c})"
        )
    return out


def _background_and_noise(image: np.ndarray, tile: int) -> tuple[np.ndarray, float]:
    """The background level at every pixel and the noise σ of a plate image, by particle
    detection's estimator (:func:`ptv.detect.estimate_background`) on tiles of about
    ``tile`` px: the level bilinear between tile centres, σ the median over the tiles."""
    h, w = image.shape
    estimate = estimate_background(image, tiles=(max(1, h // tile), max(1, w // tile)))
    rows, cols = np.divmod(np.arange(h * w), w)
    level = bilinear(estimate.level, np.column_stack([cols, rows]), (h, w)).reshape(h, w)
    return level, float(np.median(estimate.noise))


@dataclass(frozen=True)
class Blobs:
    centroid: np.ndarray  # (B, 2)
    area: np.ndarray  # (B,)
    reason: np.ndarray  # (B,) object: "" for usable blobs
    saturated: np.ndarray  # (B,) bool


def _disc(radius: int) -> np.ndarray:
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))


def _measure_blobs(
    signal: np.ndarray,
    mask: np.ndarray,
    background: np.ndarray,
    *,
    min_area: int,
    margin: int,
    ring: int,
    saturated_px: np.ndarray,
) -> Blobs:
    h, w = signal.shape
    n, labels, stats, _ = cv2.connectedComponentsWithStats(
        mask.astype(np.uint8), connectivity=8, ltype=cv2.CV_32S
    )
    area = stats[:, cv2.CC_STAT_AREA].astype(np.int64)
    keep = np.flatnonzero(area >= min_area)
    keep = keep[keep > 0]
    if len(keep) == 0:
        return Blobs(
            np.zeros((0, 2)), np.zeros(0, np.int64), np.zeros(0, object), np.zeros(0, bool)
        )
    # Relabel the kept blobs 1..B (specks → background).
    relabel = np.zeros(n, dtype=np.int32)
    relabel[keep] = np.arange(1, len(keep) + 1, dtype=np.int32)
    lab = relabel[labels]
    b = len(keep)
    big = np.float32(b + 1)
    lab_f = lab.astype(np.float32)
    window = cv2.dilate(lab_f, _disc(margin))
    lowest = cv2.erode(np.where(lab > 0, lab_f, big), _disc(margin))
    outer = cv2.dilate(lab_f, _disc(margin + ring))
    win = window.astype(np.int64)
    # Crowded: two blobs' windows meet.
    clash = (win > 0) & (lowest < big) & (lowest.astype(np.int64) != win)
    crowded = np.zeros(b + 1, dtype=bool)
    crowded[win[clash]] = True
    crowded[lowest[clash].astype(np.int64)] = True
    # Ring background per blob, from pixels outside every window and blob.
    ring_px = (outer > 0) & (win == 0) & (lab == 0)
    rl = outer.astype(np.int64)[ring_px]
    ring_n = np.bincount(rl, minlength=b + 1)
    ring_sum = np.bincount(rl, weights=signal[ring_px], minlength=b + 1)
    # Window sums.
    sel = win > 0
    wl = win[sel]
    rows, cols = np.nonzero(sel)
    val = signal[sel]
    n_w = np.bincount(wl, minlength=b + 1).astype(float)
    s0 = np.bincount(wl, weights=val, minlength=b + 1)
    sx = np.bincount(wl, weights=val * cols, minlength=b + 1)
    sy = np.bincount(wl, weights=val * rows, minlength=b + 1)
    cx = np.bincount(wl, weights=cols.astype(float), minlength=b + 1)
    cy = np.bincount(wl, weights=rows.astype(float), minlength=b + 1)
    # Local background: the ring mean, or the tile map at the blob where no ring is left.
    fallback = background[
        np.clip(stats[keep, cv2.CC_STAT_TOP] + stats[keep, cv2.CC_STAT_HEIGHT] // 2, 0, h - 1),
        np.clip(stats[keep, cv2.CC_STAT_LEFT] + stats[keep, cv2.CC_STAT_WIDTH] // 2, 0, w - 1),
    ]
    bg = np.where(ring_n[1:] > 0, ring_sum[1:] / np.maximum(ring_n[1:], 1), fallback)
    total = s0[1:] - bg * n_w[1:]
    with np.errstate(invalid="ignore", divide="ignore"):
        centroid = np.column_stack([(sx[1:] - bg * cx[1:]) / total, (sy[1:] - bg * cy[1:]) / total])
    # Cut by the edge: the window (blob grown by the margin) must lie inside the image.
    left = stats[keep, cv2.CC_STAT_LEFT]
    top = stats[keep, cv2.CC_STAT_TOP]
    right = left + stats[keep, cv2.CC_STAT_WIDTH] - 1
    bottom = top + stats[keep, cv2.CC_STAT_HEIGHT] - 1
    edge = (
        (left - margin < 0)
        | (top - margin < 0)
        | (right + margin > w - 1)
        | (bottom + margin > h - 1)
    )
    reason = np.full(b, "", dtype=object)
    reason[crowded[1:]] = "crowded"
    reason[edge] = "edge"
    reason[~(total > 0) | ~np.isfinite(centroid).all(axis=1)] = "area"
    sat = np.zeros(b + 1, dtype=bool)
    sat[lab[saturated_px]] = True
    sat[0] = False
    return Blobs(centroid=centroid, area=area[keep], reason=reason, saturated=sat[1:])


def _relative_area(centroid: np.ndarray, area: np.ndarray) -> np.ndarray:
    """Area of each blob over the median area of its nearest neighbours."""
    k = min(_AREA_NEIGHBOURS, len(area) - 1)
    if k < 1:
        return np.ones(len(area))
    _, nb = cKDTree(centroid).query(centroid, k=k + 1)
    return area / np.median(area[nb[:, 1:]], axis=1)


def _check_find_options(
    threshold, threshold_fraction, threshold_sigmas, min_area, margin, ring, background_tile
) -> None:
    """Refuse options of :func:`find_dots` and :func:`find_blobs` they cannot work with."""
    if threshold not in THRESHOLDS:
        raise ValueError(f"threshold must be one of {', '.join(THRESHOLDS)}, got {threshold!r}")
    if not 0 < threshold_fraction < 1:
        raise ValueError(f"threshold_fraction must be in (0, 1), got {threshold_fraction!r}")
    if not threshold_sigmas > 0:
        raise ValueError(f"threshold_sigmas must be > 0, got {threshold_sigmas!r}")
    for name, value, least in (
        ("min_area", min_area, 1),
        ("margin", margin, 1),
        ("ring", ring, 1),
        ("background_tile", background_tile, 8),
    ):
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < least:
            raise ValueError(f"{name} must be an integer >= {least}, got {value!r}")


def _local_level(
    signal: np.ndarray,
    saturated_px: np.ndarray,
    noise: float,
    threshold_sigmas: float,
    threshold_fraction: float,
    window: int,
    source: str,
) -> tuple[np.ndarray, np.ndarray]:
    """The local background of every pixel and the dot mask's level above it.

    Parameters
    ----------
    signal : ndarray, shape (H, W)
        The image with the dots bright.
    saturated_px : ndarray of bool, shape (H, W)
        Pixels at the saturation level: left out of the local signal.
    noise : float
        Pixel noise σ, image units.
    threshold_sigmas, threshold_fraction : float
        k and f: the level is max(k σ, f × the local signal).
    window : int
        Side of the square of the opening and of the local maximum, px (wider than a dot).
    source : str
        The image's name for messages.

    Returns
    -------
    background : ndarray, shape (H, W)
        Opening of the image smoothed over :data:`_LOCAL_SMOOTHING` px, image units.
    level : ndarray, shape (H, W)
        max(k σ, f × the largest unsaturated value above the background within
        ``window`` px), image units.

    Raises
    ------
    NoTargetError
        Nothing stands out of the noise anywhere.
    """
    square = cv2.getStructuringElement(cv2.MORPH_RECT, (window, window))
    smooth = cv2.blur(signal.astype(np.float32), (_LOCAL_SMOOTHING, _LOCAL_SMOOTHING))
    background = cv2.morphologyEx(smooth, cv2.MORPH_OPEN, square).astype(np.float64)
    above = np.where(saturated_px, 0.0, signal - background).astype(np.float32)
    peak = cv2.dilate(above, square).astype(np.float64)
    if not peak.max() > threshold_sigmas * noise:
        raise NoTargetError(
            f"no target in {source}: nothing stands out of the noise (largest local signal "
            f"{peak.max():.3g} above the background, noise σ {noise:.3g})"
        )
    return background, np.maximum(threshold_sigmas * noise, threshold_fraction * peak)


def _mask_level(
    above: np.ndarray, noise: float, threshold_sigmas: float, threshold_fraction: float, source: str
) -> float:
    """The dot mask's level above the background: max(k σ, f × the 99.9th percentile of
    the signal above background), or NoTargetError when nothing stands out of the noise."""
    peak = float(np.percentile(above, 99.9))
    if not peak > threshold_sigmas * noise:
        raise NoTargetError(
            f"no target in {source}: nothing stands out of the noise (99.9th percentile "
            f"{peak:.3g} above the background, noise σ {noise:.3g})"
        )
    return max(threshold_sigmas * noise, threshold_fraction * peak)


def _dot_signal(
    img: np.ndarray, dtype: np.dtype, dots: str, saturation: float | None
) -> tuple[np.ndarray, np.ndarray]:
    """The image with the dots bright (dark dots inverted), and its saturated pixels
    (bright dots only: dark dots sit below the plate's level)."""
    if saturation is None:
        saturation = float(np.iinfo(dtype).max) if np.issubdtype(dtype, np.integer) else np.inf
    if dots == "bright":
        return img, img >= saturation
    return img.max() - img, np.zeros(img.shape, dtype=bool)


def sizes_against_neighbours(
    blobs: Blobs, reason: np.ndarray, mark_area_ratio: float, source: str, mask: str
) -> np.ndarray:
    """Each accepted blob's area relative to its neighbours' (NaN for the others); marks
    blobs of implausible size with reason "area" (in place). NoTargetError when too few
    blobs are left (``mask`` describes the dot mask for the message)."""
    ok = reason == ""
    if ok.sum() < MIN_BLOBS:
        raise NoTargetError(
            f"no target in {source}: {int(ok.sum())} dot-like blob(s) found, a plate "
            f"image needs at least {MIN_BLOBS} ({mask})"
        )
    rel = np.full(len(reason), np.nan)
    rel[ok] = _relative_area(blobs.centroid[ok], blobs.area[ok])
    implausible = ok & ((rel < _MIN_AREA_RATIO) | (rel > _MAX_MARK_RATIO * mark_area_ratio))
    reason[implausible] = "area"
    usable = int(np.count_nonzero(reason == ""))
    if usable < MIN_BLOBS:
        raise NoTargetError(f"no target in {source}: only {usable} blob(s) of a plausible dot size")
    return rel


def threshold_blobs(
    image: np.ndarray,
    dots: str,
    *,
    source: str,
    threshold: str,
    threshold_fraction: float,
    threshold_sigmas: float,
    min_area: int,
    margin: int,
    ring: int,
    background_tile: int,
    saturation: float | None,
) -> tuple[np.ndarray, np.ndarray, float, np.ndarray | float, Blobs]:
    """Steps 1–3 of the module docstring: the image with its dots bright, its background
    map, noise σ and mask level (one number, or a map for the ``"local"`` threshold),
    and every blob of the mask measured."""
    raw = np.asarray(image)
    img = _check_image(raw, source)
    _check_find_options(
        threshold, threshold_fraction, threshold_sigmas, min_area, margin, ring, background_tile
    )
    signal, saturated_px = _dot_signal(img, raw.dtype, dots, saturation)
    background, noise = _background_and_noise(signal, background_tile)
    if threshold == "local":
        background, level = _local_level(
            signal,
            saturated_px,
            noise,
            threshold_sigmas,
            threshold_fraction,
            background_tile,
            source,
        )
    else:
        level = _mask_level(
            signal - background, noise, threshold_sigmas, threshold_fraction, source
        )
    blobs = _measure_blobs(
        signal,
        signal - background > level,
        background,
        min_area=min_area,
        margin=margin,
        ring=ring,
        saturated_px=saturated_px,
    )
    return signal, background, noise, level, blobs


@dataclass(frozen=True)
class TargetBlobs:
    """Dot-like blobs of an image, not indexed (what a target of scattered points needs).

    Attributes
    ----------
    pixels : ndarray, shape (N, 2)
        Intensity-weighted centres, px (x = column, y = row).
    area : ndarray of int, shape (N,)
        Pixels of each blob above the threshold.
    """

    pixels: np.ndarray
    area: np.ndarray

    def __len__(self) -> int:
        return len(self.pixels)


def find_blobs(
    image: np.ndarray,
    *,
    dots: str = "bright",
    source: str = "image",
    threshold_fraction: float = 0.1,
    threshold_sigmas: float = 4.0,
    min_area: int = 4,
    margin: int = 3,
    ring: int = 3,
    background_tile: int = 64,
    saturation: float | None = None,
) -> TargetBlobs:
    """Centres of the dot-like blobs of an image: steps 1–3 of :func:`find_dots`, without
    the size test against neighbours or any indexing.

    The defaults are looser than :func:`find_dots`' (4σ and a tenth of the signal): a
    3-D target seen obliquely shows dim dots, and the blobs are kept only where a
    calibration predicts a target point (:mod:`ptv.calibration.point_target`), so
    specks do no harm.

    Parameters
    ----------
    image : ndarray, shape (H, W)
        Grey levels (integers or floats).
    dots : {"bright", "dark"}
        Bright dots on a dark target, or dark on bright (the image is inverted).
    source : str
        Name of the image for messages.
    threshold_fraction, threshold_sigmas, min_area, margin, ring, background_tile, saturation
        As :func:`find_dots`.

    Returns
    -------
    TargetBlobs
        The blobs whose window lies inside the image, touches no other blob's window
        and holds light above the local background.

    Raises
    ------
    ValueError
        A non-2-D, empty or non-real image, NaN pixels, or bad options.
    NoTargetError
        Nothing stands out of the noise.
    """
    if dots not in ("bright", "dark"):
        raise ValueError(f"dots must be 'bright' or 'dark', got {dots!r}")
    blobs = threshold_blobs(
        image,
        dots,
        source=source,
        threshold="global",
        threshold_fraction=threshold_fraction,
        threshold_sigmas=threshold_sigmas,
        min_area=min_area,
        margin=margin,
        ring=ring,
        background_tile=background_tile,
        saturation=saturation,
    )[-1]
    usable = blobs.reason == ""
    return TargetBlobs(pixels=blobs.centroid[usable], area=blobs.area[usable])
