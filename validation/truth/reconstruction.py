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

Where the scores change, as the Challenge's reports show them: ``by_depth`` (the
volume's depth cut into :data:`DEPTH_SLABS` equal slabs: found, position errors and the
ghosts among the points there), ``by_neighbour`` (the particles grouped by the distance
from their image to the nearest other particle's image, the least over the cameras,
edges :data:`NEIGHBOUR_EDGES_PX`: overlap is what limits a reconstruction), and the
displacement error between the two frames of each pair: (b − a) of a particle found in
both against its true displacement, rms, µm.
"""

from collections.abc import Sequence
from dataclasses import dataclass
from itertools import pairwise

import numpy as np
from scipy.spatial import cKDTree

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
    displacement_rms_um : float
        (b − a) of the particles found in both frames of a pair against their true
        displacement, rms of the 3-D difference, µm (nan without such a particle).
    displacement_pairs : int
        Those particles, over the pairs.
    by_depth : list of dict
        Per depth slab (module docstring): ``z_mm`` (lower, upper), ``particles``,
        ``found``, ``rms_um``, ``rms_px``, ``points``, ``ghosts``.
    by_neighbour : list of dict
        Per nearest-image distance class: ``distance_px`` (lower, upper),
        ``particles``, ``found``, ``rms_um``, ``rms_px``.
    """

    found: float
    ghosts: float
    rms_um: float
    rms_px: float
    particles: int
    points: int
    exposures: int
    ppp: float
    displacement_rms_um: float = np.nan
    displacement_pairs: int = 0
    by_depth: tuple = ()
    by_neighbour: tuple = ()

    def as_dict(self) -> dict:
        """JSON-able form (nan as None)."""
        return {k: _json_value(v) for k, v in self.__dict__.items()}


#: Depth slabs of :attr:`ReconstructionScore.by_depth`.
DEPTH_SLABS = 5
#: Edges of the nearest-image distance classes of :attr:`ReconstructionScore.by_neighbour`,
#: px: overlapping (under about 2σ of a particle image), touching, apart.
NEIGHBOUR_EDGES_PX = (0.0, 1.0, 2.0, 3.0, 5.0, np.inf)


def _json_value(value):
    """nan → None, in lists, tuples and dicts too."""
    if isinstance(value, float):
        return value if np.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _json_value(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_value(v) for v in value]
    return value


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
    rows = {"z": [], "neighbour": [], "found": [], "err_um": [], "err_px": []}
    ghost_z, point_z = [], []
    partners = {}
    for (k, m, frame), p in sorted(points.items()):
        run = runs[max(k, 0)]
        row, column = m - run.first, "ab".index(frame)
        particles = run.positions[row, column]
        visible = np.array([run.visible[c][row, column] for c in cameras])
        imaged += int(visible.sum())
        reference = visible.all(axis=0)
        moved = np.asarray(p, dtype=np.float64).reshape(-1, 3) @ rotation.T + translation
        partner = assign_one_to_one(moved, particles, voxel)
        partners[k, m, frame] = (moved, partner)
        hit = partner >= 0
        found = np.zeros(len(particles), dtype=bool)
        found[partner[hit]] = True
        reference_total += int(reference.sum())
        found_total += int((found & reference).sum())
        points_total += len(moved)
        ghosts_total += int((~hit).sum())
        err_m.append(moved[hit] - particles[partner[hit]])
        point_z.append(moved[:, 2])
        ghost_z.append(moved[~hit, 2])
        per_particle_m = np.full(len(particles), np.nan)
        per_particle_m[partner[hit]] = np.linalg.norm(err_m[-1], axis=1)
        per_particle_px = np.zeros(len(particles))
        nearest = np.full(len(particles), np.inf)
        for c, camera in enumerate(true_cameras):
            xy = run.xy[cameras[c]][row, column].astype(np.float64)
            exact = xy[partner[hit]]
            d2 = np.sum((camera.project(moved[hit]) - exact) ** 2, axis=1)
            err_px.append(d2)
            per_particle_px[partner[hit]] += np.where(np.isfinite(d2), d2, np.nan)
            nearest = np.minimum(nearest, _nearest_other_image(xy, visible[c]))
        rows["z"].append(particles[reference, 2])
        rows["neighbour"].append(nearest[reference])
        rows["found"].append(found[reference])
        rows["err_um"].append(per_particle_m[reference] * 1e6)
        rows["err_px"].append(np.sqrt(per_particle_px[reference] / len(true_cameras)))
    d3 = np.concatenate(err_m) if err_m else np.empty((0, 3))
    d2 = np.concatenate(err_px) if err_px else np.empty(0)
    d2 = d2[np.isfinite(d2)]
    exposures = len(points)
    per = {key: np.concatenate(v) if v else np.empty(0) for key, v in rows.items()}
    displacement = _displacement_errors(partners, runs)
    return ReconstructionScore(
        found=found_total / max(reference_total, 1),
        ghosts=ghosts_total / max(points_total, 1),
        rms_um=float(np.sqrt(np.mean(np.sum(d3**2, axis=1)))) * 1e6 if len(d3) else np.nan,
        rms_px=float(np.sqrt(np.mean(d2))) if len(d2) else np.nan,
        particles=reference_total,
        points=points_total,
        exposures=exposures,
        ppp=imaged / max(exposures * len(cameras) * sensor_pixels, 1),
        displacement_rms_um=_rms(displacement) * 1e6,
        displacement_pairs=len(displacement),
        by_depth=_by_depth(
            per, np.concatenate(point_z or [np.empty(0)]), np.concatenate(ghost_z or [np.empty(0)])
        ),
        by_neighbour=_by_neighbour(per),
    )


