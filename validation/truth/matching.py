"""Measured 3-D positions scored against the truth: yield, ghost fraction, errors.

A measured point is a true positive when it lies within one voxel (the object-side
pixel) of a true particle, each point and each particle counting once: points and
particles are paired one-to-one, the closest pairs first (:func:`assign_one_to_one`). A
point left without a particle is a ghost; the yield is the fraction of the reference
particles (those imaged by enough cameras) that have a point. Calibrations from a
physical plate live in the plate's frame, which differs from the world frame by the
plate's tilt and the traverse origin (a rotation of ~0.1° and tens of µm); the measured
points are therefore brought into the world frame by the rigid transform that best fits
their nearest true particles (Kabsch, :func:`align_to_truth`) before they are scored.

``synptv run`` scores the matched points of frame a of its first snapshots
(:func:`score_matching`), and breaks the whole sheet's yield down by region of the
sheet (:mod:`validation.truth.sheet_regions`); ``synptv score`` scores any code's
positions with the same functions (:mod:`validation.score`).
"""

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ptv.box import Box, inside_box
from ptv.settings import PipelineSettings
from validation.truth.sheet_regions import SheetRegions, region_counts, region_table
from validation.truth.truth_file import TruthRun

#: Nearest-neighbour distance within which pairs enter the rigid fit, m.
_ALIGN_RADIUS = 0.5e-3


@dataclass(frozen=True)
class MatchingQuality:
    """Matching of frame a over the scored snapshots.

    Attributes
    ----------
    yield_fraction : float
        Particles in the analysis volume imaged by every camera that have a matched
        point (one-to-one, within one voxel).
    ghost_fraction : float
        Matched points in the analysis volume paired with no particle.
    sheet_yield_fraction, sheet_ghost_fraction : float
        The same over the whole lit sheet, whose wings hold dim particles that the
        detection misses more often.
    voxel : float
        The tolerance, m.
    particles : int
        Particles in the analysis volume imaged by every camera.
    matches : int
        Matched points in the analysis volume.
    rotation : ndarray, shape (3, 3)
        The fitted rigid rotation, calibration frame → world: X_world = R X + t.
    rotation_deg : float
        Its angle, degrees.
    translation : ndarray, shape (3,)
        t, m.
    regions : list of dict
        The whole sheet's yield by region (:func:`validation.truth.sheet_regions.region_table`).
    """

    yield_fraction: float
    ghost_fraction: float
    sheet_yield_fraction: float
    sheet_ghost_fraction: float
    voxel: float
    particles: int
    matches: int
    rotation: np.ndarray
    rotation_deg: float
    translation: np.ndarray
    regions: list

    def as_dict(self) -> dict:
        """JSON-able form."""
        return {
            "yield": self.yield_fraction,
            "ghost_fraction": self.ghost_fraction,
            "sheet_yield": self.sheet_yield_fraction,
            "sheet_ghost_fraction": self.sheet_ghost_fraction,
            "voxel_m": self.voxel,
            "particles": self.particles,
            "matches": self.matches,
            "frame_rotation": self.rotation.tolist(),
            "frame_rotation_deg": self.rotation_deg,
            "frame_translation_m": self.translation.tolist(),
            "sheet_regions": self.regions,
        }


