"""Dots of a calibration plate image: detection, centroids and grid indexing (MLBAV step 1).

A plate carries a square grid of dots (pitch p) and three larger *marks* at known grid
indices (synptv's plate: the origin (0, 0), an X mark at (2, 0) and a Y mark at (0, 3)).
For one image, :func:`find_dots` returns every dot it could identify with its pixel
centre, its integer grid index (i, j) and its nominal plate coordinates (X, Y) = p·(i, j).

Steps
-----
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
4. **Marks.** The blobs whose area exceeds √((D_mark/D_dot)²) times their neighbours'
   median (the geometric midpoint between a dot and a mark). Each triple of candidates
   and each assignment of the three mark names to it defines an affine map
   grid index → pixel; the right one predicts the neighbouring dots (a wrong one
   predicts a lattice of the wrong spacing or orientation), so the assignment that
   matches the most detections near the marks wins. Mirrored or rotated images are
   handled alike. A plate with a single mark (the one blob clearly larger than its
   neighbours) takes its axes from the grid instead: of the two lattice directions at
   the mark (its nearest neighbours), +i is the one pointing closest to the image
   direction the description's ``axes`` names for it (within 40°), +j likewise.
5. **Indexing.** From the marks the grid grows ring by ring: each unassigned
   neighbour of an indexed node is predicted by an affine map fitted to the indexed
   nodes within two grid steps (nearest indexed nodes if too few), and takes the
   nearest unused detection within 0.3 local pitches. Candidates are resolved closest
   first, so no detection is assigned twice. Local fits follow perspective,
   Scheimpflug tilt, lens distortion and refraction. A final cubic fit of all
   pixels against their indices flags gross outliers (> 0.25 pitch), which are
   dropped.
6. **Missing nodes.** Grid nodes that should be seen but were not: inside the plate's
   ``extent`` (when known; else inside the index box of the found dots) and within two
   grid steps of found dots, predicted with their whole window on the image.

Errors (``ValueError`` subclasses, naming ``source``): a non-2-D or non-real image,
NaNs; :class:`NoTargetError` when too few dot-like blobs are seen;
:class:`MarkersNotFoundError` when the marks cannot be found or placed.
"""

import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import cv2
import numpy as np
from scipy.spatial import cKDTree

from ptv.calibration._plate_grid import (  # raised by find_dots: part of its API
    MarkersNotFoundError as MarkersNotFoundError,
)
from ptv.calibration._plate_grid import SeedDotsError as SeedDotsError
from ptv.calibration._plate_grid import index_grid, missing_nodes
from ptv.calibration.observations import PlaneObservation
from ptv.detect.background import bilinear, estimate_background

log = logging.getLogger(__name__)

#: Bit flags of :attr:`PlaneDots.flags`.
FLAG_MARK = 1
FLAG_SATURATED = 2

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


