"""Reconstructed particles scored against the truth, as the LPT Challenge scores them.

Every exposure of a run's reconstruction (frame a and frame b of each Δt) is compared
with the particles it images: a reconstructed particle is found when it lies within
one voxel (the object-side pixel) of a true particle, one to one
(:func:`validation.truth.matching.assign_one_to_one`, the Euclidean distance: stricter
than the Challenge's one voxel on each axis). ``found`` is the fraction of the particles
lit and on every camera's sensor that have a point, ``ghosts`` the fraction of the
points that have no particle; the position error is the rms over the found particles of
the 3-D distance (µm) and of the distance between the found point's image through the
true cameras and the particle's exact image (px, rms over the cameras), the projected
error the Challenge gives. Points from a fitted calibration are first brought into the
world frame by the rigid transform the matching score fitted (the plate's frame differs
from the world by its tilt and the traverse's origin).
"""

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from validation.truth.matching import assign_one_to_one
from validation.truth.truth_file import TruthRun


@dataclass(frozen=True)
class ReconstructionScore:
    """What :func:`score_reconstruction` gives.

    Attributes
    ----------
    found : float
        Reference particles with a point.
    ghosts : float
        Points with no particle.
    rms_um : float
        3-D position error of the found particles, rms, µm (nan when none is found).
    rms_px : float
        Projected position error, rms over the found particles and the cameras, px.
    particles : int
        Reference particles over the exposures scored.
    points : int
        Points over the exposures scored.
    exposures : int
        Exposures scored.
    ppp : float
        Particles imaged per pixel, mean over the cameras and the exposures.
    """

    found: float
    ghosts: float
    rms_um: float
    rms_px: float
    particles: int
    points: int
    exposures: int
    ppp: float

    def as_dict(self) -> dict:
        """JSON-able form (nan as None)."""
        return {
            k: (None if isinstance(v, float) and not np.isfinite(v) else v)
            for k, v in self.__dict__.items()
        }


def score_reconstruction(
    points: dict,
    runs: Sequence[TruthRun],
    cameras: Sequence[str],
    true_cameras: Sequence,
    *,
    voxel: float,
    sensor_pixels: float,
    rotation: np.ndarray,
    translation: np.ndarray,
) -> ReconstructionScore:
    """Score every exposure's points (module docstring).

    Parameters
    ----------
    points : dict of (int, int, str) to ndarray, shape (N, 3)
        Per exposure (k, m, frame), k = −1 for a shared frame a (then scored against
        Δt_0's frame a): the points, m, in the calibration's frame.
    runs : sequence of K TruthRun
        The truth of every Δt over the snapshots of ``points``.
    cameras : sequence of str
        Camera names.
    true_cameras : sequence of C camera models
        The true cameras (``project``), in the order of ``cameras``.
    voxel : float
        Pairing distance, m.
    sensor_pixels : float
        Pixels of one sensor (for ``ppp``).
    rotation, translation : ndarray, shapes (3, 3) and (3,)
        Calibration frame → world.

    Returns
    -------
    ReconstructionScore
    """
    reference_total = found_total = points_total = ghosts_total = imaged = 0
    err_m, err_px = [], []
    for (k, m, frame), p in sorted(points.items()):
        run = runs[max(k, 0)]
        row, column = m - run.first, "ab".index(frame)
        particles = run.positions[row, column]
        visible = np.array([run.visible[c][row, column] for c in cameras])
        imaged += int(visible.sum())
        reference = visible.all(axis=0)
        moved = np.asarray(p, dtype=np.float64).reshape(-1, 3) @ rotation.T + translation
        partner = assign_one_to_one(moved, particles, voxel)
        hit = partner >= 0
        found = np.zeros(len(particles), dtype=bool)
        found[partner[hit]] = True
        reference_total += int(reference.sum())
        found_total += int((found & reference).sum())
        points_total += len(moved)
        ghosts_total += int((~hit).sum())
        err_m.append(moved[hit] - particles[partner[hit]])
        for c, camera in enumerate(true_cameras):
            exact = run.xy[cameras[c]][row, column][partner[hit]].astype(np.float64)
            err_px.append(np.sum((camera.project(moved[hit]) - exact) ** 2, axis=1))
    d3 = np.concatenate(err_m) if err_m else np.empty((0, 3))
    d2 = np.concatenate(err_px) if err_px else np.empty(0)
    d2 = d2[np.isfinite(d2)]
    exposures = len(points)
    return ReconstructionScore(
        found=found_total / max(reference_total, 1),
        ghosts=ghosts_total / max(points_total, 1),
        rms_um=float(np.sqrt(np.mean(np.sum(d3**2, axis=1)))) * 1e6 if len(d3) else np.nan,
        rms_px=float(np.sqrt(np.mean(d2))) if len(d2) else np.nan,
        particles=reference_total,
        points=points_total,
        exposures=exposures,
        ppp=imaged / max(exposures * len(cameras) * sensor_pixels, 1),
    )
