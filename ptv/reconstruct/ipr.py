"""Iterative particle reconstruction (IPR; Wieneke 2013, Jahn, Schanz & Schröder 2021).

Input: one image per camera, the cameras (the protocol of :mod:`ptv.camera_model`),
each camera's OTF (:mod:`ptv.reconstruct.otf`) and the measurement volume. Output: the
3-D particles, their intensities and what each iteration did.

The images, less their background level
(:func:`ptv.reconstruct.dense_background.background_level` per image unless given), are
the starting residual R_c. Each outer iteration:

1. Peaks of every residual image (:func:`ptv.reconstruct.peaks.find_peaks`) above
   max(``peak_threshold`` × a typical particle's peak, ``noise_threshold`` × noise).
2. Candidates seen in every camera
   (:func:`ptv.reconstruct.triangulation.triangulate_candidates`), later also in every
   subset of one camera fewer (see below), chosen greedily so that each peak serves at
   most ``peak_uses`` of them, smallest reprojection error first
   (:func:`ptv.reconstruct.triangulation.select_candidates`). Candidates closer than
   ``merge_distance`` to a particle or to a better candidate are dropped. A
   candidate's first intensity is the smallest over its cameras of peak value /
   (I_c × the central pixel's share of a unit spot).
3. All particles are projected exactly, with the derivatives of the mapping (one
   ``project`` call per camera), and the residual is recomputed:
   R_c = image − background − Σ_p E_p I_c g_c,p.
4. ``shake_iterations`` shaking passes (:mod:`ptv.reconstruct.shake`), the step going
   geometrically from ``shake_step`` to ``shake_step_min`` px of image motion.
5. Particles leaving the volume (beyond ``margin`` voxels), seen by fewer than
   ``min_cameras`` cameras, fainter than ``intensity_threshold`` × a typical particle,
   or much fainter in one camera than overall (the intensity one camera alone sees,
   :func:`ptv.reconstruct.shake.camera_intensities`, below ``camera_ratio`` × theirs: a
   ghost lit by other particles' light in some cameras only) are removed; particles
   closer than ``merge_distance`` voxels are merged (the brighter one kept, at the
   intensity-weighted mean position, with the summed intensity). The residual is
   recomputed, and the background level corrected by the mode of the residual (unless
   given: at high density the image's mode lies above the background).

Triangulation switches to one camera fewer once an all-camera iteration increases the
number of particles by less than ``reduce_below`` × itself (or for the last
``reduced_iterations`` of ``outer_iterations`` at the latest), and the loop stops once,
after at least two such iterations, one adds at most ``converged`` × the particles (the
number of particles alone is no test: at high density ghosts keep being replaced by
true particles while their number stays the same). ``final_shakes`` passes and a last
removal follow.

What limits it: at high density most particles need many iterations (0.12 particles
per pixel: about 40), each freeing light for the next, and with one camera fewer a
particle hidden in one camera is found once its neighbours are; the greedy choice and
the per-camera test keep the ghosts that borrow light from unfound particles few.
With a camera model (``project``) slower than about 10⁶ points/s, set
``mapping_grid`` (:class:`ptv.reconstruct.mapping.GridMapping`).
"""

