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
   Seed dots given by the user replace the marks: four or more fix a homography, whose
   prediction gives the dots next to each seed before the grid grows; a seed off the
   cubic fit is a wrong index, refused.
6. **Missing nodes.** Grid nodes that should be seen but were not: inside the plate's
   ``extent`` (when known; else inside the index box of the found dots) and within two
   grid steps of found dots, predicted with their whole window on the image.

Steps 1–3 are :mod:`ptv.calibration.blobs`, steps 4–6 :mod:`ptv.calibration._plate_grid`;
the plate and the result are described in :mod:`ptv.calibration.plate`.

Errors (``ValueError`` subclasses, naming ``source``): a non-2-D or non-real image,
NaNs; :class:`NoTargetError` when too few dot-like blobs are seen;
:class:`MarkersNotFoundError` when the marks cannot be found or placed.
"""

import logging
from collections.abc import Mapping, Sequence

import numpy as np

from ptv.calibration._plate_grid import (  # raised by find_dots: part of its API
    MarkersNotFoundError as MarkersNotFoundError,
)
from ptv.calibration._plate_grid import NoDotAtSeedError as NoDotAtSeedError
from ptv.calibration._plate_grid import SeedDotsError as SeedDotsError
from ptv.calibration._plate_grid import index_grid, missing_nodes
from ptv.calibration.blobs import Blobs, sizes_against_neighbours, threshold_blobs
from ptv.calibration.blobs import NoTargetError as NoTargetError
from ptv.calibration.observations import PlaneObservation
from ptv.calibration.plate import FLAG_MARK, FLAG_SATURATED, PlaneDots, PlateDescription

log = logging.getLogger(__name__)


def _plane_dots(
    blobs: Blobs,
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
    signal, background, noise, level, blobs = threshold_blobs(
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
    rel = sizes_against_neighbours(blobs, reason, description.mark_area_ratio, source, mask)
    usable = reason == ""
    pts = blobs.centroid
    dot_area = float(np.median(blobs.area[usable]))
    try:
        nodes, det, mark_rows, outliers = index_grid(
            pts, usable, rel, description, dot_area, (w, h), source, seeds=dict(seeds or {})
        )
    except NoDotAtSeedError as error:
        above = signal - background
        why = _what_set_the_threshold(
            above, level, noise, threshold, threshold_fraction, threshold_sigmas, error
        )
        raise NoDotAtSeedError(f"{error}; {why}", error.pixel, error.reach) from None
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


def _what_set_the_threshold(
    above: np.ndarray,
    level: np.ndarray | float,
    noise: float,
    threshold: str,
    threshold_fraction: float,
    threshold_sigmas: float,
    missed: NoDotAtSeedError,
) -> str:
    """Why a seed found no dot, as far as the threshold tells: how high the image rises
    above the background near the seed against the mask level there, and which term
    set that level. ``above`` (H, W) is the signal above the background."""
    h, w = above.shape
    x, y = missed.pixel
    r = int(np.ceil(missed.reach))
    col, row = round(x), round(y)
    window = (
        slice(max(row - r, 0), min(row + r + 1, h)),
        slice(max(col - r, 0), min(col + r + 1, w)),
    )
    local = np.broadcast_to(level, above.shape)[window]
    if local.size == 0:
        return "the seed is off the image"
    rise, at = float(above[window].max()), float(np.median(local))
    there = (
        f"the image rises {rise:.3g} above the background there, the {threshold} "
        f"threshold is {at:.3g}"
    )
    if threshold == "local" or rise >= at:
        return there
    peak = float(np.percentile(above, 99.9))
    if threshold_fraction * peak > threshold_sigmas * noise:
        return (
            f"{there}, set by {threshold_fraction:g} × the image's 99.9th percentile above the "
            f"background ({peak:.3g}, against {threshold_sigmas:g} noise σ = "
            f"{threshold_sigmas * noise:.3g}): if a bright region (a banner, a reflection, a "
            'window frame) set it rather than the dots, use "threshold": "local" in the '
            "target or mask that region (cameras.<name>.mask)"
        )
    return f"{there}, {threshold_sigmas:g} noise σ (σ = {noise:.3g}): the dot is too faint"


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
