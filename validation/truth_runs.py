"""Reference measurements of a rendered dataset that use the truth: the error budget's rungs.

- :func:`exact_runs`: the true positions at t and t + Δt of every particle (no camera at
  all): what is left is the multi-Δt method's own error (finite Δt, sampling).
- :func:`detected_runs`: the detected centres on the images, each paired with the
  particle that made it (so no matching error), triangulated with the true cameras (so
  no calibration error): what is added is the detection error. It also measures the
  detection error in pixels, the detection yield, the fractional-position histogram
  and the position noise in 3-D.

Both return :class:`ptv.stats.links.RunParticles`, so the same statistics run on them as
on the PTV stack's own links.
"""

import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import reduce
from pathlib import Path

import h5py
import numpy as np
from scipy.spatial import cKDTree

from ptv.camera_model import CameraModel
from ptv.frames import FrameDetections
from ptv.pipeline import PipelineSettings
from ptv.stats.links import RunParticles, inside_box
from ptv.triangulate import triangulate
from simulator.rigs import Rig, rig_from_dict

#: Largest distance between a detection and the true image of its particle, px.
ASSOCIATION_RADIUS = 1.0


@dataclass(frozen=True)
class TruthRun:
    """The truth of the run at one Δt (``/particles/dt<k>`` of truth.h5).

    Attributes
    ----------
    dt : float
        s.
    positions : ndarray, shape (M, 2, P, 3)
        Particle positions at t and t + Δt, m.
    velocity : ndarray, shape (M, P, 3)
        Velocities at t, m/s.
    xy : dict of str to ndarray, shape (M, 2, P, 2)
        Exact image of every particle per camera, px.
    visible : dict of str to ndarray of bool, shape (M, 2, P)
        Particle lit and its spot on the sensor.
    """

    dt: float
    positions: np.ndarray
    velocity: np.ndarray
    xy: dict
    visible: dict


def read_truth(folder: Path) -> tuple[Rig, list[TruthRun]]:
    """The rig and the particle truth of a dataset written by ``synptv render``."""
    path = Path(folder) / "truth.h5"
    if not path.is_file():
        raise ValueError(f"{folder} has no truth.h5: reference runs need a synthetic dataset")
    with h5py.File(path) as truth:
        rig = rig_from_dict(json.loads(truth.attrs["rig"]), source=str(path))
        runs = []
        for k in range(len(truth["particles"])):
            g = truth[f"particles/dt{k}"]
            runs.append(
                TruthRun(
                    dt=float(g.attrs["dt"]),
                    positions=g["positions"][:],
                    velocity=g["velocity"][:],
                    xy={name: g[f"{name}/xy"][:] for name in rig.camera_names},
                    visible={name: g[f"{name}/visible"][:] for name in rig.camera_names},
                )
            )
    return rig, runs


def _run_particles(
    k: int,
    dt: float,
    per_snapshot: Sequence[tuple[np.ndarray, np.ndarray]],
    settings: PipelineSettings,
    n_cam: int,
) -> RunParticles:
    """RunParticles from (X(t), X(t + Δt)) per snapshot; no outliers by construction.

    Detections and matches per snapshot are recorded as the number of particles used.
    """
    x = [a for a, _ in per_snapshot]
    d = [b - a for a, b in per_snapshot]
    sizes = np.array([len(a) for a in x], dtype=np.int64)
    positions = np.concatenate(x) if x else np.empty((0, 3))
    m = len(per_snapshot)
    return RunParticles(
        k=k,
        dt=dt,
        positions=positions,
        displacements=np.concatenate(d) if d else np.empty((0, 3)),
        offsets=np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64),
        snapshot_ids=np.arange(m, dtype=np.int64),
        detections=np.broadcast_to(sizes[:, None, None], (m, 2, n_cam)).copy(),
        matches=np.repeat(sizes[:, None], 2, axis=1),
        links=sizes,
        processed=np.arange(m, dtype=np.int64),
        in_analysis=inside_box(positions, settings.statistics.analysis_volume),
        outlier=np.zeros(len(positions), dtype=bool),
    )


def exact_runs(truth: Sequence[TruthRun], settings: PipelineSettings) -> list[RunParticles]:
    """The true positions of every particle at t and t + Δt, per Δt."""
    return [
        _run_particles(k, run.dt, [(p[0], p[1]) for p in run.positions], settings, len(run.xy))
        for k, run in enumerate(truth)
    ]