import logging
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ptv.box import Box, check_box
from ptv.camera_model import CameraModel
from ptv.reconstruct._grid import point_grid
from ptv.reconstruct._spots import add_spots
from ptv.reconstruct.dense_background import background_level
from ptv.reconstruct.mapping import GridMapping, Mappings, grid_mappings, volume_voxel
from ptv.reconstruct.otf import OpticalTransferFunction, peak_fraction
from ptv.reconstruct.peaks import find_peaks
from ptv.reconstruct.shake import camera_intensities, shake_pass
from ptv.reconstruct.triangulation import (
    Candidates,
    epipolar_lengths,
    select_candidates,
    triangulate_candidates,
)
from ptv.settings import IPRSettings

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class IPRDiagnostics:
    """What each outer iteration did (arrays of one entry per outer iteration).

    Attributes
    ----------
    iterations : int
        Outer iterations run.
    peaks : ndarray of int, shape (I, C)
        Peaks found on each camera's residual.
    candidates : ndarray of int, shape (I,)
        New candidates triangulated (before dropping those at known particles).
    added : ndarray of int, shape (I,)
        Particles added.
    removed : ndarray of int, shape (I,)
        Particles removed (faint, outside, unseen).
    merged : ndarray of int, shape (I,)
        Particles merged into another.
    particles : ndarray of int, shape (I,)
        Particles after the iteration.
    residual_energy : ndarray, shape (I,)
        Σ R² / Σ (image − background)² over all cameras after the iteration.
    seconds : ndarray, shape (I,)
        Wall time of each iteration, s.
    min_cameras : ndarray of int, shape (I,)
        Cameras a new candidate needed in that iteration.
    voxel : float
        Object-space size of a pixel at the volume's centre, m.
    points_projected : int
        World points passed to the cameras' ``project`` in all.
    seconds_project : float
        Time spent in ``project``, s.
    seconds_rays : float
        Time spent in ``pixel_to_ray``, s.
    seconds_total : float
        Wall time of the whole reconstruction, s.
    mapping_fallback : int
        Points the grid mapping (``mapping_grid``) passed to the cameras themselves.
    converged : bool
        Whether the outer loop stopped by its criterion; False when it ran out of
        ``outer_iterations`` still adding particles (the reconstruction is incomplete:
        at 0.16 particles per pixel 150 iterations found 0.997 of the particles where 60
        found 0.87, docs/study.md §3).
    """

    iterations: int
    peaks: np.ndarray
    candidates: np.ndarray
    added: np.ndarray
    removed: np.ndarray
    merged: np.ndarray
    particles: np.ndarray
    residual_energy: np.ndarray
    seconds: np.ndarray
    min_cameras: np.ndarray
    voxel: float
    points_projected: int
    seconds_project: float
    seconds_rays: float
    seconds_total: float
    mapping_fallback: int = 0
    converged: bool = True


@dataclass(frozen=True, eq=False)
class Reconstruction:
    """Particles reconstructed from one set of simultaneous images.

    Attributes
    ----------
    positions : ndarray, shape (N, 3)
        Particle centres, m.
    intensities : ndarray, shape (N,)
        Intensity of each particle relative to the OTF's typical particle (about 1).
    xy : ndarray, shape (C, N, 2)
        Their images in every camera, px (NaN where not imaged).
    residuals : list of C ndarray, shape (H_c, W_c)
        Image − background − projected particles, image units.
    diagnostics : IPRDiagnostics
    """

    positions: np.ndarray
    intensities: np.ndarray
    xy: np.ndarray
    residuals: list
    diagnostics: IPRDiagnostics


