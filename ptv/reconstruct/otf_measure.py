"""Measure the OTF of each camera from its particle images, as a laboratory would.

Per camera (:func:`measure_camera_otf`):

1. Background level and noise from the image's darkest pixels
   (:func:`ptv.reconstruct.dense_background.background_level`).
2. Particles detected with :func:`ptv.detect.detect_particles` (least-squares Gaussian
   centres, blends split).
3. Isolated particles kept: a clean detection (no flag: not saturated, not on the
   edge, not split from a blend, not elongated) with no other detection closer than
   ``isolation`` px, so that no neighbour's light falls on its fitting window.
4. Each kept particle image fitted on a (2w + 1)² window by a pixel-integrated
   elliptical Gaussian plus a local background (:mod:`ptv.reconstruct._fit`), giving
   σ_x, σ_y, ρ and the integrated intensity A. Fits with a large residual (above
   ``max_rms_noise`` background noise σ: a hidden neighbour) or too faint (peak below
   ``min_snr`` σ) are dropped.
5. The particles' region on a ``regions`` = (rows, columns) grid spanning the extent
   of the detections (1st to 99th percentile on each axis), and per region the median
   of each quantity. ρ is set to 0 in a region where its median is not significant
   (below 3 standard errors, or below 0.03 in magnitude).

A region with fewer than ``min_per_region`` fitted particles raises
:class:`TooFewIsolatedImages` (a ValueError) that gives every region's count: pool more
exposures (a stack of images), record sparser images (a calibration recording at
0.001–0.01 particles per pixel), or ask for fewer regions. :func:`refine_otf_pooled`
measures the OTF per depth slab from reconstructed particles.
"""

import logging
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ptv.detect import detect_particles
from ptv.reconstruct._fit import N_PARAMS, fit_spots
from ptv.reconstruct.dense_background import BackgroundLevel, background_level
from ptv.reconstruct.otf import OpticalTransferFunction, peak_fraction

logger = logging.getLogger(__name__)


class TooFewIsolatedImages(ValueError):
    """Too few isolated particle images in some cell to measure the OTF there: more
    exposures, a sparser recording or fewer cells would do.

    Attributes
    ----------
    poorest : int
        Fitted images in the poorest cell.
    inner_only : bool
        Whether every cell short of images lies in an inner depth slab (which the
        defocus law can fill, :func:`refine_otf_pooled`).
    """

    def __init__(self, message: str, *, poorest: int = 0, inner_only: bool = False):
        super().__init__(message)
        self.poorest = poorest
        self.inner_only = inner_only


def _check_regions(regions: object) -> tuple[int, int]:
    try:
        ny, nx = (int(v) for v in regions)  # type: ignore[union-attr]
    except (TypeError, ValueError):
        raise ValueError(f"regions must be (rows, columns) of integers, got {regions!r}") from None
    if ny < 1 or nx < 1 or (ny, nx) != tuple(regions):  # type: ignore[arg-type]
        raise ValueError(f"regions must be (rows, columns) of integers >= 1, got {regions!r}")
    return ny, nx