@dataclass(frozen=True)
class DetectionQuality:
    """Detection measured against the exact particle images, per camera.

    Attributes
    ----------
    cameras : tuple of str
        Camera names.
    rms_error_px : ndarray, shape (C, 2)
        RMS of detected − exact centre (x, y) over associated particles, px.
    found : ndarray, shape (C,)
        Fraction of the visible particles with a detection within
        :data:`ASSOCIATION_RADIUS`.
    spurious : ndarray, shape (C,)
        Fraction of detections associated with no particle.
    detected_xy : dict of str to ndarray, shape (N, 2)
        Detected positions of the associated particles, px (for the peak-locking test).
    dt : ndarray, shape (K,)
        The time separations, s.
    position_noise : ndarray, shape (3,)
        RMS of triangulated − true position per component (true cameras), m, over the
        particles whose true X(t) lies in the analysis volume (those the statistics use;
        the dim ones in the sheet's wings are noisier).
    displacement_noise : ndarray, shape (K, 3)
        RMS of measured − true ΔX per Δt and component, m, same particles (√2 × the
        position noise when the noise at t and t + Δt is independent; less, and growing
        with Δt, when part of the error, such as a neighbour's overlapping image, is
        common to both frames).
    """

    cameras: tuple[str, ...]
    rms_error_px: np.ndarray
    found: np.ndarray
    spurious: np.ndarray
    detected_xy: dict
    dt: np.ndarray
    position_noise: np.ndarray
    displacement_noise: np.ndarray


def _associate(detected: np.ndarray, exact: np.ndarray, visible: np.ndarray) -> np.ndarray:
    """Row of ``detected`` imaging each particle (−1: none), mutual nearest within radius."""
    out = np.full(len(exact), -1, dtype=np.int64)
    idx = np.flatnonzero(visible & np.isfinite(exact).all(axis=1))
    if len(detected) == 0 or len(idx) == 0:
        return out
    dist, nearest = cKDTree(detected).query(exact[idx], distance_upper_bound=ASSOCIATION_RADIUS)
    ok = np.isfinite(dist)
    back = cKDTree(exact[idx]).query(detected[nearest[ok]])[1]
    mutual = back == np.flatnonzero(ok)
    out[idx[np.flatnonzero(ok)[mutual]]] = nearest[ok][mutual]
    return out


class _DetectionTally:
    """Detection against the exact particle images, summed per camera over the frames."""

    def __init__(self, names: Sequence[str]) -> None:
        n = len(names)
        self.sq_err = np.zeros((n, 2))
        self.found, self.visible = np.zeros(n), np.zeros(n)
        self.detected, self.spurious = np.zeros(n), np.zeros(n)
        self.xy: list[list[np.ndarray]] = [[] for _ in names]

    def add(self, c: int, detected: np.ndarray, exact: np.ndarray, visible, row) -> None:
        """Camera c's detections (D, 2), the exact images (P, 2), visibility and rows (P,)."""
        hit = row >= 0
        self.sq_err[c] += np.sum((detected[row[hit]] - exact[hit]) ** 2, axis=0)
        self.found[c] += hit.sum()
        self.visible[c] += visible.sum()
        self.detected[c] += len(detected)
        self.spurious[c] += len(detected) - hit.sum()
        self.xy[c].append(detected[row[hit]])


def _triangulated_particles(detected, exact, visible, cameras, tally) -> np.ndarray:
    """Each particle's position from its detected centres in one frame of every camera.

    Parameters
    ----------
    detected : sequence of C ndarray, shape (N_c, 2)
        The detected centres on the frame of each camera, px.
    exact, visible : sequences of C ndarray, shapes (P, 2) and (P,)
        The exact image of every particle and whether it is imaged, per camera.
    cameras : sequence of C CameraModel
        The true cameras.
    tally : _DetectionTally
        Receives the detection statistics.

    Returns
    -------
    ndarray, shape (P, 3)
        Triangulated positions, m; NaN for particles not detected in every camera.
    """
    rows = []
    for c, xy in enumerate(detected):
        row = _associate(xy, exact[c], visible[c])
        tally.add(c, xy, exact[c], visible[c], row)
        rows.append((row, xy))
    everywhere = np.all([row >= 0 for row, _ in rows], axis=0)
    points = np.full((len(everywhere), 3), np.nan)
    pixels = [xy[row[everywhere]] for row, xy in rows]
    points[everywhere] = triangulate(cameras, pixels).points
    return points