class _State:
    """The particles and the residual images during the reconstruction."""

    def __init__(self, base: np.ndarray, shapes: np.ndarray, otfs, settings: IPRSettings):
        self.base = base
        self.residual = base.copy()
        self.shapes = shapes
        self.otfs = otfs
        self.settings = settings
        n_cams = base.shape[0]
        self.points = np.empty((0, 3))
        self.energy = np.empty(0)
        self.xy = np.empty((n_cams, 0, 2))
        self.jac = np.empty((n_cams, 0, 2, 3))
        self.spot = np.empty((4, n_cams, 0))  # sigma_x, sigma_y, rho, intensity

    @property
    def n(self) -> int:
        return len(self.points)

    def set_images(self, xy: np.ndarray, jac: np.ndarray | None = None) -> None:
        """New image positions (C, N, 2) (and derivatives); OTF looked up there."""
        self.xy = np.ascontiguousarray(xy)
        n_cams = xy.shape[0]
        if jac is not None:
            self.jac = np.ascontiguousarray(jac)
        spot = np.empty((4, n_cams, xy.shape[1]))
        for c in range(n_cams):
            spot[:, c] = np.stack(self.otfs[c].at(xy[c], self.points))
        spot[3] = np.where(np.isfinite(spot[3]), spot[3], 0.0)
        self.spot = spot

    def rebuild(self) -> None:
        """R = image − background − Σ_p E_p I_c g_c,p."""
        self.residual[:] = self.base
        radius = self.settings.radius_sigmas
        for c in range(self.base.shape[0]):
            rows, cols = self.shapes[c]
            sx, sy, rho, inten = self.spot[:, c]
            add_spots(
                self.residual[c],
                int(rows),
                int(cols),
                self.xy[c, :, 0],
                self.xy[c, :, 1],
                -self.energy * inten,
                sx,
                sy,
                rho,
                radius,
            )

    def keep(self, mask: np.ndarray) -> None:
        self.points = self.points[mask]
        self.energy = self.energy[mask]
        self.xy = np.ascontiguousarray(self.xy[:, mask])
        self.jac = np.ascontiguousarray(self.jac[:, mask])
        self.spot = np.ascontiguousarray(self.spot[:, :, mask])

    def rebase(self, noise: np.ndarray) -> None:
        """Correct the background level by the mode of the residual (0 if it is right).

        At high density the image's mode lies above the true background (particle light
        reaches most pixels: 4 DN too high at 0.16 particles per pixel); with the
        particles subtracted, the residual's mode is the error.
        """
        for c in range(self.base.shape[0]):
            rows, cols = self.shapes[c]
            error = background_level(self.residual[c, :rows, :cols]).level
            if abs(error) > 0.1 * noise[c]:
                self.base[c, :rows, :cols] -= error
                self.residual[c, :rows, :cols] -= error

    def residual_energy(self) -> float:
        return float(np.sum(self.residual**2) / max(np.sum(self.base**2), 1e-300))


def _check_inputs(images, cameras, otfs) -> tuple[np.ndarray, np.ndarray]:
    n = len(cameras)
    if n < 3:
        raise ValueError(
            f"iterative particle reconstruction needs at least 3 cameras, got {n} (with 2, "
            "every pair of particles on an epipolar line makes a ghost; use "
            "ptv.matching for stereo)"
        )
    if len(images) != n or len(otfs) != n:
        raise ValueError(
            f"need one image and one OTF per camera: {n} cameras, {len(images)} images, "
            f"{len(otfs)} OTFs"
        )
    shapes = np.zeros((n, 2), dtype=np.int64)
    for c, (image, otf) in enumerate(zip(images, otfs, strict=True)):
        img = np.asarray(image)
        if img.ndim != 2 or img.size == 0 or not np.issubdtype(img.dtype, np.number):
            raise ValueError(
                f"image of camera {c} must be a non-empty 2-D numeric array, got "
                f"shape {img.shape} and dtype {img.dtype}"
            )
        if not isinstance(otf, OpticalTransferFunction):
            raise ValueError(
                f"OTF of camera {c} must be an OpticalTransferFunction, got {type(otf).__name__}"
            )
        if img.shape != otf.shape:
            raise ValueError(
                f"image of camera {c} has shape {img.shape} (rows, columns), but "
                f"its OTF is for images of shape {otf.shape}"
            )
        if not np.isfinite(img).all():
            raise ValueError(f"image of camera {c} has NaN or infinite pixels")
        shapes[c] = img.shape
    return shapes, shapes.max(axis=0)


