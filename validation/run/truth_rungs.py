"""Reference measurements of a rendered dataset that use the truth: the error budget's rungs.

- :func:`exact_runs`: the true positions at t and t + Δt of every particle (no camera at
  all): what is left is the multi-Δt method's own error (finite Δt, sampling).
- :func:`detection_chunk` and :func:`detected_runs`: the detected centres on the images,
  each paired with the particle that made it (so no matching error), triangulated with
  the true cameras (so no calibration error): what is added is the detection error.
  They also measure the detection error in pixels, the detection yield, the
  fractional-position histogram and the position noise in 3-D.

Both give :class:`ptv.stats.links.RunParticles`, so the same statistics run on them as
on the PTV stack's own links. Their rows are the particles whose X(t) lies in the
analysis volume (the only ones the statistics use); the counts per snapshot are those
of every particle.
"""

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import reduce

import numpy as np
from scipy.spatial import cKDTree

from ptv.bins import LogBins
from ptv.box import inside_box
from ptv.camera_model import CameraModel
from ptv.detect import FractionSums
from ptv.detect.frames import FrameDetections
from ptv.settings import PipelineSettings
from ptv.stats.links import RunParticles
from ptv.triangulate import triangulate
from validation.truth.pair_noise import PairNoiseSums
from validation.truth.truth_file import TruthFile, TruthRun

#: Largest distance between a detection and the true image of its particle, px.
ASSOCIATION_RADIUS = 1.0


def in_volume(
    start: np.ndarray, end: np.ndarray, settings: PipelineSettings
) -> tuple[int, np.ndarray, np.ndarray]:
    """A snapshot's particles kept for a reference run: their count, and X(t) and
    X(t + Δt), shapes (N, 3), of those whose X(t) lies in the analysis volume, m."""
    keep = inside_box(start, settings.statistics.analysis_volume)
    return len(start), start[keep], end[keep]


def reference_run(
    k: int,
    dt: float,
    snapshot_ids: Sequence[int],
    per_snapshot: Sequence[tuple[int, np.ndarray, np.ndarray]],
    n_cameras: int,
) -> RunParticles:
    """RunParticles from :func:`in_volume` of each snapshot; no outliers by construction.

    Detections, matches and links per snapshot are recorded as the number of particles
    the snapshot had.
    """
    counts = np.array([n for n, _, _ in per_snapshot], dtype=np.int64)
    sizes = np.array([len(a) for _, a, _ in per_snapshot], dtype=np.int64)
    m = len(per_snapshot)
    positions = np.concatenate([a for _, a, _ in per_snapshot]) if m else np.empty((0, 3))
    moves = [b - a for _, a, b in per_snapshot]
    return RunParticles(
        k=k,
        dt=dt,
        positions=positions,
        displacements=np.concatenate(moves) if m else np.empty((0, 3)),
        offsets=np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64),
        snapshot_ids=np.asarray(snapshot_ids, dtype=np.int64),
        detections=np.broadcast_to(counts[:, None, None], (m, 2, n_cameras)).copy(),
        matches=np.repeat(counts[:, None], 2, axis=1),
        links=counts,
        processed=np.asarray(snapshot_ids, dtype=np.int64),
        in_analysis=np.ones(len(positions), dtype=bool),
        outlier=np.zeros(len(positions), dtype=bool),
    )