def measure_camera_otf(
    image: np.ndarray,
    *,
    regions: tuple[int, int] = (3, 4),
    min_per_region: int = 20,
    isolation: float = 5.0,
    window: int = 3,
    threshold_sigmas: float = 8.0,
    min_snr: float = 20.0,
    max_rms_noise: float = 2.0,
    fit_orientation: bool = True,
    saturation: float | None = None,
    camera: str = "camera",
) -> OpticalTransferFunction:
    """The OTF of one camera, measured on its particle images.

    Parameters
    ----------
    image : ndarray, shape (H, W) or (E, H, W)
        Particle image, integers (DN) or floats; or E exposures of the camera, whose
        isolated particle images are pooled (a dense recording holds few per image).
    regions : (rows, columns)
        Grid of image regions, >= 1 each.
    min_per_region : int
        Fitted isolated particle images needed in every region, >= 1.
    isolation : float
        Distance to the nearest other detection above which a particle counts as
        isolated, px (a few σ; default 5), > 0.
    window : int
        Half-width w of the fitting window, px (at least about 3σ), >= 2.
    threshold_sigmas : float
        Detection threshold in background noise units, > 0.
    min_snr : float
        Fitted peak above the background needed, in noise units, > 0.
    max_rms_noise : float
        Largest rms fit residual, in background noise units, > 0.
    fit_orientation : bool
        Fit ρ (elliptical spots of any orientation); False: axis-aligned spots.
    saturation : float or None
        Saturation level for the detector (None: the dtype's maximum).
    camera : str
        Name used in messages.

    Returns
    -------
    OpticalTransferFunction

    Raises
    ------
    ValueError
        Bad image or option.
    TooFewIsolatedImages
        Fewer than ``min_per_region`` isolated particles fitted in some region (the
        message gives every region's count).
    """
    ny, nx = _check_regions(regions)
    if not (isinstance(min_per_region, int | np.integer) and min_per_region >= 1):
        raise ValueError(f"min_per_region must be an integer >= 1, got {min_per_region!r}")
    if not (isinstance(window, int | np.integer) and window >= 2):
        raise ValueError(f"window must be an integer >= 2, got {window!r}")
    for name, value in (
        ("isolation", isolation),
        ("threshold_sigmas", threshold_sigmas),
        ("min_snr", min_snr),
        ("max_rms_noise", max_rms_noise),
    ):
        if not (np.isfinite(value) and value > 0):
            raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
    stack = np.asarray(image)
    if stack.ndim not in (2, 3) or stack.size == 0:
        raise ValueError(f"{camera}: image must be 2-D or a stack of them, got shape {stack.shape}")
    stack = stack.reshape((-1, *stack.shape[-2:]))
    pooled = [
        _fit_isolated(
            img,
            isolation,
            window,
            threshold_sigmas,
            min_snr,
            max_rms_noise,
            fit_orientation,
            saturation,
        )
        for img in stack
    ]
    detected = np.concatenate([p.detected for p in pooled])
    fitted = np.concatenate([p.fitted for p in pooled])
    n_isolated = sum(p.isolated for p in pooled)
    needed = ny * nx * min_per_region
    if len(detected) < 2:
        raise TooFewIsolatedImages(
            f"{camera}: {len(detected)} particle images detected; measuring the OTF on a "
            f"{ny} x {nx} grid needs at least {min_per_region} isolated ones per region "
            f"({needed} in all)"
        )
    xy = fitted[:, 1:3]
    # the region grid spans the extent of all detections
    lo = np.percentile(detected, 1.0, axis=0)
    hi = np.percentile(detected, 99.0, axis=0)
    hi = np.maximum(hi, lo + 1.0)
    edges_x = np.linspace(lo[0], hi[0], nx + 1)
    edges_y = np.linspace(lo[1], hi[1], ny + 1)
    cx = np.clip(np.searchsorted(edges_x, xy[:, 0], side="right") - 1, 0, nx - 1)
    cy = np.clip(np.searchsorted(edges_y, xy[:, 1], side="right") - 1, 0, ny - 1)
    counts = np.zeros((ny, nx), dtype=np.int64)
    np.add.at(counts, (cy, cx), 1)
    logger.info(
        "%s: %d exposures, %d detections, %d isolated, %d fitted; per region %s",
        camera,
        len(stack),
        len(detected),
        n_isolated,
        len(fitted),
        counts.tolist(),
    )
    if counts.min() < min_per_region:
        raise TooFewIsolatedImages(
            f"{camera}: too few isolated particle images to measure the OTF: "
            f"{int(counts.min())} in the poorest region, {min_per_region} needed in each of "
            f"the {ny} x {nx} regions (counts per region, rows top to bottom: "
            f"{counts.tolist()}; {len(detected)} detected in {len(stack)} exposures, "
            f"{n_isolated} isolated by {isolation:g} px, {len(fitted)} fitted). Pool more "
            "exposures, use a sparser recording (about 0.001-0.01 particles per pixel) or "
            "fewer regions"
        )
    tables, _ = _aggregate(fitted, np.zeros(len(cy), dtype=np.int64), cy, cx, (1, ny, nx))
    return OpticalTransferFunction(
        shape=stack.shape[1:],
        grid_x=0.5 * (edges_x[1:] + edges_x[:-1]),
        grid_y=0.5 * (edges_y[1:] + edges_y[:-1]),
        counts=counts,
        background=float(np.median([p.background.level for p in pooled])),
        noise=float(np.median([p.background.noise for p in pooled])),
        **tables,
    )