def reconstruct(
    images: Sequence[np.ndarray],
    cameras: Sequence[CameraModel],
    otfs: Sequence[OpticalTransferFunction],
    box: Box,
    *,
    settings: IPRSettings | None = None,
    background: Sequence[float] | None = None,
    initial: tuple[np.ndarray, np.ndarray] | None = None,
) -> Reconstruction:
    """Reconstruct the particles seen in one set of simultaneous images (module docstring).

    Parameters
    ----------
    images : sequence of C ndarray, shape (H_c, W_c)
        One image per camera, integers (DN) or floats.
    cameras : sequence of C CameraModel
        Their calibrations (``project`` and ``pixel_to_ray``), C >= 3; with
        ``settings.mapping_grid`` > 0 they may be the :func:`grid_mappings` of them,
        built once for many exposures.
    otfs : sequence of C OpticalTransferFunction
        Each camera's particle image model, for images of its shape.
    box : Box
        The measurement volume, (lower, upper) corners, m.
    settings : IPRSettings, optional
        Options (default: ``IPRSettings()``).
    background : sequence of C float, optional
        Background level of each image, image units (default: measured on each image).
    initial : (positions (N, 3) m, intensities (N,)), optional
        Particles known beforehand (e.g. predicted by tracks), shaken with the others.

    Returns
    -------
    Reconstruction

    Raises
    ------
    ValueError
        Fewer than 3 cameras, not one image and one OTF per camera, an image whose shape
        is not its OTF's, NaN pixels, a bad box or a volume no camera sees.
    """
    t_start = time.perf_counter()
    shapes, (rows, cols) = _check_inputs(images, cameras, otfs)
    box = check_box("box", box)
    s = IPRSettings() if settings is None else settings
    if not isinstance(s, IPRSettings):
        raise ValueError(f"settings must be IPRSettings, got {type(s).__name__}")
    n_cams = len(cameras)
    lower, upper = (np.asarray(v) for v in box)
    voxel, motion = volume_voxel(cameras, box)
    if s.mapping_grid > 0 and not all(isinstance(c, GridMapping) for c in cameras):
        cameras = grid_mappings(cameras, box, s)
    mappings = Mappings(cameras)
    if s.mapping_grid <= 0:
        _warn_if_slow(mappings, box)
    noise = np.empty(n_cams)
    base = np.zeros((n_cams, rows, cols))
    for c, image in enumerate(images):
        level = background_level(image)
        noise[c] = level.noise
        given = None if background is None else float(background[c])
        base[c, : shapes[c, 0], : shapes[c, 1]] = np.asarray(image, np.float64) - (
            level.level if given is None else given
        )
    peak_thr = np.array(
        [
            max(s.peak_threshold * otfs[c].typical_peak(), s.noise_threshold * noise[c])
            for c in range(n_cams)
        ]
    )
    lengths = epipolar_lengths(mappings, box)
    logger.info(
        "IPR: %d cameras, voxel %.1f µm, epipolar segments %s px, peak thresholds %s",
        n_cams,
        voxel * 1e6,
        np.round(lengths, 1).tolist(),
        np.round(peak_thr, 1).tolist(),
    )
    state = _State(base, shapes, otfs, s)
    if initial is not None:
        pos, inten = (np.asarray(v, dtype=np.float64) for v in initial)
        if pos.ndim != 2 or pos.shape[1] != 3 or inten.shape != (len(pos),):
            raise ValueError(
                f"initial must be positions (N, 3) and intensities (N,), got "
                f"{pos.shape} and {inten.shape}"
            )
        state.points, state.energy = pos.copy(), inten.copy()
    diff_step = 0.5 * voxel
    margin_box = (lower - s.margin * voxel, upper + s.margin * voxel)
    merge = s.merge_distance * voxel
    rec = {
        k: []
        for k in (
            "peaks",
            "candidates",
            "added",
            "removed",
            "merged",
            "particles",
            "energy",
            "seconds",
            "min_cameras",
        )
    }
    if state.n:
        _project(state, mappings, diff_step)
        state.rebuild()
    iterations = 0
    reduced = False
    reduced_done = 0
    for it in range(s.outer_iterations):
        t_it = time.perf_counter()
        reduced = reduced or it >= s.outer_iterations - s.reduced_iterations
        subsets = [list(range(n_cams))]
        if reduced and n_cams > 3:
            subsets += [[c for c in range(n_cams) if c != k] for k in range(n_cams)]
        # 1-2: peaks and candidates
        peaks, values = [], []
        for c in range(n_cams):
            xy, v = find_peaks(state.residual[c], threshold=peak_thr[c], shape=tuple(shapes[c]))
            peaks.append(xy)
            values.append(v)
        grids = [point_grid(p, tuple(shapes[c])) for c, p in enumerate(peaks)]
        rays = [mappings.rays(c, p) for c, p in enumerate(peaks)]
        ramp = min(1.0, it / s.tolerance_ramp) if s.tolerance_ramp > 0 else 1.0
        tolerance = s.tolerance_start + (s.tolerance - s.tolerance_start) * ramp
        found = [
            triangulate_candidates(
                mappings,
                peaks,
                grids,
                rays,
                box,
                subset=sub,
                tolerance=tolerance,
                lengths=lengths,
                samples=s.epipolar_samples,
            )
            for sub in subsets
        ]
        n_cand = sum(len(f) for f in found)
        new_pts, new_e = _new_particles(found, values, state, merge)
        state.points = np.concatenate([state.points, new_pts])
        state.energy = np.concatenate([state.energy, new_e])
        # 3-4: project, residual, shake
        _project(state, mappings, diff_step)
        state.rebuild()
        seen = _shake(state, s.shake_iterations, motion)
        # 5: removal and merging
        removed, merged = _prune(state, seen, margin_box, merge)
        if background is None and state.n:
            state.rebase(noise)
        iterations += 1
        for key, value in (
            ("peaks", [len(p) for p in peaks]),
            ("candidates", n_cand),
            ("added", len(new_pts)),
            ("removed", removed),
            ("merged", merged),
            ("particles", state.n),
            ("energy", state.residual_energy()),
            ("seconds", time.perf_counter() - t_it),
            ("min_cameras", n_cams - 1 if len(subsets) > 1 else n_cams),
        ):
            rec[key].append(value)
        logger.info(
            "IPR iteration %d: peaks %s, candidates %d, added %d, removed %d, merged %d, "
            "particles %d, residual energy %.4f, %.2f s",
            it,
            rec["peaks"][-1],
            n_cand,
            len(new_pts),
            removed,
            merged,
            state.n,
            rec["energy"][-1],
            rec["seconds"][-1],
        )
        growth = state.n - (rec["particles"][-2] if len(rec["particles"]) > 1 else 0)
        if reduced:
            reduced_done += 1
            if reduced_done >= 2 and len(new_pts) <= s.converged * max(state.n, 1):
                converged = True
                break
        elif growth < s.reduce_below * max(state.n, 1):
            reduced = True
    else:
        converged = iterations == 0
    if s.final_shakes and state.n:
        _project(state, mappings, diff_step)
        state.rebuild()
        seen = _shake(state, s.final_shakes, motion)
        _prune(state, seen, margin_box, merge)
    if state.n:
        _project(state, mappings, diff_step)
    state.rebuild()
    mappings.log_cost()
    diagnostics = IPRDiagnostics(
        iterations=iterations,
        peaks=np.array(rec["peaks"], dtype=np.int64).reshape(-1, n_cams),
        candidates=np.array(rec["candidates"], dtype=np.int64),
        added=np.array(rec["added"], dtype=np.int64),
        removed=np.array(rec["removed"], dtype=np.int64),
        merged=np.array(rec["merged"], dtype=np.int64),
        particles=np.array(rec["particles"], dtype=np.int64),
        residual_energy=np.array(rec["energy"]),
        seconds=np.array(rec["seconds"]),
        min_cameras=np.array(rec["min_cameras"], dtype=np.int64),
        voxel=voxel,
        points_projected=mappings.points_projected,
        seconds_project=mappings.seconds_project,
        seconds_rays=mappings.seconds_rays,
        seconds_total=time.perf_counter() - t_start,
        mapping_fallback=int(sum(getattr(c, "fallback", 0) for c in mappings.cameras)),
        converged=converged,
    )
    residuals = [state.residual[c, : shapes[c, 0], : shapes[c, 1]].copy() for c in range(n_cams)]
    return Reconstruction(
        positions=state.points.copy(),
        intensities=state.energy.copy(),
        xy=state.xy.copy(),
        residuals=residuals,
        diagnostics=diagnostics,
    )