def detected_runs(
    frames: FrameDetections,
    truth: Sequence[TruthRun],
    cameras: Sequence[CameraModel],
    settings: PipelineSettings,
    *,
    tick: Callable[[], None] | None = None,
) -> tuple[list[RunParticles], DetectionQuality]:
    """Detected centres, paired with their particles by the truth, through the true cameras.

    With a shared first frame, frame a of each snapshot is triangulated once for every
    Δt, so X(t) is the same bits at every Δt (the statistics join the Δt on it) and the
    detection figures count each image once.

    Parameters
    ----------
    frames : FrameDetections
        The detections on the rendered images.
    truth : sequence of TruthRun
        From :func:`read_truth`, in the dataset's Δt order.
    cameras : sequence of CameraModel
        The true cameras in the dataset's camera order.
    settings : PipelineSettings
        Analysis volume, snapshot limit.
    tick : callable, optional
        Called after each snapshot.

    Returns
    -------
    (list of RunParticles, DetectionQuality)
    """
    names = frames.cameras
    tally = _DetectionTally(names)
    shared_a: dict[int, np.ndarray] = {}
    errors = []  # per Δt: {snapshot: (particle indices, position error, ΔX error)}
    runs = []
    box = settings.statistics.analysis_volume
    for k, run in enumerate(truth):
        per_snapshot, run_errors = [], {}
        for m in range(settings.snapshot_count(frames.frames[k])):

            def measured(f: int, m=m, k=k, run=run) -> np.ndarray:
                exact = [run.xy[name][m, f] for name in names]
                visible = [run.visible[name][m, f] for name in names]
                detected = frames.detections(k, m, "ab"[f])
                return _triangulated_particles(detected, exact, visible, cameras, tally)

            if frames.shared_first_frame:
                if m not in shared_a:
                    shared_a[m] = measured(0)
                start = shared_a[m]
            else:
                start = measured(0)
            end = measured(1)
            both = np.isfinite(start[:, 0]) & np.isfinite(end[:, 0])
            ends = (start[both], end[both])
            true_ends = run.positions[m][:, both]
            inside = inside_box(true_ends[0], box)
            run_errors[m] = (
                np.flatnonzero(both)[inside],
                ends[0][inside] - true_ends[0][inside],
                (ends[1] - ends[0])[inside] - (true_ends[1] - true_ends[0])[inside],
            )
            per_snapshot.append(ends)
            if tick is not None:
                tick()
        runs.append(_run_particles(k, run.dt, per_snapshot, settings, len(names)))
        errors.append(run_errors)
    position_noise, displacement_noise = _noise_rms(errors, shared=frames.shared_first_frame)
    quality = DetectionQuality(
        cameras=tuple(names),
        rms_error_px=np.sqrt(tally.sq_err / np.maximum(tally.found, 1)[:, None]),
        found=tally.found / np.maximum(tally.visible, 1),
        spurious=tally.spurious / np.maximum(tally.detected, 1),
        detected_xy={n: np.concatenate(v) for n, v in zip(names, tally.xy, strict=True)},
        dt=np.array([run.dt for run in truth]),
        position_noise=position_noise,
        displacement_noise=displacement_noise,
    )
    return runs, quality


def _noise_rms(errors: Sequence[dict], *, shared: bool) -> tuple[np.ndarray, np.ndarray]:
    """RMS position noise (3,) and displacement noise per Δt (K, 3) of the scored particles.

    ``errors[k][m]`` holds (particle indices, position errors (N, 3), ΔX errors (N, 3)) of
    snapshot m at Δt_k. With a shared first frame the statistics use only the particles
    found at every Δt (:func:`ptv.stats.links.shared_snapshots`), which are less often
    overlapped by a neighbour and so less noisy: the noise is measured on them too.
    """
    if shared:
        snapshots = sorted(set.intersection(*(set(e) for e in errors)))
        common = {m: reduce(np.intersect1d, [e[m][0] for e in errors]) for m in snapshots}
        errors = [
            {m: tuple(a[np.isin(e[m][0], common[m])] for a in e[m]) for m in snapshots}
            for e in errors
        ]

    def rms(arrays) -> np.ndarray:
        stacked = np.concatenate(list(arrays)) if arrays else np.empty((0, 3))
        return np.sqrt(np.mean(stacked**2, axis=0)) if len(stacked) else np.full(3, np.nan)

    position = rms([v[1] for v in errors[0].values()])
    displacement = np.array([rms([v[2] for v in e.values()]) for e in errors])
    return position, displacement