@dataclass(frozen=True)
class _IsolatedFits:
    """One image's detections and the fits of its isolated particle images."""

    detected: np.ndarray  # (N, 2) px
    fitted: np.ndarray  # (M, N_PARAMS): A, x, y, σ_x, σ_y, ρ, … of the good fits
    isolated: int
    background: BackgroundLevel


def _fit_isolated(
    img, isolation, window, threshold_sigmas, min_snr, max_rms_noise, fit_orientation, saturation
) -> _IsolatedFits:
    """Module docstring, steps 1-4, on one image."""
    back = background_level(img)
    det = detect_particles(img, threshold_sigmas=threshold_sigmas, saturation=saturation)
    if len(det.xy) < 2:
        return _IsolatedFits(det.xy.reshape(-1, 2), np.empty((0, N_PARAMS)), 0, back)
    dist, _ = cKDTree(det.xy).query(det.xy, k=2)
    isolated = (dist[:, 1] > isolation) & (det.flags == 0)
    params, rms, ok = fit_spots(
        img.astype(np.float64),
        np.ascontiguousarray(det.xy[isolated]),
        int(window),
        0.8,
        fit_orientation,
        50,
    )
    peak = params[:, 0] * peak_fraction(params[:, 3], params[:, 4])
    good = ok & (rms <= max_rms_noise * back.noise) & (peak >= min_snr * back.noise)
    return _IsolatedFits(det.xy, params[good], int(isolated.sum()), back)


def _aggregate(fitted, cz, cy, cx, shape) -> tuple[dict, np.ndarray]:
    """Per-cell medians of the fitted spots (module docstring, step 5)."""
    tables = {k: np.empty(shape) for k in ("sigma_x", "sigma_y", "rho", "intensity")}
    counts = np.zeros(shape, dtype=np.int64)
    np.add.at(counts, (cz, cy, cx), 1)
    for z in range(shape[0]):
        for r in range(shape[1]):
            for c in range(shape[2]):
                sel = fitted[(cz == z) & (cy == r) & (cx == c)]
                if not len(sel):
                    for table in tables.values():
                        table[z, r, c] = np.nan
                    continue
                tables["sigma_x"][z, r, c] = np.median(sel[:, 3])
                tables["sigma_y"][z, r, c] = np.median(sel[:, 4])
                tables["intensity"][z, r, c] = np.median(sel[:, 0])
                tables["rho"][z, r, c] = _significant_rho(sel[:, 5])
    return tables, counts


def measure_otf(
    images: Sequence[np.ndarray],
    *,
    regions: tuple[int, int] = (3, 4),
    min_per_region: int = 20,
    isolation: float = 5.0,
    window: int = 3,
    threshold_sigmas: float = 8.0,
    fit_orientation: bool = True,
    saturation: float | None = None,
) -> list[OpticalTransferFunction]:
    """The OTF of every camera, each measured on its own images (:func:`measure_camera_otf`).

    Parameters
    ----------
    images : sequence of C ndarray, shape (H_c, W_c) or (E, H_c, W_c)
        One particle image per camera, or E exposures of each (their isolated particle
        images pooled).
    regions, min_per_region, isolation, window, threshold_sigmas, fit_orientation, saturation
        As :func:`measure_camera_otf`.

    Returns
    -------
    list of C OpticalTransferFunction
    """
    if len(images) < 1:
        raise ValueError("measure_otf needs at least one image")
    return [
        measure_camera_otf(
            image,
            regions=regions,
            min_per_region=min_per_region,
            isolation=isolation,
            window=window,
            threshold_sigmas=threshold_sigmas,
            fit_orientation=fit_orientation,
            saturation=saturation,
            camera=f"camera {c}",
        )
        for c, image in enumerate(images)
    ]


def refine_otf(
    images: Sequence[np.ndarray],
    positions: np.ndarray,
    xy: np.ndarray,
    otfs: Sequence[OpticalTransferFunction],
    **options,
) -> list[OpticalTransferFunction]:
    """The OTF per image region and depth slab, from the particles reconstructed on one
    exposure: :func:`refine_otf_pooled` with ``[(images, positions, xy)]``.

    Parameters
    ----------
    images : sequence of C ndarray, shape (H_c, W_c)
        The images the particles were reconstructed from.
    positions : ndarray, shape (N, 3)
        Reconstructed particle positions, m.
    xy : ndarray, shape (C, N, 2)
        Their images in each camera, px (NaN where not imaged).
    otfs : sequence of C OpticalTransferFunction
        The OTFs measured without depth (their region grids are kept).
    **options
        As :func:`refine_otf_pooled`.

    Returns
    -------
    list of C OpticalTransferFunction
    """
    return refine_otf_pooled([(images, positions, xy)], otfs, **options)