def _warn_if_slow(mappings: Mappings, box: Box) -> None:
    """Log a warning when a camera's ``project`` is too slow for direct use."""
    lower, upper = (np.asarray(v) for v in box)
    pts = lower + (upper - lower) * np.random.default_rng(0).random((2000, 3))
    for c in range(len(mappings)):
        t0 = time.perf_counter()
        mappings.project(c, pts)
        rate = len(pts) / max(time.perf_counter() - t0, 1e-9)
        if rate < 2e5:
            logger.warning(
                "camera %d projects only %.3g points/s; reconstruction projects millions: "
                "set IPRSettings.mapping_grid (e.g. 32 voxels) to interpolate it",
                c,
                rate,
            )


def _steps(s: IPRSettings, n: int) -> np.ndarray:
    """Step of each of n shaking passes, px (geometric from shake_step to shake_step_min)."""
    if n <= 1:
        return np.array([s.shake_step])
    return s.shake_step * (s.shake_step_min / s.shake_step) ** (np.arange(n) / (n - 1))


def _project(state: _State, mappings: Mappings, step: float) -> None:
    """Exact images and derivatives of every particle, one call per camera."""
    n_cams = len(mappings)
    xy = np.empty((n_cams, state.n, 2))
    jac = np.empty((n_cams, state.n, 2, 3))
    for c in range(n_cams):
        xy[c], jac[c] = mappings.project_with_jacobian(c, state.points, step)
    state.set_images(xy, jac)


