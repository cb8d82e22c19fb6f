"""Stereo matching scored against the truth: yield and ghost fraction.

A matched point is a true positive when it lies within one voxel (the object-side
pixel) of a true particle. Calibrations from a physical plate live in the plate's
frame, which differs from the world frame by the plate's tilt and the traverse origin
(a rotation of ~0.1° and tens of µm); the matched points are therefore brought into the
world frame by the rigid transform that best fits their nearest true particles
(Kabsch) before they are scored.
"""

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ptv.box import inside_box
from ptv.pipeline import PipelineSettings
from validation.dataset.truth_file import TruthRun

#: Nearest-neighbour distance within which pairs enter the rigid fit, m.
_ALIGN_RADIUS = 0.5e-3


@dataclass(frozen=True)
class MatchingQuality:
    """Matching of frame a over the scored snapshots.

    Attributes
    ----------
    yield_fraction : float
        Particles in the analysis volume imaged by every camera that have a matched
        point within one voxel.
    ghost_fraction : float
        Matched points in the analysis volume within one voxel of no particle.
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
        }


def _fraction(selected: np.ndarray, among: np.ndarray) -> float:
    """Fraction of the ``among`` entries that are ``selected`` (0 if there are none)."""
    return float(np.sum(selected & among) / max(int(among.sum()), 1))


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


def score_matching(
    points: Sequence[np.ndarray],
    truth: TruthRun,
    cameras: Sequence[str],
    settings: PipelineSettings,
    *,
    voxel: float,
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
        Camera names (a particle counts when every camera images it).
    settings : PipelineSettings
        Analysis volume.
    voxel : float
        Object-side pixel, m.

    Returns
    -------
    MatchingQuality
    """
    particles, measurable = [], []
    for m in range(len(points)):
        particles.append(truth.positions[m - truth.first, 0])
        measurable.append(
            np.all([truth.visible[name][m - truth.first, 0] for name in cameras], axis=0)
        )
    rotation, translation = np.eye(3), np.zeros(3)
    for _ in range(2):  # refit once on the pairs the first fit brings together
        src, dst = [], []
        for p, t in zip(points, particles, strict=True):
            moved = p @ rotation.T + translation
            dist, nearest = cKDTree(t).query(moved, distance_upper_bound=_ALIGN_RADIUS)
            ok = np.isfinite(dist)
            src.append(p[ok])
            dst.append(t[nearest[ok]])
        rotation, translation = rigid_fit(np.concatenate(src), np.concatenate(dst))
    box = settings.statistics.analysis_volume
    found, measured, particle_in, ghost, point_in = [], [], [], [], []
    for p, t, m in zip(points, particles, measurable, strict=True):
        moved = p @ rotation.T + translation
        ghost.append(cKDTree(t).query(moved)[0] > voxel)
        point_in.append(inside_box(moved, box))
        hit = np.zeros(len(t), dtype=bool)
        if len(p):
            hit[m] = cKDTree(moved).query(t[m])[0] <= voxel
        found.append(hit)
        measured.append(m)
        particle_in.append(inside_box(t, box))
    found, measured, particle_in, ghost, point_in = (
        np.concatenate(v) for v in (found, measured, particle_in, ghost, point_in)
    )
    scored = measured & particle_in
    angle = np.degrees(np.arccos(np.clip((np.trace(rotation) - 1) / 2, -1.0, 1.0)))
    return MatchingQuality(
        yield_fraction=_fraction(found, scored),
        ghost_fraction=_fraction(ghost, point_in),
        sheet_yield_fraction=_fraction(found, measured),
        sheet_ghost_fraction=_fraction(ghost, np.ones_like(ghost)),
        voxel=voxel,
        particles=int(scored.sum()),
        matches=int(point_in.sum()),
        rotation=rotation,
        rotation_deg=float(angle),
        translation=translation,
    )