def refine_otf_pooled(
    exposures: Sequence[tuple[Sequence[np.ndarray], np.ndarray, np.ndarray]],
    otfs: Sequence[OpticalTransferFunction],
    *,
    depth_slabs: int = 5,
    depth_axis: int = 2,
    min_per_cell: int = 15,
    isolation: float = 5.0,
    window: int = 3,
    min_snr: float = 20.0,
    max_rms_noise: float = 2.0,
    fit_orientation: bool = True,
    fill_inner: bool = True,
) -> list[OpticalTransferFunction]:
    """The OTF per image region **and depth slab**, from reconstructed particles.

    As Schanz et al. (2013) calibrate the OTF per sub-volume: particles reconstructed
    from sparse images (e.g. by :func:`ptv.reconstruct.reconstruct` with the OTFs of
    :func:`measure_otf`) give each particle image a depth. In each camera, the images
    with no other reconstructed particle's image within ``isolation`` px are fitted
    (:mod:`ptv.reconstruct._fit`), pooled over the exposures, and the medians taken per
    cell of the given OTF's image regions × ``depth_slabs`` slabs of equal thickness
    spanning the particles' depths (1st to 99th percentile). With ``fill_inner``, a
    cell of an inner slab with fewer than ``min_per_cell`` images takes σ from the
    defocus law fitted to its region's images at every depth (:func:`_defocus_fill`).

    Parameters
    ----------
    exposures : sequence of E (images, positions, xy)
        Per exposure: the C images (H_c, W_c) the particles were reconstructed from,
        their positions (N, 3), m, and their images in each camera (C, N, 2), px (NaN
        where not imaged).
    otfs : sequence of C OpticalTransferFunction
        The OTFs measured without depth (their region grids are kept).
    depth_slabs : int
        Depth slabs, >= 1.
    depth_axis : int
        World axis of the depth (2: Z).
    min_per_cell : int
        Fitted particle images needed in every cell, >= 1.
    isolation, window, min_snr, max_rms_noise, fit_orientation
        As :func:`measure_camera_otf`.
    fill_inner : bool
        Fill the inner slabs' cells short of images from the defocus law; False: refuse
        them too (to pool more exposures first).

    Returns
    -------
    list of C OpticalTransferFunction
        With ``grid_z`` (the slabs' centres, m).

    Raises
    ------
    ValueError
        Inconsistent inputs.
    TooFewIsolatedImages
        A cell with fewer than ``min_per_cell`` fitted images in the first or last slab
        (or, without ``fill_inner``, in any slab); the message gives every cell's count.
    """
    n_cams = len(otfs)
    if len(exposures) < 1:
        raise ValueError("refine_otf_pooled needs at least one exposure")
    checked = [_checked_exposure(*exposure, otfs) for exposure in exposures]
    if not (isinstance(depth_slabs, int | np.integer) and depth_slabs >= 1):
        raise ValueError(f"depth_slabs must be an integer >= 1, got {depth_slabs!r}")
    if depth_axis not in (0, 1, 2):
        raise ValueError(f"depth_axis must be 0, 1 or 2, got {depth_axis!r}")
    depth = np.concatenate([positions[:, depth_axis] for _, positions, _ in checked])
    lo, hi = np.percentile(depth, [1.0, 99.0]) if len(depth) else (0.0, 1.0)
    hi = max(hi, lo + 1e-9)
    edges_z = np.linspace(lo, hi, depth_slabs + 1)
    out = []
    for c in range(n_cams):
        otf = otfs[c]
        fits = [
            _fit_reconstructed(
                np.asarray(images[c], dtype=np.float64),
                xy[c],
                positions[:, depth_axis],
                otf,
                isolation,
                window,
                min_snr,
                max_rms_noise,
                fit_orientation,
            )
            for images, positions, xy in checked
        ]
        fitted = np.concatenate([f[0] for f in fits])
        fitted_depth = np.concatenate([f[1] for f in fits])
        edges_x = _edges(otf.grid_x)
        edges_y = _edges(otf.grid_y)
        cx = np.clip(
            np.searchsorted(edges_x, fitted[:, 1], side="right") - 1, 0, otf.grid_x.size - 1
        )
        cy = np.clip(
            np.searchsorted(edges_y, fitted[:, 2], side="right") - 1, 0, otf.grid_y.size - 1
        )
        cz = np.clip(np.searchsorted(edges_z, fitted_depth, side="right") - 1, 0, depth_slabs - 1)
        shape = (depth_slabs, otf.grid_y.size, otf.grid_x.size)
        counts = np.zeros(shape, dtype=np.int64)
        np.add.at(counts, (cz, cy, cx), 1)
        logger.info(
            "camera %d: %d isolated reconstructed particles fitted in %d exposures; per cell %s",
            c,
            len(fitted),
            len(checked),
            counts.tolist(),
        )
        short = counts < min_per_cell
        inner = np.zeros(shape, dtype=bool)
        inner[1:-1] = True
        if (short & ~(inner & fill_inner)).any():
            where = "outer slab's cell" if (short & ~inner).any() else "cell"
            raise TooFewIsolatedImages(
                f"camera {c}: too few isolated reconstructed particle images to measure the "
                f"OTF per depth slab: {int(counts[short].min())} in the poorest {where}, "
                f"{min_per_cell} needed in each cell of the {shape[0]} x {shape[1]} x "
                f"{shape[2]} (slabs x rows x columns; counts in {len(checked)} exposures "
                f"{counts.tolist()}). Pool more exposures, reconstruct particles from sparser "
                "images, or ask for fewer slabs",
                poorest=int(counts.min()),
                inner_only=not (short & ~inner).any(),
            )
        tables, _ = _aggregate(fitted, cz, cy, cx, shape)
        if short.any():
            _defocus_fill(tables, short, fitted, fitted_depth, cy, cx, edges_z)
            logger.info(
                "camera %d: σ of the cells %s from the defocus law fitted over all depths",
                c,
                np.argwhere(short).tolist(),
            )
        out.append(
            OpticalTransferFunction(
                shape=otf.shape,
                grid_x=otf.grid_x,
                grid_y=otf.grid_y,
                grid_z=0.5 * (edges_z[1:] + edges_z[:-1]),
                depth_axis=depth_axis,
                counts=counts,
                background=float(np.median([f[2].level for f in fits])),
                noise=float(np.median([f[2].noise for f in fits])),
                **tables,
            )
        )
    return out