def _shake(state: _State, passes: int, motion: np.ndarray) -> np.ndarray:
    """``passes`` shaking passes; the number of cameras seeing each particle."""
    steps_px = _steps(state.settings, passes)
    seen = np.isfinite(state.xy).all(axis=2).sum(axis=0)
    if passes == 0 or state.n == 0:
        return seen
    active = np.ones(state.n, dtype=bool)
    sx, sy, rho, inten = (np.ascontiguousarray(a) for a in state.spot)
    for k in range(passes):
        steps = steps_px[min(k, len(steps_px) - 1)] / motion
        seen, _ = shake_pass(
            state.residual,
            state.shapes,
            state.points,
            state.energy,
            state.xy,
            state.jac,
            sx,
            sy,
            rho,
            inten,
            steps,
            active,
            state.settings.radius_sigmas,
            1,
            True,
        )
    return seen


def _new_particles(
    found: list[Candidates], values: list[np.ndarray], state: _State, merge: float
) -> tuple[np.ndarray, np.ndarray]:
    """New particles among the candidates, and their first intensity.

    The candidates are chosen greedily (:func:`select_candidates`); those at a known
    particle or at a better chosen candidate (``merge_distance``) are dropped. The
    first intensity is the least over the cameras of the peak's value / (I_c × the
    central pixel's share of a unit spot).
    """
    s = state.settings
    found = [f for f in found if len(f)]
    if not found:
        return np.empty((0, 3)), np.empty(0)
    every = Candidates(
        points=np.concatenate([f.points for f in found]),
        peaks=np.concatenate([f.peaks for f in found]),
        xy=np.concatenate([f.xy for f in found], axis=1),
        error=np.concatenate([f.error for f in found]),
        rms=np.concatenate([f.rms for f in found]),
    )
    keep = select_candidates(every, [len(v) for v in values], max_uses=s.peak_uses)
    points, ids, xy = every.points, every.peaks, every.xy
    if state.n and merge > 0:
        d, _ = cKDTree(state.points).query(points, distance_upper_bound=merge)
        keep &= ~np.isfinite(d)
    if merge > 0 and keep.sum() > 1:
        idx = np.flatnonzero(keep)
        order = idx[np.argsort(every.rms[idx], kind="stable")]
        tree = cKDTree(points[order])
        taken = np.zeros(len(order), dtype=bool)
        chosen = np.zeros(len(order), dtype=bool)
        for i, nbrs in enumerate(tree.query_ball_point(points[order], merge)):
            if taken[i]:
                continue
            chosen[i] = True
            taken[nbrs] = True
        keep[:] = False
        keep[order[chosen]] = True
    points, ids, xy = points[keep], ids[keep], xy[:, keep]
    energy = np.full(len(points), np.inf)
    for c, otf in enumerate(state.otfs):
        used = ids[:, c] >= 0
        if not used.any():
            continue
        sx, sy, _, inten = otf.at(xy[c, used], points[used])
        peak = inten * peak_fraction(sx, sy)
        e = values[c][ids[used, c]] / np.where(peak > 0, peak, np.inf)
        energy[used] = np.minimum(energy[used], e)
    energy = np.where(np.isfinite(energy), np.maximum(energy, 0.0), 0.0)
    return points, energy