# -- the plate description ---------------------------------------------------------------
@dataclass(frozen=True)
class PlateDescription:
    """The nominal plate, as an experimentalist describes it to the calibration software.

    Parameters
    ----------
    pitch : float
        Dot spacing along X and Y, m.
    dot_diameter : float
        Diameter of the ordinary dots, m.
    mark_diameter : float or None
        Diameter of the three marked dots, m (larger than ``dot_diameter``); None for a
        plate without marks.
    marks : dict of str to (int, int)
        Grid indices (i, j) of the three marks, e.g. ``{"origin": (0, 0),
        "x_axis": (2, 0), "y_axis": (0, 3)}``, not collinear; or of a single mark, with
        ``axes``; empty for a plate without marks (then every image needs seed dots,
        :func:`find_dots`). Plate coordinates are (X, Y) = pitch·(i, j).
    dots : str
        ``"bright"`` (back-lit dots on a dark plate) or ``"dark"`` (dark dots on a
        bright plate).
    extent : ((int, int), (int, int)) or None
        ((i_min, i_max), (j_min, j_max)), inclusive: the grid nodes the plate has.
        None when unknown (then only holes inside the found grid count as missing).
    axes : (str, str) or None
        With a single mark: the image directions of +i and +j, one of "right" and
        "left" and one of "up" and "down" (e.g. ``("right", "up")``: i grows to the
        right, j upwards), each within 40° of the grid's own directions on the images.
    """

    pitch: float
    dot_diameter: float
    mark_diameter: float | None = None
    marks: Mapping[str, tuple[int, int]] = field(default_factory=dict)
    dots: str = "bright"
    extent: tuple[tuple[int, int], tuple[int, int]] | None = None
    axes: tuple[str, str] | None = None

    def __post_init__(self) -> None:
        sizes = ("pitch", "dot_diameter") + (
            () if self.mark_diameter is None else ("mark_diameter",)
        )
        for name in sizes:
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float | np.floating):
                raise ValueError(f"plate {name} must be a number (m), got {value!r}")
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"plate {name} must be finite and > 0 (m), got {value!r}")
            object.__setattr__(self, name, float(value))
        if self.marks and self.mark_diameter is None:
            raise ValueError("a plate with marks needs their mark_diameter")
        if self.mark_diameter is not None and not self.dot_diameter < self.mark_diameter:
            raise ValueError(
                f"the marks must be larger than the dots: mark_diameter {self.mark_diameter} "
                f"m <= dot_diameter {self.dot_diameter} m"
            )
        if self.mark_diameter is not None and not self.mark_diameter < self.pitch:
            raise ValueError(
                f"mark_diameter {self.mark_diameter} m must be smaller than the pitch "
                f"{self.pitch} m"
            )
        if self.dots not in ("bright", "dark"):
            raise ValueError(f"dots must be 'bright' or 'dark', got {self.dots!r}")
        if not isinstance(self.marks, Mapping) or len(self.marks) not in (0, 1, 3):
            raise ValueError(
                f"the plate needs three marks {{name: (i, j)}}, one with its axes, or none, "
                f"got {self.marks!r}"
            )
        marks = {str(k): _grid_pair(v, f"mark {k!r}") for k, v in self.marks.items()}
        g = np.array(list(marks.values()), dtype=float).reshape(-1, 2)
        if len(marks) == 3 and abs(np.linalg.det(np.column_stack([g, np.ones(3)]))) < 0.5:
            raise ValueError(f"the three marks must not be collinear, got {marks}")
        object.__setattr__(self, "marks", marks)
        object.__setattr__(self, "axes", _axes(self.axes, len(marks)))
        if self.extent is not None:
            ext = np.asarray(self.extent)
            if ext.shape != (2, 2) or not np.issubdtype(ext.dtype, np.integer):
                raise ValueError(
                    f"extent must be ((i_min, i_max), (j_min, j_max)) integers, got {self.extent!r}"
                )
            if np.any(ext[:, 0] > ext[:, 1]):
                raise ValueError(f"extent must have min <= max, got {self.extent!r}")
            ext_t = ((int(ext[0, 0]), int(ext[0, 1])), (int(ext[1, 0]), int(ext[1, 1])))
            for name, (i, j) in marks.items():
                if not (ext_t[0][0] <= i <= ext_t[0][1] and ext_t[1][0] <= j <= ext_t[1][1]):
                    raise ValueError(f"mark {name!r} at {(i, j)} lies outside the extent {ext_t}")
            object.__setattr__(self, "extent", ext_t)

    @property
    def mark_area_ratio(self) -> float:
        """Nominal area of a mark over that of a dot, (D_mark/D_dot)² (1 without marks)."""
        if self.mark_diameter is None:
            return 1.0
        return (self.mark_diameter / self.dot_diameter) ** 2

    def in_extent(self, indices: np.ndarray) -> np.ndarray:
        """Whether grid indices (N, 2) lie on the plate (all True when the extent is unknown)."""
        idx = np.asarray(indices).reshape(-1, 2)
        if self.extent is None:
            return np.ones(len(idx), dtype=bool)
        (i0, i1), (j0, j1) = self.extent
        return (idx[:, 0] >= i0) & (idx[:, 0] <= i1) & (idx[:, 1] >= j0) & (idx[:, 1] <= j1)

    @classmethod
    def from_dict(cls, spec: Mapping, *, source: str = "target description") -> "PlateDescription":
        """Read the ``"target"`` entry of ``experiment.json`` (SI units).

        Required: ``pitch`` and ``dot_diameter`` (m). Optional: ``marks`` ({name: [i, j]},
        three of them, or one with ``axes``) with ``mark_diameter`` (m), absent for a
        plate without marks;
        ``extent``
        ([[i_min, i_max], [j_min, j_max]]), or ``columns`` and ``rows``, which give
        the extent of synptv's layout with the origin mark in the middle of the grid
        (i from −⌊columns/2⌋ to columns − 1 − ⌊columns/2⌋, likewise j); ``dots`` or
        ``dots_are`` (text starting with "bright" or "dark"; bright by default).
        Other fields (e.g. ``thickness``) are ignored.

        Raises
        ------
        ValueError
            Naming ``source`` and the field, for a missing or malformed field.
        """
        if not isinstance(spec, Mapping):
            raise ValueError(f"{source}: the target must be a table of fields, got {spec!r}")
        missing = [k for k in ("pitch", "dot_diameter") if k not in spec]
        if "marks" in spec and "mark_diameter" not in spec:
            missing.append("mark_diameter")
        if missing:
            raise ValueError(
                f"{source}: the target description lacks the field(s) {', '.join(missing)} "
                "(needs pitch and dot_diameter in m; marks {name: [i, j]} with their "
                "mark_diameter, if the plate has marks)"
            )
        marks = spec.get("marks", {})
        if not isinstance(marks, Mapping):
            raise ValueError(f"{source}: 'marks' must map names to [i, j], got {marks!r}")
        dots = spec.get("dots", spec.get("dots_are", "bright"))
        if not isinstance(dots, str) or not dots.strip():
            raise ValueError(f"{source}: 'dots' must be 'bright' or 'dark', got {dots!r}")
        word = dots.strip().split()[0].lower()
        extent = spec.get("extent")
        if extent is None and ("columns" in spec or "rows" in spec):
            if not ("columns" in spec and "rows" in spec):
                raise ValueError(f"{source}: give both 'columns' and 'rows' (or neither)")
            columns, rows = spec["columns"], spec["rows"]
            for name, value in (("columns", columns), ("rows", rows)):
                if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                    raise ValueError(
                        f"{source}: '{name}' must be a positive integer, got {value!r}"
                    )
            extent = (
                (-(columns // 2), columns - 1 - columns // 2),
                (-(rows // 2), rows - 1 - rows // 2),
            )
        try:
            return cls(
                pitch=spec["pitch"],
                dot_diameter=spec["dot_diameter"],
                mark_diameter=spec.get("mark_diameter"),
                marks={
                    str(k): tuple(v) if isinstance(v, list | tuple) else v for k, v in marks.items()
                },
                dots=word,
                extent=None if extent is None else tuple(tuple(e) for e in extent),
                axes=spec.get("axes"),
            )
        except (ValueError, TypeError) as err:
            raise ValueError(f"{source}: {err}") from None


def _axes(axes: object, marks: int) -> tuple[str, str] | None:
    """``axes`` checked against the number of marks: a pair of image directions, one
    horizontal and one vertical, for a single mark; None otherwise."""
    if marks != 1:
        if axes is not None:
            raise ValueError(f"axes go with a single mark, the plate has {marks}")
        return None
    if axes is None:
        raise ValueError("a single mark needs the axes: the image directions of +i and +j")
    pair = tuple(axes) if isinstance(axes, list | tuple) else ()
    horizontal = sum(word in ("right", "left") for word in pair)
    vertical = sum(word in ("up", "down") for word in pair)
    if not (len(pair) == 2 and horizontal == 1 and vertical == 1):
        raise ValueError(
            f"axes must name one of right and left and one of up and down, got {axes!r}"
        )
    return pair


def _grid_pair(value: object, what: str) -> tuple[int, int]:
    arr = np.asarray(value)
    if arr.shape != (2,) or not (
        np.issubdtype(arr.dtype, np.integer)
        or (np.issubdtype(arr.dtype, np.floating) and np.all(arr == np.round(arr)))
    ):
        raise ValueError(f"{what} must be two integers (i, j), got {value!r}")
    return int(arr[0]), int(arr[1])


# -- results -----------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class PlaneDots:
    """The identified dots of one plate image.

    Attributes
    ----------
    pixels : ndarray, shape (N, 2), float64
        Intensity-weighted dot centres, px (x = column, y = row).
    indices : ndarray, shape (N, 2), int64
        Grid index (i, j) of each dot.
    world_xy : ndarray, shape (N, 2), float64
        Nominal plate coordinates pitch·(i, j), m.
    area : ndarray, shape (N,), int64
        Pixels of each dot above the threshold, px.
    flags : ndarray, shape (N,), uint8
        Bit flags: :data:`FLAG_MARK` (a mark), :data:`FLAG_SATURATED`
        (a pixel at the saturation level: the centroid may be biased).
    marks : dict of str to int
        Row of each mark (by its name in the description).
    missing : ndarray, shape (M, 2), int64
        Grid nodes expected on the image (whole, inside the plate's extent) but not found.
    rejected_pixels : ndarray, shape (K, 2), float64
        Centroids of blobs that were not used, px.
    rejected_reasons : tuple of str
        Why, per rejected blob: ``"edge"`` (cut by the image edge), ``"area"``
        (implausible size), ``"crowded"`` (touching another blob's window),
        ``"unindexed"`` (not on the grid), ``"outlier"`` (off the smooth grid fit).
    image_size : (int, int)
        (width, height) of the image, px.
    background : float
        Median background level, image units.
    noise : float
        Pixel noise σ, image units.
    threshold : float
        Median threshold of the dot mask, image units.
    source : str
        The image's name (used in messages).
    """

    pixels: np.ndarray
    indices: np.ndarray
    world_xy: np.ndarray
    area: np.ndarray
    flags: np.ndarray
    marks: dict[str, int]
    missing: np.ndarray
    rejected_pixels: np.ndarray
    rejected_reasons: tuple[str, ...]
    image_size: tuple[int, int]
    background: float
    noise: float
    threshold: float
    source: str = field(default="image")

    def __len__(self) -> int:
        return len(self.pixels)

    def observation(self, z: float) -> PlaneObservation:
        """The dots as a calibration plane at traverse position ``z`` (m)."""
        return PlaneObservation(
            z=float(z), pixels=self.pixels.copy(), world_xy=self.world_xy.copy()
        )


#: The name the brief of issue 4 uses for the result.
DotDetections = PlaneDots


# -- image checks and background ---------------------------------------------------------
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


# -- blobs and centroids -------------------------------------------------------------------
@dataclass(frozen=True)
class _Blobs:
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
) -> _Blobs:
    h, w = signal.shape
    n, labels, stats, _ = cv2.connectedComponentsWithStats(
        mask.astype(np.uint8), connectivity=8, ltype=cv2.CV_32S
    )
    area = stats[:, cv2.CC_STAT_AREA].astype(np.int64)
    keep = np.flatnonzero(area >= min_area)
    keep = keep[keep > 0]
    if len(keep) == 0:
        return _Blobs(
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
    return _Blobs(centroid=centroid, area=area[keep], reason=reason, saturated=sat[1:])


def _relative_area(centroid: np.ndarray, area: np.ndarray) -> np.ndarray:
    """Area of each blob over the median area of its nearest neighbours."""
    k = min(_AREA_NEIGHBOURS, len(area) - 1)
    if k < 1:
        return np.ones(len(area))
    _, nb = cKDTree(centroid).query(centroid, k=k + 1)
    return area / np.median(area[nb[:, 1:]], axis=1)


# -- the detector ---------------------------------------------------------------------------
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


def _sizes_against_neighbours(
    blobs: _Blobs, reason: np.ndarray, mark_area_ratio: float, source: str, mask: str
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


def _plane_dots(
    blobs: _Blobs,
    reason: np.ndarray,
    nodes: np.ndarray,
    det: np.ndarray,
    mark_rows: Mapping[str, int],
    description: PlateDescription,
    *,
    dot_area: float,
    margin: int,
    image_size: tuple[int, int],
    background: np.ndarray,
    noise: float,
    level: float,
    source: str,
) -> PlaneDots:
    """The result of :func:`find_dots`: the indexed blobs ``det`` at grid ``nodes`` in
    grid order, flagged, with the rejected blobs (``reason``) and the grid nodes missed."""
    order = np.lexsort((nodes[:, 0], nodes[:, 1]))
    nodes, det = nodes[order], det[order]
    flags = np.zeros(len(det), dtype=np.uint8)
    marks_out: dict[str, int] = {}
    for name, k in mark_rows.items():
        row = int(np.flatnonzero(det == k)[0])
        marks_out[name] = row
        flags[row] |= FLAG_MARK
    flags[blobs.saturated[det]] |= FLAG_SATURATED
    missing = missing_nodes(nodes, blobs.centroid[det], description, dot_area, margin, image_size)
    rejected = np.flatnonzero(reason != "")
    if len(missing) or len(rejected):
        log.info(
            "%s: %d dots indexed, %d expected node(s) missing, %d blob(s) rejected",
            source,
            len(det),
            len(missing),
            len(rejected),
        )
    return PlaneDots(
        pixels=blobs.centroid[det].copy(),
        indices=nodes,
        world_xy=nodes.astype(float) * description.pitch,
        area=blobs.area[det].copy(),
        flags=flags,
        marks=marks_out,
        missing=missing,
        rejected_pixels=blobs.centroid[rejected].copy(),
        rejected_reasons=tuple(str(r) for r in reason[rejected]),
        image_size=(int(image_size[0]), int(image_size[1])),
        background=float(np.median(background)),
        noise=float(noise),
        threshold=float(np.median(background + level)),
        source=source,
    )


def _threshold_blobs(
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
) -> tuple[np.ndarray, np.ndarray, float, np.ndarray | float, _Blobs]:
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
    blobs = _threshold_blobs(
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


def find_dots(
    image: np.ndarray,
    description: PlateDescription,
    *,
    source: str = "image",
    threshold_fraction: float = 0.2,
    threshold_sigmas: float = 6.0,
    min_area: int = 9,
    margin: int = 3,
    ring: int = 3,
    background_tile: int = 64,
    saturation: float | None = None,
    seeds: Mapping[tuple[int, int], tuple[float, float]] | None = None,
    threshold: str = "global",
) -> PlaneDots:
    """Detect, centre and index the dots of one plate image.

    Parameters
    ----------
    image : ndarray, shape (H, W)
        Grey levels (integers or floats), x = column, y = row.
    description : PlateDescription
        The nominal plate.
    source : str
        Name of the image (a file name) for messages.
    threshold_fraction : float
        f: the dot mask threshold is at least f × the image's signal above background
        (0 < f < 1).
    threshold_sigmas : float
        k: and at least k noise σ above background.
    min_area : int
        Blobs smaller than this are specks, dropped, px.
    margin : int
        The centroid window is the blob grown by this many px (holds the dot's blurred
        edge), ≥ 1.
    ring : int
        Width of the ring outside the window where the local background is measured, px.
    background_tile : int
        Tile size of the background level map, px (several dot pitches).
    saturation : float, optional
        Pixels at or above this level flag their dot as saturated (default: the
        dtype's maximum for integer images; none for floats).
    seeds : mapping of (int, int) to (float, float), optional
        Seed dots: grid index (i, j) → approximate pixel (x, y) of three or more dots,
        not on a line (what OpenPTV's manual orientation asks for). They replace the
        marks: the grid grows from the dots nearest to them.
    threshold : {"global", "local"}
        "global": the background from tile medians and the signal the image's 99.9th
        percentile above it; "local": both from the pixel's surroundings (an opening
        and a local maximum over ``background_tile`` px, saturated pixels left out), so
        that a saturated region does not raise the threshold of the dots elsewhere.

    Returns
    -------
    PlaneDots

    Raises
    ------
    ValueError
        A non-2-D, empty or non-real image, NaN pixels, or bad options.
    NoTargetError
        Fewer than ``MIN_BLOBS`` dot-like blobs ("no target ... in <source>").
    MarkersNotFoundError
        The three marks cannot be found or placed ("markers not found in <source>"), or
        the plate has none and no seeds are given.
    SeedDotsError
        Seeds with no dot near them, or that contradict each other.
    """
    if not isinstance(description, PlateDescription):
        raise TypeError(f"description must be a PlateDescription, got {type(description).__name__}")
    signal, background, noise, level, blobs = _threshold_blobs(
        image,
        description.dots,
        source=source,
        threshold=threshold,
        threshold_fraction=threshold_fraction,
        threshold_sigmas=threshold_sigmas,
        min_area=min_area,
        margin=margin,
        ring=ring,
        background_tile=background_tile,
        saturation=saturation,
    )
    h, w = signal.shape
    reason = blobs.reason.copy()
    mask = f"{threshold} threshold {np.median(level):.3g} above background, noise σ {noise:.3g}"
    rel = _sizes_against_neighbours(blobs, reason, description.mark_area_ratio, source, mask)
    usable = reason == ""
    pts = blobs.centroid
    dot_area = float(np.median(blobs.area[usable]))
    nodes, det, mark_rows, outliers = index_grid(
        pts, usable, rel, description, dot_area, (w, h), source, seeds=dict(seeds or {})
    )
    reason[usable & ~np.isin(np.arange(len(reason)), det)] = "unindexed"
    reason[outliers] = "outlier"
    return _plane_dots(
        blobs,
        reason,
        nodes,
        det,
        mark_rows,
        description,
        dot_area=dot_area,
        margin=margin,
        image_size=(w, h),
        background=background,
        noise=noise,
        level=level,
        source=source,
    )


# -- several planes -----------------------------------------------------------------------
def observations_from_images(
    images: Sequence[np.ndarray],
    z: Sequence[float],
    description: PlateDescription,
    *,
    sources: Sequence[str] | None = None,
) -> list[PlaneObservation]:
    """Detect and index the dots of a traverse of plate images of one camera.

    Parameters
    ----------
    images : sequence of ndarray, shape (H, W)
        One plate image per traverse position, all of one size.
    z : sequence of float
        Traverse positions Z_j, m, one per image.
    description : PlateDescription
        The nominal plate.
    sources : sequence of str, optional
        Names of the images (file names) for messages.

    Returns
    -------
    list of PlaneObservation
        One per image, in order, ready for ``calibrate_model_free`` / ``calibrate_tsai``.

    Raises
    ------
    ValueError
        Fewer than two planes, a length mismatch, planes of different image sizes, or
        any error of :func:`find_dots` (naming the image).
    """
    images = list(images)
    z = [float(v) for v in z]
    if len(images) != len(z):
        raise ValueError(f"got {len(images)} image(s) but {len(z)} plane position(s)")
    if len(images) < 2:
        raise ValueError(f"a calibration needs at least two planes, got {len(images)}")
    names = (
        [f"plane {k} (Z = {zk:.6g} m)" for k, zk in enumerate(z)]
        if sources is None
        else [str(s) for s in sources]
    )
    if len(names) != len(images):
        raise ValueError(f"got {len(images)} image(s) but {len(names)} source name(s)")
    shapes = [np.shape(im) for im in images]
    if len(set(shapes)) != 1:
        listing = ", ".join(f"{n}: {s}" for n, s in zip(names, shapes, strict=True))
        raise ValueError(f"planes of different image sizes: {listing}")
    return [
        find_dots(im, description, source=name).observation(zk)
        for im, zk, name in zip(images, z, names, strict=True)
    ]