def _significant_rho(rho: np.ndarray) -> float:
    """The median ρ of some fitted images, or 0 where it is not significant (module
    docstring, step 5)."""
    med = float(np.median(rho))
    err = 1.2533 * np.std(rho) / np.sqrt(len(rho))
    return med if abs(med) > max(3 * err, 0.03) else 0.0


def defocus_law(depth: np.ndarray, sigma: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Particle-image width at depths ``at`` from the defocus law fitted to images.

    Defocus blurs a particle image by a disc whose diameter grows linearly with the
    distance from the focal plane, and adds in quadrature to the diffraction spot: σ² is
    quadratic in depth. σ² = a + b·z + c·z² is fitted to the images by least squares
    (one pass, then again without the images beyond 3 robust standard deviations: hidden
    neighbours).

    Parameters
    ----------
    depth : ndarray, shape (N,)
        Depth of each fitted image's particle, m.
    sigma : ndarray, shape (N,)
        Its fitted width, px.
    at : ndarray, shape (M,)
        Depths to evaluate the law at, m.

    Returns
    -------
    ndarray, shape (M,)
        σ at ``at``, px; NaN where the fitted σ² is not positive (too few images, or too
        narrow a depth range).
    """
    depth, at = np.asarray(depth, dtype=np.float64), np.asarray(at, dtype=np.float64)
    scale = max(float(np.ptp(at)), 1e-12)
    design = np.stack([np.ones_like(depth), depth / scale, (depth / scale) ** 2], axis=1)
    target = np.asarray(sigma, dtype=np.float64) ** 2
    keep = np.ones(len(depth), dtype=bool)
    for _ in range(2):
        coef = np.linalg.lstsq(design[keep], target[keep], rcond=None)[0]
        residual = target - design @ coef
        spread = 1.4826 * np.median(np.abs(residual[keep]))
        keep = np.abs(residual) <= 3 * max(spread, 1e-12)
    value = np.stack([np.ones_like(at), at / scale, (at / scale) ** 2], axis=1) @ coef
    with np.errstate(invalid="ignore"):
        return np.where(value > 0, np.sqrt(np.maximum(value, 0.0)), np.nan)


def _defocus_fill(tables, short, fitted, depth, cy, cx, edges_z) -> None:
    """Fill the inner cells ``short`` of fitted images from all the region's depths:
    σ_x and σ_y from :func:`defocus_law` fitted to the region's images at every depth,
    ρ and intensity the region's medians over all depths. An oblique camera's isolated
    images lie where its image of the volume is thin, near the volume's front and back
    faces: at high density its middle slabs hold few.
    """
    centres = 0.5 * (edges_z[1:] + edges_z[:-1])
    for r, col in {(int(r), int(col)) for _, r, col in np.argwhere(short)}:
        region = (cy == r) & (cx == col)
        z, params = depth[region], fitted[region]
        cells = np.flatnonzero(short[:, r, col])
        for name, column in (("sigma_x", 3), ("sigma_y", 4)):
            value = defocus_law(z, params[:, column], centres)
            if not np.isfinite(value[cells]).all():
                raise TooFewIsolatedImages(
                    f"the defocus law fitted over {len(z)} images gives no width at depths "
                    f"{centres[cells].tolist()} m: too few images, or too narrow a depth range"
                )
            tables[name][cells, r, col] = value[cells]
        tables["rho"][short[:, r, col], r, col] = _significant_rho(params[:, 5])
        tables["intensity"][short[:, r, col], r, col] = np.median(params[:, 0])


def _checked_exposure(images, positions, xy, otfs):
    """One exposure of :func:`refine_otf_pooled`, its positions and xy as float arrays
    and its shapes checked."""
    positions = np.asarray(positions, dtype=np.float64)
    xy = np.asarray(xy, dtype=np.float64)
    n_cams = len(images)
    if positions.ndim != 2 or positions.shape[1] != 3:
        raise ValueError(f"positions must have shape (N, 3), got {positions.shape}")
    if xy.shape != (n_cams, len(positions), 2) or len(otfs) != n_cams:
        raise ValueError(
            f"need xy of shape ({n_cams}, {len(positions)}, 2) and {n_cams} OTFs, got "
            f"{xy.shape} and {len(otfs)}"
        )
    for c, (image, otf) in enumerate(zip(images, otfs, strict=True)):
        if np.shape(image) != otf.shape:
            raise ValueError(
                f"image of camera {c} has shape {np.shape(image)}, its OTF {otf.shape}"
            )
    return images, positions, xy


def _fit_reconstructed(
    img, xy, depth, otf, isolation, window, min_snr, max_rms_noise, fit_orientation
) -> tuple[np.ndarray, np.ndarray, BackgroundLevel]:
    """The good fits (M, N_PARAMS) of one camera's isolated reconstructed particle
    images on one exposure, their depths (M,), m, and the image's background."""
    seen = np.flatnonzero(np.isfinite(xy).all(axis=1))
    pts = xy[seen]
    dist, _ = (
        cKDTree(pts).query(pts, k=2) if len(pts) > 1 else (np.full((len(pts), 2), np.inf), None)
    )
    alone = seen[dist[:, 1] > isolation]
    back = background_level(img)
    params, rms, ok = fit_spots(
        img,
        np.ascontiguousarray(xy[alone]),
        int(window),
        float(np.median(otf.sigma_x)),
        fit_orientation,
        50,
    )
    peak = params[:, 0] * peak_fraction(params[:, 3], params[:, 4])
    good = ok & (rms <= max_rms_noise * back.noise) & (peak >= min_snr * back.noise)
    return params[good], depth[alone[good]], back


def _edges(centres: np.ndarray) -> np.ndarray:
    """Cell edges around increasing centres (outer edges at ±infinity)."""
    mid = 0.5 * (centres[1:] + centres[:-1])
    return np.concatenate([[-np.inf], mid, [np.inf]])