def exact_runs(
    truth: TruthFile,
    chunks: Sequence[tuple[int, int]],
    settings: PipelineSettings,
    *,
    progress: Callable[[int, int], None] | None = None,
) -> list[RunParticles]:
    """The true positions of every particle at t and t + Δt, per Δt.

    Parameters
    ----------
    truth : TruthFile
        The dataset's truth, read chunk by chunk.
    chunks : sequence of (int, int)
        Snapshot ranges covering the snapshots to use, in order.
    settings : PipelineSettings
        Analysis volume.
    progress : callable(done, total), optional
        Called after each chunk.
    """
    per_k: list[list] = [[] for _ in truth.dt]
    for i, (m0, m1) in enumerate(chunks):
        for k, run in enumerate(truth.runs(m0, m1)):
            per_k[k].extend(in_volume(p[0], p[1], settings) for p in run.positions)
        if progress is not None:
            progress(i + 1, len(chunks))
    n_cam = len(truth.rig.camera_names)
    return [
        reference_run(k, float(dt), range(len(per_k[k])), per_k[k], n_cam)
        for k, dt in enumerate(truth.dt)
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
    fractions : dict of str to FractionSums
        The fractional positions of the associated particles' detections, per camera
        (pooled for the peak-locking test, :func:`ptv.detect.peak_locking`).
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
    pair_noise : ndarray, shape (K, B)
        ⟨[(δ_j − δ_i)·e]²⟩ over the pairs of those particles per Δt and separation bin,
        δ their ΔX errors, m² (:mod:`validation.truth.pair_noise`): the noise term of
        their S2 (NaN where no pair).
    """

    cameras: tuple[str, ...]
    rms_error_px: np.ndarray
    found: np.ndarray
    spurious: np.ndarray
    fractions: dict
    dt: np.ndarray
    position_noise: np.ndarray
    displacement_noise: np.ndarray
    pair_noise: np.ndarray


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
        self.fractions = [FractionSums.of(np.empty((0, 2))) for _ in names]

    def add(self, c: int, detected: np.ndarray, exact: np.ndarray, visible, row) -> None:
        """Camera c's detections (D, 2), the exact images (P, 2), visibility and rows (P,)."""
        hit = row >= 0
        self.sq_err[c] += np.sum((detected[row[hit]] - exact[hit]) ** 2, axis=0)
        self.found[c] += hit.sum()
        self.visible[c] += visible.sum()
        self.detected[c] += len(detected)
        self.spurious[c] += len(detected) - hit.sum()
        self.fractions[c] = self.fractions[c] + FractionSums.of(detected[row[hit]])

    def merged(self, other: "_DetectionTally") -> "_DetectionTally":
        """The sum of this tally and ``other``."""
        out = _DetectionTally([None] * len(self.found))
        for name in ("sq_err", "found", "visible", "detected", "spurious"):
            setattr(out, name, getattr(self, name) + getattr(other, name))
        out.fractions = [a + b for a, b in zip(self.fractions, other.fractions, strict=True)]
        return out


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


@dataclass(frozen=True)
class NoiseSums:
    """Sums of the squared errors against the truth of the scored particles: the noise
    of a chunk, summed over chunks (:meth:`merged`) into that of the run.

    The scored particles are those whose true X(t) lies in the analysis volume. With a
    shared first frame the statistics use only the particles found at every Δt
    (:func:`ptv.stats.links.shared_snapshots`), which are less often overlapped by a
    neighbour and so less noisy: the noise is measured on them alone. A chunk holds
    every Δt of its snapshots, so this choice is made within the chunk.

    Attributes
    ----------
    position : ndarray, shape (3,)
        Σ (X(t) − X_true(t))², m², over the scored particles of Δt_0.
    positions : int
        Particles in ``position``.
    displacement : ndarray, shape (K, 3)
        Σ (ΔX − ΔX_true)² per Δt, m².
    displacements : ndarray of int, shape (K,)
        Particles in each row of ``displacement``.
    pairs : PairNoiseSums
        The squared longitudinal ΔX-error differences over their pairs.
    """

    position: np.ndarray
    positions: int
    displacement: np.ndarray
    displacements: np.ndarray
    pairs: PairNoiseSums

    @classmethod
    def of(cls, errors: Sequence[dict], bins: LogBins, *, shared: bool) -> "NoiseSums":
        """From ``errors[k][m]`` = (particle indices, position errors (N, 3), ΔX errors
        (N, 3), true X(t) (N, 3)) of snapshot m at Δt_k, and the separation bins."""
        if shared:
            snapshots = sorted(set.intersection(*(set(e) for e in errors)))
            common = {m: reduce(np.intersect1d, [e[m][0] for e in errors]) for m in snapshots}
            errors = [
                {m: tuple(a[np.isin(e[m][0], common[m])] for a in e[m]) for m in snapshots}
                for e in errors
            ]

        def stacked(run: dict, column: int) -> np.ndarray:
            arrays = [v[column] for v in run.values()]
            return np.concatenate(arrays) if arrays else np.empty((0, 3))

        position = stacked(errors[0], 1)
        moves = [stacked(run, 2) for run in errors]

        def pair_sums(run: dict) -> PairNoiseSums:
            per_snapshot = (
                PairNoiseSums.of_snapshot(x, moved[:, None], bins, seed=m)
                for m, (_, _, moved, x) in run.items()
            )
            return reduce(PairNoiseSums.merged, per_snapshot, PairNoiseSums.empty(1, bins))

        pairs = [pair_sums(run) for run in errors]
        return cls(
            np.sum(position**2, axis=0),
            len(position),
            np.array([np.sum(d**2, axis=0) for d in moves]).reshape(len(errors), 3),
            np.array([len(d) for d in moves], dtype=np.int64),
            PairNoiseSums.stacked(pairs),
        )

    def merged(self, other: "NoiseSums") -> "NoiseSums":
        """The sums of this chunk and ``other``."""
        return NoiseSums(
            self.position + other.position,
            self.positions + other.positions,
            self.displacement + other.displacement,
            self.displacements + other.displacements,
            self.pairs.merged(other.pairs),
        )

    def rms(self) -> tuple[np.ndarray, np.ndarray]:
        """RMS position noise (3,) and displacement noise per Δt (K, 3), m; NaN where
        no particle was scored."""
        with np.errstate(invalid="ignore"):  # no particle: 0/0 = NaN
            position = np.sqrt(self.position / self.positions)
            displacement = np.sqrt(self.displacement / self.displacements[:, None])
        return position, displacement


@dataclass(frozen=True, eq=False)
class DetectionChunk:
    """The truth-paired detections of a chunk of snapshots (:func:`detection_chunk`).

    Attributes
    ----------
    ends : list of K lists of (int, ndarray (N, 3), ndarray (N, 3))
        Per Δt and snapshot, the number of particles found in both frames of every
        camera, and X(t) and X(t + Δt) of those in the analysis volume
        (:func:`in_volume`), m.
    snapshots : list of K lists of int
        The snapshots of ``ends``, per Δt.
    noise : NoiseSums
        Their errors against the truth.
    tally : _DetectionTally
        Detection against the exact images, summed over the chunk's frames.
    """

    ends: list
    snapshots: list
    noise: NoiseSums
    tally: _DetectionTally


def detection_chunk(
    item: tuple[FrameDetections, Sequence[TruthRun]],
    *,
    cameras: Sequence[CameraModel],
    settings: PipelineSettings,
) -> DetectionChunk:
    """Truth-paired detections of one chunk: its detections and its truth, per Δt.

    With a shared first frame, frame a of each snapshot is triangulated once for every
    Δt, so X(t) is the same bits at every Δt (the statistics join the Δt on it) and the
    detection figures count each image once.

    Parameters
    ----------
    item : (FrameDetections, sequence of K TruthRun)
        The detections on the rendered images and the truth of the same snapshots.
    cameras : sequence of CameraModel
        The true cameras in the detections' camera order.
    settings : PipelineSettings
        Analysis volume, snapshot limit.

    Returns
    -------
    DetectionChunk
    """
    frames, truth = item
    names = frames.cameras
    tally = _DetectionTally(names)
    box = settings.statistics.analysis_volume
    shared_a: dict[int, np.ndarray] = {}
    ends, errors = [], []
    for k, run in enumerate(truth):
        run_ends, run_errors = [], {}
        for m in run.snapshots:
            if m >= settings.snapshot_count(frames.frames[k]):
                continue
            i = m - run.first

            def measured(f: int, m=m, k=k, i=i, run=run) -> np.ndarray:
                exact = [run.xy[name][i, f] for name in names]
                visible = [run.visible[name][i, f] for name in names]
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
            pair = (start[both], end[both])
            true_ends = run.positions[i][:, both]
            inside = inside_box(true_ends[0], box)
            run_errors[m] = (
                np.flatnonzero(both)[inside],
                pair[0][inside] - true_ends[0][inside],
                (pair[1] - pair[0])[inside] - (true_ends[1] - true_ends[0])[inside],
                true_ends[0][inside],
            )
            run_ends.append(in_volume(*pair, settings))
        ends.append(run_ends)
        errors.append(run_errors)
    noise = NoiseSums.of(errors, settings.statistics.bins, shared=frames.shared_first_frame)
    return DetectionChunk(ends, [list(e) for e in errors], noise, tally)


def detected_runs(
    chunks: Sequence[DetectionChunk], dt: np.ndarray, cameras: Sequence[str]
) -> tuple[list[RunParticles], DetectionQuality]:
    """The detection rung's runs and the detection quality, from its chunks in order.

    Parameters
    ----------
    chunks : sequence of DetectionChunk
        :func:`detection_chunk` of every chunk, in snapshot order.
    dt : ndarray, shape (K,)
        s.
    cameras : sequence of str
        Camera names.

    Returns
    -------
    (list of RunParticles, DetectionQuality)
    """
    tally = reduce(_DetectionTally.merged, (c.tally for c in chunks), _DetectionTally(cameras))
    runs = []
    for k, step in enumerate(dt):
        ends = [pair for c in chunks for pair in c.ends[k]]
        snapshots = [m for c in chunks for m in c.snapshots[k]]
        runs.append(reference_run(k, float(step), snapshots, ends, len(cameras)))
    noise = reduce(NoiseSums.merged, (c.noise for c in chunks))
    position_noise, displacement_noise = noise.rms()
    quality = DetectionQuality(
        cameras=tuple(cameras),
        rms_error_px=np.sqrt(tally.sq_err / np.maximum(tally.found, 1)[:, None]),
        found=tally.found / np.maximum(tally.visible, 1),
        spurious=tally.spurious / np.maximum(tally.detected, 1),
        fractions=dict(zip(cameras, tally.fractions, strict=True)),
        dt=np.asarray(dt),
        position_noise=position_noise,
        displacement_noise=displacement_noise,
        pair_noise=noise.pairs.mean(),
    )
    return runs, quality