def _prune(state: _State, seen: np.ndarray, box: tuple, merge: float) -> tuple[int, int]:
    """Remove faint, outside and unseen particles, merge close ones; rebuild the residual."""
    s = state.settings
    if state.n == 0:
        return 0, 0
    lower, upper = box
    inside = np.all((state.points >= lower) & (state.points <= upper), axis=1)
    bright = state.energy > s.intensity_threshold
    keep = inside & (seen >= s.min_cameras) & bright & np.isfinite(state.points).all(axis=1)
    if s.camera_ratio > 0 and state.n:
        sx, sy, rho, inten = (np.ascontiguousarray(a) for a in state.spot)
        per_camera = camera_intensities(
            state.residual,
            state.shapes,
            state.energy,
            state.xy,
            sx,
            sy,
            rho,
            inten,
            s.radius_sigmas,
        )
        with np.errstate(invalid="ignore", divide="ignore"):
            ratio = np.nanmin(np.where(np.isfinite(per_camera), per_camera, np.inf), axis=0)
            ratio = ratio / state.energy
        keep &= ~(ratio < s.camera_ratio)
    removed = int((~keep).sum())
    state.keep(keep)
    merged = 0
    if merge > 0 and state.n > 1:
        pairs = cKDTree(state.points).query_pairs(merge, output_type="ndarray")
        if len(pairs):
            order = np.argsort(-state.energy, kind="stable")
            rank = np.empty_like(order)
            rank[order] = np.arange(len(order))
            alive = np.ones(state.n, dtype=bool)
            # brighter first: each absorbs its still-alive neighbours
            nbrs: dict[int, list[int]] = {}
            for a, b in pairs:
                nbrs.setdefault(int(a), []).append(int(b))
                nbrs.setdefault(int(b), []).append(int(a))
            for p in sorted(nbrs, key=lambda q: rank[q]):
                if not alive[p]:
                    continue
                group = [q for q in nbrs[p] if alive[q]]
                if not group:
                    continue
                members = [p, *group]
                w = state.energy[members]
                total = float(w.sum())
                if total > 0:
                    state.points[p] = (w[:, None] * state.points[members]).sum(0) / total
                    state.xy[:, p] = (w[None, :, None] * state.xy[:, members]).sum(1) / total
                state.energy[p] = total
                alive[group] = False
                merged += len(group)
            state.keep(alive)
            state.set_images(state.xy)
    state.rebuild()
    return removed, merged