def rigid_fit(source: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation R and translation t minimising Σ|R·source + t − target|² (Kabsch).

    Parameters
    ----------
    source, target : ndarray, shape (N, 3)
        Paired points, N ≥ 3, m.

    Returns
    -------
    (ndarray (3, 3), ndarray (3,))
    """
    cs, ct = source.mean(axis=0), target.mean(axis=0)
    u, _, vt = np.linalg.svd((source - cs).T @ (target - ct))
    d = np.sign(np.linalg.det(vt.T @ u.T))
    rotation = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    return rotation, ct - rotation @ cs


def rotation_angle_deg(rotation: np.ndarray) -> float:
    """The angle of a rotation matrix (3, 3), degrees."""
    return float(np.degrees(np.arccos(np.clip((np.trace(rotation) - 1) / 2, -1.0, 1.0))))


def align_to_truth(
    frames: Callable[[], Iterable[tuple[np.ndarray, np.ndarray]]],
) -> tuple[np.ndarray, np.ndarray]:
    """The rigid transform that brings measured points onto their true particles.

    Each measured point is paired with its nearest true particle within 0.5 mm, the
    pairs of every frame are fitted at once (:func:`rigid_fit`), and the fit is made
    again on the pairs the first one brings together.

    Parameters
    ----------
    frames : callable() -> iterable of (ndarray (N, 3), ndarray (P, 3))
        Gives, each time it is called, the measured points and the true particles of
        every frame scored, m, in the same order.

    Returns
    -------
    (ndarray (3, 3), ndarray (3,))
        R and t, X_world = R X + t; the identity when fewer than 3 points pair up.
    """
    rotation, translation = np.eye(3), np.zeros(3)
    for _ in range(2):  # refit once on the pairs the first fit brings together
        src, dst = [], []
        for points, particles in frames():
            if not len(points) or not len(particles):
                continue
            moved = points @ rotation.T + translation
            dist, nearest = cKDTree(particles).query(moved, distance_upper_bound=_ALIGN_RADIUS)
            ok = np.isfinite(dist)
            src.append(points[ok])
            dst.append(particles[nearest[ok]])
        if sum(len(s) for s in src) < 3:
            return np.eye(3), np.zeros(3)
        rotation, translation = rigid_fit(np.concatenate(src), np.concatenate(dst))
    return rotation, translation


def assign_one_to_one(points: np.ndarray, particles: np.ndarray, voxel: float) -> np.ndarray:
    """Pair measured points with true particles one-to-one within one voxel.

    The pairs closer than ``voxel`` are taken in order of distance (ties by point, then
    particle index), each point and each particle at most once.

    Parameters
    ----------
    points : ndarray, shape (N, 3)
        Measured points in the world frame, m.
    particles : ndarray, shape (P, 3)
        True particles, m.
    voxel : float
        Largest distance of a pair, m (inclusive).

    Returns
    -------
    ndarray of int, shape (N,)
        The particle each point is paired with, −1 for a ghost.
    """
    partner = np.full(len(points), -1, dtype=np.int64)
    if not len(points) or not len(particles):
        return partner
    pairs = cKDTree(points).sparse_distance_matrix(cKDTree(particles), voxel, output_type="ndarray")
    i, j = pairs["i"], pairs["j"]
    alone = (np.bincount(i, minlength=len(points))[i] == 1) & (
        np.bincount(j, minlength=len(particles))[j] == 1
    )
    partner[i[alone]] = j[alone]  # the usual case: a point and a particle alone together
    taken = np.zeros(len(particles), dtype=bool)
    contested = np.flatnonzero(~alone)
    for q in contested[np.lexsort((j[contested], i[contested], pairs["v"][contested]))]:
        if partner[i[q]] < 0 and not taken[j[q]]:
            partner[i[q]] = j[q]
            taken[j[q]] = True
    return partner


def reference_particles(visible: Sequence[np.ndarray], min_cameras: int) -> np.ndarray:
    """The particles a measurement should find: those imaged by at least ``min_cameras``
    cameras.

    Parameters
    ----------
    visible : sequence of C ndarray of bool, shape (P,)
        Per camera, each particle lit and on its sensor.
    min_cameras : int
        Fewest cameras.

    Returns
    -------
    ndarray of bool, shape (P,)
    """
    return np.sum(np.asarray(visible, dtype=np.int64), axis=0) >= min_cameras


@dataclass(frozen=True, eq=False)
class FrameMatch:
    """One frame's measured points paired with its true particles.

    Attributes
    ----------
    points : ndarray, shape (N, 3)
        Measured points in the world frame (aligned), m.
    partner : ndarray of int, shape (N,)
        Index of each point's particle, −1 for a ghost.
    particles : ndarray, shape (P, 3)
        True particles, m.
    reference : ndarray of bool, shape (P,)
        Particles imaged by enough cameras to be measured.
    """

    points: np.ndarray
    partner: np.ndarray
    particles: np.ndarray
    reference: np.ndarray

    @property
    def found(self) -> np.ndarray:
        """(P,) bool: particles paired with a point."""
        found = np.zeros(len(self.particles), dtype=bool)
        found[self.partner[self.partner >= 0]] = True
        return found

    def counts(self, box: Box) -> np.ndarray:
        """The counts of :func:`matching_fractions`, shape (6,): reference particles,
        those found, points and ghosts inside ``box``, then reference particles and
        those found in the whole frame (points and ghosts there: ``len(points)`` and
        ``(partner < 0).sum()``)."""
        found, particle_in = self.found, inside_box(self.particles, box)
        point_in, ghost = inside_box(self.points, box), self.partner < 0
        scored = self.reference & particle_in
        return np.array(
            [
                scored.sum(),
                (found & scored).sum(),
                point_in.sum(),
                (ghost & point_in).sum(),
                self.reference.sum(),
                (found & self.reference).sum(),
            ],
            dtype=np.int64,
        )


def match_frame(
    points: np.ndarray,
    particles: np.ndarray,
    reference: np.ndarray,
    *,
    voxel: float,
    rotation: np.ndarray,
    translation: np.ndarray,
) -> FrameMatch:
    """Bring one frame's points into the world frame and pair them with its particles.

    Parameters
    ----------
    points : ndarray, shape (N, 3)
        Measured points in their own frame, m.
    particles : ndarray, shape (P, 3)
        True particles, m.
    reference : ndarray of bool, shape (P,)
        Particles imaged by enough cameras.
    voxel : float
        Pairing distance, m.
    rotation, translation : ndarray, shapes (3, 3) and (3,)
        Own frame → world (:func:`align_to_truth`).

    Returns
    -------
    FrameMatch
    """
    moved = np.asarray(points, dtype=np.float64).reshape(-1, 3) @ rotation.T + translation
    partner = assign_one_to_one(moved, particles, voxel)
    return FrameMatch(moved, partner, particles, np.asarray(reference, dtype=bool))


def matching_fractions(counts: np.ndarray, points: int, ghosts: int) -> dict:
    """Yield and ghost fraction from summed :meth:`FrameMatch.counts`.

    Parameters
    ----------
    counts : ndarray of int, shape (6,)
        :meth:`FrameMatch.counts` summed over the frames scored.
    points, ghosts : int
        Points and ghosts over the whole frames.

    Returns
    -------
    dict
        ``yield`` and ``ghost_fraction`` in the box, ``sheet_yield`` and
        ``sheet_ghost_fraction`` over the whole frames (0 where nothing is counted),
        ``particles`` and ``matches`` (reference particles and points in the box).
    """
    scored, found, point_in, ghost_in, reference, found_all = (int(c) for c in counts)
    return {
        "yield": found / max(scored, 1),
        "ghost_fraction": ghost_in / max(point_in, 1),
        "sheet_yield": found_all / max(reference, 1),
        "sheet_ghost_fraction": ghosts / max(points, 1),
        "particles": scored,
        "matches": point_in,
    }


def score_matching(
    points: Sequence[np.ndarray],
    truth: TruthRun,
    cameras: Sequence[str],
    settings: PipelineSettings,
    *,
    voxel: float,
    regions: SheetRegions,
) -> MatchingQuality:
    """Score the matched points of frame a of the first snapshots against the truth.

    Parameters
    ----------
    points : sequence of n ndarray, shape (N_m, 3)
        Matched points of frame a of snapshots 0 … n − 1 (Δt_0), m, in the
        calibration's frame.
    truth : TruthRun
        The truth of Δt_0 holding those snapshots (``first`` = 0).
    cameras : sequence of str
        Camera names.
    settings : PipelineSettings
        Analysis volume.
    voxel : float
        Object-side pixel, m.
    regions : SheetRegions
        The regions of the sheet the whole sheet's yield is broken down by.

    Returns
    -------
    MatchingQuality
    """
    particles, imaging = [], []
    for m in range(len(points)):
        particles.append(truth.positions[m - truth.first, 0])
        visible = [truth.visible[name][m - truth.first, 0] for name in cameras]
        imaging.append(np.sum(np.asarray(visible, dtype=np.int64), axis=0))
    rotation, translation = align_to_truth(lambda: zip(points, particles, strict=True))
    counts, total, ghosts = np.zeros(6, dtype=np.int64), 0, 0
    by_region = np.zeros((len(regions.labels()), 2), dtype=np.int64)
    for p, t, seen in zip(points, particles, imaging, strict=True):
        ref = seen == len(cameras)
        frame = match_frame(p, t, ref, voxel=voxel, rotation=rotation, translation=translation)
        counts += frame.counts(settings.statistics.analysis_volume)
        total, ghosts = total + len(frame.points), ghosts + int((frame.partner < 0).sum())
        by_region += region_counts(regions, t, seen, frame.found)
    fractions = matching_fractions(counts, total, ghosts)
    return MatchingQuality(
        yield_fraction=fractions["yield"],
        ghost_fraction=fractions["ghost_fraction"],
        sheet_yield_fraction=fractions["sheet_yield"],
        sheet_ghost_fraction=fractions["sheet_ghost_fraction"],
        voxel=voxel,
        particles=fractions["particles"],
        matches=fractions["matches"],
        rotation=rotation,
        rotation_deg=rotation_angle_deg(rotation),
        translation=translation,
        regions=region_table(regions, by_region),
    )
