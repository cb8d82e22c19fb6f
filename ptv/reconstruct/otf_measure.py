"""Measure the OTF of each camera from its particle images, as a laboratory would.

Per camera (:func:`measure_camera_otf`):

1. Background level and noise from the image's darkest pixels
   (:func:`ptv.reconstruct.background.background_level`).
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

A region with fewer than ``min_per_region`` fitted particles raises a ValueError that
gives every region's count: record sparser images (a calibration recording at
0.001–0.01 particles per pixel), or ask for fewer regions.
"""

import logging
from collections.abc import Sequence

import numpy as np
from scipy.spatial import cKDTree

from ptv.detect import detect_particles
from ptv.reconstruct._fit import fit_spots
from ptv.reconstruct.background import background_level
from ptv.reconstruct.otf import OpticalTransferFunction, peak_fraction

logger = logging.getLogger(__name__)


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
    """The OTF of one camera, measured on one of its particle images.

    Parameters
    ----------
    image : ndarray, shape (H, W)
        Particle image, integers (DN) or floats.
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
        Bad image or option; fewer than ``min_per_region`` isolated particles fitted in
        some region (the message gives every region's count).
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
    img = np.asarray(image)
    if img.ndim != 2:
        raise ValueError(f"{camera}: image must be 2-D, got shape {img.shape}")
    back = background_level(img)
    det = detect_particles(img, threshold_sigmas=threshold_sigmas, saturation=saturation)
    needed = ny * nx * min_per_region
    if len(det.xy) < 2:
        raise ValueError(
            f"{camera}: {len(det.xy)} particle images detected; measuring the OTF on a "
            f"{ny} x {nx} grid needs at least {min_per_region} isolated ones per region "
            f"({needed} in all)"
        )
    dist, _ = cKDTree(det.xy).query(det.xy, k=2)
    isolated = (dist[:, 1] > isolation) & (det.flags == 0)
    floats = img.astype(np.float64)
    params, rms, ok = fit_spots(
        floats, np.ascontiguousarray(det.xy[isolated]), int(window), 0.8, fit_orientation, 50
    )
    amp, sx, sy = params[:, 0], params[:, 3], params[:, 4]
    peak = amp * peak_fraction(sx, sy)
    good = ok & (rms <= max_rms_noise * back.noise) & (peak >= min_snr * back.noise)
    xy = params[good, 1:3]
    # the region grid spans the extent of all detections
    lo = np.percentile(det.xy, 1.0, axis=0)
    hi = np.percentile(det.xy, 99.0, axis=0)
    hi = np.maximum(hi, lo + 1.0)
    edges_x = np.linspace(lo[0], hi[0], nx + 1)
    edges_y = np.linspace(lo[1], hi[1], ny + 1)
    cx = np.clip(np.searchsorted(edges_x, xy[:, 0], side="right") - 1, 0, nx - 1)
    cy = np.clip(np.searchsorted(edges_y, xy[:, 1], side="right") - 1, 0, ny - 1)
    counts = np.zeros((ny, nx), dtype=np.int64)
    np.add.at(counts, (cy, cx), 1)
    logger.info(
        "%s: %d detections, %d isolated, %d fitted; per region %s",
        camera,
        len(det.xy),
        int(isolated.sum()),
        int(good.sum()),
        counts.tolist(),
    )
    if counts.min() < min_per_region:
        raise ValueError(
            f"{camera}: too few isolated particle images to measure the OTF: "
            f"{int(counts.min())} in the poorest region, {min_per_region} needed in each of "
            f"the {ny} x {nx} regions (counts per region, rows top to bottom: "
            f"{counts.tolist()}; {len(det.xy)} detected, {int(isolated.sum())} isolated by "
            f"{isolation:g} px, {int(good.sum())} fitted). Use a sparser recording "
            "(about 0.001-0.01 particles per pixel) or fewer regions"
        )
    tables, _ = _aggregate(params[good], np.zeros(len(cy), dtype=np.int64), cy, cx, (1, ny, nx))
    return OpticalTransferFunction(
        shape=img.shape,
        grid_x=0.5 * (edges_x[1:] + edges_x[:-1]),
        grid_y=0.5 * (edges_y[1:] + edges_y[:-1]),
        counts=counts,
        background=back.level,
        noise=back.noise,
        **tables,
    )


def _aggregate(fitted, cz, cy, cx, shape) -> tuple[dict, np.ndarray]:
    """Per-cell medians of the fitted spots (module docstring, step 5)."""
    tables = {k: np.empty(shape) for k in ("sigma_x", "sigma_y", "rho", "intensity")}
    counts = np.zeros(shape, dtype=np.int64)
    np.add.at(counts, (cz, cy, cx), 1)
    for z in range(shape[0]):
        for r in range(shape[1]):
            for c in range(shape[2]):
                sel = fitted[(cz == z) & (cy == r) & (cx == c)]
                tables["sigma_x"][z, r, c] = np.median(sel[:, 3])
                tables["sigma_y"][z, r, c] = np.median(sel[:, 4])
                tables["intensity"][z, r, c] = np.median(sel[:, 0])
                rho = sel[:, 5]
                med = np.median(rho)
                err = 1.2533 * np.std(rho) / np.sqrt(len(rho))
                tables["rho"][z, r, c] = med if abs(med) > max(3 * err, 0.03) else 0.0
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
    """The OTF of every camera, each measured on its own image (:func:`measure_camera_otf`).

    Parameters
    ----------
    images : sequence of C ndarray, shape (H_c, W_c)
        One particle image per camera (sparse enough for isolated particle images).
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
    *,
    depth_slabs: int = 5,
    depth_axis: int = 2,
    min_per_cell: int = 15,
    isolation: float = 5.0,
    window: int = 3,
    min_snr: float = 20.0,
    max_rms_noise: float = 2.0,
    fit_orientation: bool = True,
) -> list[OpticalTransferFunction]:
    """The OTF per image region **and depth slab**, from reconstructed particles.

    As Schanz et al. (2013) calibrate the OTF per sub-volume: particles reconstructed
    from sparse images (e.g. by :func:`ptv.reconstruct.reconstruct` with the OTFs of
    :func:`measure_otf`) give each particle image a depth. In each camera, the images
    with no other reconstructed particle's image within ``isolation`` px are fitted
    (:mod:`ptv.reconstruct._fit`), and the medians taken per cell of the given OTF's
    image regions × ``depth_slabs`` slabs of equal thickness spanning the particles'
    depths (1st to 99th percentile).

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
    depth_slabs : int
        Depth slabs, >= 1.
    depth_axis : int
        World axis of the depth (2: Z).
    min_per_cell : int
        Fitted particle images needed in every cell, >= 1.
    isolation, window, min_snr, max_rms_noise, fit_orientation
        As :func:`measure_camera_otf`.

    Returns
    -------
    list of C OpticalTransferFunction
        With ``grid_z`` (the slabs' centres, m).

    Raises
    ------
    ValueError
        Inconsistent inputs, or a cell with fewer than ``min_per_cell`` fitted images
        (the message gives every cell's count).
    """
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
    if not (isinstance(depth_slabs, int | np.integer) and depth_slabs >= 1):
        raise ValueError(f"depth_slabs must be an integer >= 1, got {depth_slabs!r}")
    if depth_axis not in (0, 1, 2):
        raise ValueError(f"depth_axis must be 0, 1 or 2, got {depth_axis!r}")
    depth = positions[:, depth_axis]
    lo, hi = np.percentile(depth, [1.0, 99.0]) if len(depth) else (0.0, 1.0)
    hi = max(hi, lo + 1e-9)
    edges_z = np.linspace(lo, hi, depth_slabs + 1)
    out = []
    for c in range(n_cams):
        otf = otfs[c]
        img = np.asarray(images[c], dtype=np.float64)
        if img.shape != otf.shape:
            raise ValueError(f"image of camera {c} has shape {img.shape}, its OTF {otf.shape}")
        seen = np.flatnonzero(np.isfinite(xy[c]).all(axis=1))
        pts = xy[c, seen]
        dist, _ = (
            cKDTree(pts).query(pts, k=2) if len(pts) > 1 else (np.full((len(pts), 2), np.inf), None)
        )
        alone = seen[dist[:, 1] > isolation]
        back = background_level(img)
        params, rms, ok = fit_spots(
            img,
            np.ascontiguousarray(xy[c, alone]),
            int(window),
            float(np.median(otf.sigma_x)),
            fit_orientation,
            50,
        )
        peak = params[:, 0] * peak_fraction(params[:, 3], params[:, 4])
        good = ok & (rms <= max_rms_noise * back.noise) & (peak >= min_snr * back.noise)
        fitted = params[good]
        edges_x = _edges(otf.grid_x)
        edges_y = _edges(otf.grid_y)
        cx = np.clip(
            np.searchsorted(edges_x, fitted[:, 1], side="right") - 1, 0, otf.grid_x.size - 1
        )
        cy = np.clip(
            np.searchsorted(edges_y, fitted[:, 2], side="right") - 1, 0, otf.grid_y.size - 1
        )
        cz = np.clip(
            np.searchsorted(edges_z, depth[alone[good]], side="right") - 1, 0, depth_slabs - 1
        )
        shape = (depth_slabs, otf.grid_y.size, otf.grid_x.size)
        counts = np.zeros(shape, dtype=np.int64)
        np.add.at(counts, (cz, cy, cx), 1)
        logger.info(
            "camera %d: %d isolated reconstructed particles fitted; per cell %s",
            c,
            int(good.sum()),
            counts.tolist(),
        )
        if counts.min() < min_per_cell:
            raise ValueError(
                f"camera {c}: too few isolated reconstructed particle images to measure the "
                f"OTF per depth slab: {int(counts.min())} in the poorest cell, {min_per_cell} "
                f"needed in each of the {shape[0]} x {shape[1]} x {shape[2]} cells (slabs x "
                f"rows x columns; counts {counts.tolist()}). Reconstruct more particles "
                "from sparse images, or ask for fewer slabs"
            )
        tables, _ = _aggregate(fitted, cz, cy, cx, shape)
        out.append(
            OpticalTransferFunction(
                shape=otf.shape,
                grid_x=otf.grid_x,
                grid_y=otf.grid_y,
                grid_z=0.5 * (edges_z[1:] + edges_z[:-1]),
                depth_axis=depth_axis,
                counts=counts,
                background=back.level,
                noise=back.noise,
                **tables,
            )
        )
    return out


def _edges(centres: np.ndarray) -> np.ndarray:
    """Cell edges around increasing centres (outer edges at ±infinity)."""
    mid = 0.5 * (centres[1:] + centres[:-1])
    return np.concatenate([[-np.inf], mid, [np.inf]])