def _nearest_other_image(xy: np.ndarray, visible: np.ndarray) -> np.ndarray:
    """Distance from each particle's image to the nearest other visible particle's
    image in one camera, px (inf where the particle is not visible or alone)."""
    out = np.full(len(xy), np.inf)
    seen = np.flatnonzero(visible & np.isfinite(xy).all(axis=1))
    if len(seen) > 1:
        d, _ = cKDTree(xy[seen]).query(xy[seen], k=2)
        out[seen] = d[:, 1]
    return out


def _displacement_errors(partners: dict, runs: Sequence[TruthRun]) -> np.ndarray:
    """(b − a) of the particles found in both frames of each pair against their true
    displacement, norm of the 3-D difference, m, shape (n,).

    ``partners`` maps each exposure (k, m, frame) to its aligned points (N, 3) and each
    point's particle (N,), −1 for a ghost; a shared frame a is (−1, m, "a")."""
    errors = []
    for (k, m, frame), (moved_b, partner_b) in partners.items():
        first = partners.get((k, m, "a"), partners.get((-1, m, "a")))
        if frame != "b" or first is None:
            continue
        moved_a, partner_a = first
        run = runs[k]
        truth = run.positions[m - run.first]  # (2, P, 3): the same particles in a and b
        point_a = np.full(truth.shape[1], -1)
        point_b = np.full(truth.shape[1], -1)
        point_a[partner_a[partner_a >= 0]] = np.flatnonzero(partner_a >= 0)
        point_b[partner_b[partner_b >= 0]] = np.flatnonzero(partner_b >= 0)
        both = np.flatnonzero((point_a >= 0) & (point_b >= 0))
        measured = moved_b[point_b[both]] - moved_a[point_a[both]]
        errors.append(np.linalg.norm(measured - (truth[1, both] - truth[0, both]), axis=1))
    return np.concatenate(errors) if errors else np.empty(0)


def _rms(values: np.ndarray) -> float:
    """Root mean square of the finite values (nan without one)."""
    values = values[np.isfinite(values)]
    return float(np.sqrt(np.mean(values**2))) if len(values) else np.nan


def _scores(per: dict, select: np.ndarray) -> dict:
    """particles, found, rms_um, rms_px of the reference particles ``select``."""
    found = per["found"][select]
    return {
        "particles": int(select.sum()),
        "found": float(found.mean()) if len(found) else np.nan,
        "rms_um": _rms(per["err_um"][select & per["found"]]),
        "rms_px": _rms(per["err_px"][select & per["found"]]),
    }


def _by_depth(per: dict, point_z: np.ndarray, ghost_z: np.ndarray) -> tuple:
    """The scores per depth slab of the reference particles' range."""
    if not len(per["z"]):
        return ()
    edges = np.linspace(per["z"].min(), per["z"].max(), DEPTH_SLABS + 1)
    table = []
    for lo, hi in pairwise(edges):
        inside = (per["z"] >= lo) & (per["z"] <= hi)
        points = int(np.sum((point_z >= lo) & (point_z <= hi)))
        ghosts = int(np.sum((ghost_z >= lo) & (ghost_z <= hi)))
        table.append(
            {
                "z_mm": [lo * 1e3, hi * 1e3],
                **_scores(per, inside),
                "points": points,
                "ghosts": ghosts / points if points else np.nan,
            }
        )
    return tuple(table)


def _by_neighbour(per: dict) -> tuple:
    """The scores per class of the nearest other image's distance."""
    edges = NEIGHBOUR_EDGES_PX
    return tuple(
        {
            "distance_px": [lo, hi],
            **_scores(per, (per["neighbour"] >= lo) & (per["neighbour"] < hi)),
        }
        for lo, hi in pairwise(edges)
    )
