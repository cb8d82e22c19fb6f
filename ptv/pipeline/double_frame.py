"""Double-frame 3D-PTV, from detected particles to links, then to S2(r), ε and u′.

The particles detected on every frame come from a :class:`ptv.pipeline.frames.FrameDetections`
source (detected from a dataset's images, or read from a detection store). For every
Δt_k and every snapshot m:

1. match the cameras in frame a and in frame b (:func:`ptv.matching.stereo.match`) inside the
   measurement volume (default: the 100 × 100 × 10 mm sheet plus 1 mm) with the stereo
   tolerance (default 0.15 mm, 2–3× the calibration error); with a shared first frame,
   frame a of snapshot m is matched once for every Δt;
2. link frame a to frame b one-to-one (:func:`ptv.tracking.linking.link`) within the radius
   r_k = max_speed·Δt_k + 5σ_b (max_speed: the largest speed expected, default
   1.5 m/s; σ_b: the position noise, default 30 µm): the Δt-scaled threshold of
   docs/ptv.md §4, which also rejects mismatches with |ΔX| beyond it;
3. flag mislinks by the normalised median test (Westerweel & Scarano 2005) on the
   3-D displacements: a link is an outlier when |ΔX − m| > threshold·(r̃ + ε0), m the
   median displacement of its 8 nearest linked neighbours (same snapshot, by X(t)), r̃
   the median of the neighbours' own |ΔX_j − m| and ε0 = σ_b (default threshold 4);
4. keep X(t) and ΔX = X(t + Δt) − X(t) of every link, with the outlier flag.

Why step 3: a link whose end is a stereo ghost, or a particle whose partner was lost,
is taken up to the link radius away (~0.9 mm at Δt = 0.5 ms) and its displacement is
unrelated to the flow. Such links are rare (0.1–0.3 % in the analysis volume on a
rendered paper-stereo dataset) but q grows as |ΔX|², and their share grows with Δt,
so they added +4–8 % to the multi-Δt S2 and pushed c2 negative there; the test
removed the harmful half of them and no correct link. Ghost-to-ghost links that
move with their neighbours pass it, and do no harm.

A snapshot whose frames give no match (an empty frame, a dark laser pulse) or no link
is skipped with a warning; a Δt left without snapshots is dropped from the statistics;
fewer than two Δt left is an error.

Snapshots are independent of one another, so :func:`measure_snapshots` measures any
range of them on its own (a chunk of a parallel run) and :func:`run_particles` joins
the chunks. The statistics of the links are :func:`ptv.stats.run_statistics.compute_statistics`.

Nothing here reads a ground truth, plots or prints; :mod:`ptv.pipeline.results` writes the
results, ``validation`` draws and compares.
"""

import logging
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.spatial import cKDTree

from ptv._checks import positive
from ptv.box import Box, check_box, inside_box
from ptv.camera_model import CameraModel
from ptv.io.dataset import cameras_in_order
from ptv.matching.stereo import match
from ptv.pipeline.frames import FrameDetections
from ptv.stats.links import RunParticles
from ptv.stats.run_statistics import PtvStatistics, StatisticsSettings, compute_statistics
from ptv.tracking.linking import RecordingTracks, link, search_radius

__all__ = [
    "MEASUREMENT_VOLUME",
    "MatchedPoints",
    "PipelineSettings",
    "PtvResult",
    "SnapshotMeasurement",
    "link_radius",
    "match_frame",
    "measure_snapshot",
    "measure_snapshots",
    "median_test_outliers",
    "run_particles",
    "run_pipeline",
]

log = logging.getLogger(__name__)

Progress = Callable[[int, int], None]

#: The 100 × 100 × 10 mm laser sheet plus a 1 mm margin, m: the default matching volume.
MEASUREMENT_VOLUME: Box = ((-0.051, -0.051, -0.006), (0.051, 0.051, 0.006))


@dataclass(frozen=True)
class PipelineSettings:
    """Options of :func:`run_pipeline` (SI units).

    Attributes
    ----------
    volume : (lower, upper)
        Matching volume, m (default :data:`MEASUREMENT_VOLUME`).
    tolerance : float
        Stereo tolerance on the ray distances, m (default 0.15 mm).
    min_cameras : int
        Fewest cameras a match must use (default 2; at most the number of cameras).
    max_speed : float
        Largest particle speed expected, m/s: sets the link radius (default 1.5).
    position_noise : float
        Expected position noise σ_b (one component), m: adds 5σ_b to the link radius
        (default 30 µm).
    max_acceleration : float
        Largest particle acceleration expected, m/s²: sets the radius around a track's
        constant-velocity prediction in a time-resolved recording
        (:func:`ptv.tracking.recording.track_radii`; default 100, about 5 times the rms of one
        component in the paper's flows).
    outlier_threshold : float or None
        Threshold of the normalised median test on the displacements (default 4; None
        keeps every link).
    outlier_neighbours : int
        Neighbours of the normalised median test (default 8).
    snapshots : int or None
        Process only the first N snapshots of every Δt (None: all).
    statistics : StatisticsSettings
        Analysis volume, bins, plateau, C2, bootstrap (:mod:`ptv.stats.run_statistics`).
    """

    volume: Box = MEASUREMENT_VOLUME
    tolerance: float = 1.5e-4
    min_cameras: int = 2
    max_speed: float = 1.5
    position_noise: float = 30e-6
    max_acceleration: float = 100.0
    outlier_threshold: float | None = 4.0
    outlier_neighbours: int = 8
    snapshots: int | None = None
    statistics: StatisticsSettings = field(default_factory=StatisticsSettings)

    def __post_init__(self) -> None:
        object.__setattr__(self, "volume", check_box("volume", self.volume))
        for name in ("tolerance", "max_speed", "position_noise", "max_acceleration"):
            object.__setattr__(self, name, positive(name, getattr(self, name)))
        if self.outlier_threshold is not None:
            object.__setattr__(
                self, "outlier_threshold", positive("outlier_threshold", self.outlier_threshold)
            )
        if (
            isinstance(self.min_cameras, bool)
            or not isinstance(self.min_cameras, int)
            or self.min_cameras < 2
        ):
            raise ValueError(f"min_cameras must be an integer >= 2, got {self.min_cameras!r}")
        if not isinstance(self.outlier_neighbours, int) or self.outlier_neighbours < 2:
            raise ValueError(
                f"outlier_neighbours must be an integer >= 2, got {self.outlier_neighbours!r}"
            )
        if self.snapshots is not None and not (
            isinstance(self.snapshots, int)
            and not isinstance(self.snapshots, bool)
            and self.snapshots >= 1
        ):
            raise ValueError(f"snapshots must be an integer >= 1 or None, got {self.snapshots!r}")
        if not isinstance(self.statistics, StatisticsSettings):
            raise ValueError(
                f"statistics must be a StatisticsSettings, got {type(self.statistics).__name__}"
            )

    def snapshot_count(self, frames: int) -> int:
        """Snapshots processed of a run of ``frames`` frame pairs."""
        return frames if self.snapshots is None else min(self.snapshots, frames)


def link_radius(dt: float, settings: PipelineSettings) -> float:
    """Link search radius max_speed·Δt + 5·position_noise, m."""
    return search_radius(
        dt, u_rms=settings.max_speed, sigma_b=settings.position_noise, k_v=1.0, k_b=5.0
    )


def median_test_outliers(
    positions: np.ndarray,
    displacements: np.ndarray,
    *,
    threshold: float,
    noise: float,
    neighbours: int = 8,
) -> np.ndarray:
    """Normalised median test (Westerweel & Scarano 2005) on scattered 3-D displacements.

    For link i with neighbours j (its ``neighbours`` nearest links by position), m_i is
    the component-wise median of ΔX_j, r̃_i the median of |ΔX_j − m_i|, and link i is
    an outlier when |ΔX_i − m_i| > threshold·(r̃_i + noise).

    Parameters
    ----------
    positions, displacements : ndarray, shape (N, 3)
        X(t) and ΔX of the links of one snapshot, m.
    threshold : float
        > 0 (about 2 for PIV vectors; 4 keeps genuine turbulent increments).
    noise : float
        ε0, the displacement noise floor, m (> 0).
    neighbours : int
        Neighbours per link (fewer when the snapshot has fewer links).

    Returns
    -------
    ndarray of bool, shape (N,)
        True for outliers; all False with fewer than 4 links.
    """
    x = np.asarray(positions, dtype=np.float64)
    d = np.asarray(displacements, dtype=np.float64)
    n = len(x)
    k = min(int(neighbours), n - 1)
    if k < 3:
        return np.zeros(n, dtype=bool)
    _, nb = cKDTree(x).query(x, k=k + 1)
    nb = nb[:, 1:]  # drop the point itself
    median = np.median(d[nb], axis=1)
    spread = np.median(np.linalg.norm(d[nb] - median[:, None, :], axis=2), axis=1)
    return np.linalg.norm(d - median, axis=1) > threshold * (spread + noise)


# ------------------------------------------------------------------------ per snapshot


@dataclass(frozen=True, eq=False)
class SnapshotMeasurement:
    """What one snapshot gave.

    Attributes
    ----------
    k, m : int
        Δt index and snapshot number.
    detections : ndarray of int, shape (2, C)
        Particles detected in frame a (row 0) and frame b (row 1) of each camera.
    matches : ndarray of int, shape (2,)
        3-D points matched in frames a and b.
    links : int
        Links made (whatever rows are kept below).
    positions : ndarray, shape (N, 3)
        X(t) of the links kept (all of them unless :meth:`within` dropped some), m.
    displacements : ndarray, shape (N, 3)
        ΔX = X(t + Δt) − X(t), m.
    outlier : ndarray of bool, shape (N,)
        Links failing the normalised median test (made on all the links).
    matched : (ndarray (N_a, 3), ndarray (N_b, 3)) or None
        The matched points of frames a and b, m (None unless asked for).
    """

    k: int
    m: int
    detections: np.ndarray
    matches: np.ndarray
    links: int
    positions: np.ndarray
    displacements: np.ndarray
    outlier: np.ndarray
    matched: tuple[np.ndarray, np.ndarray] | None = None

    def within(self, box: Box) -> "SnapshotMeasurement":
        """The same measurement keeping only the links whose X(t) lies in ``box``."""
        keep = inside_box(self.positions, box)
        return replace(
            self,
            positions=self.positions[keep],
            displacements=self.displacements[keep],
            outlier=self.outlier[keep],
        )


def match_frame(
    xy: Sequence[np.ndarray], cameras: Sequence[CameraModel], settings: PipelineSettings
) -> np.ndarray:
    """The matched 3-D points of one frame from the detections of every camera.

    Parameters
    ----------
    xy : sequence of C ndarray, shape (N_c, 2)
        Detected centres on each camera, px (the same instant).
    cameras : sequence of C CameraModel
        Their calibrations.
    settings : PipelineSettings
        Matching volume, tolerance and fewest cameras per match.

    Returns
    -------
    ndarray, shape (N, 3)
        Matched points, m.
    """
    if len(xy) != len(cameras):
        raise ValueError(f"need detections per camera, got {len(xy)} for {len(cameras)} cameras")
    return match(
        cameras,
        list(xy),
        settings.volume,
        tolerance=settings.tolerance,
        min_cameras=settings.min_cameras,
    ).points


def measure_snapshot(
    frames: FrameDetections,
    k: int,
    m: int,
    cameras: Sequence[CameraModel],
    settings: PipelineSettings,
    *,
    frame_a: tuple[list[int], np.ndarray] | None = None,
    keep_matched: bool = False,
) -> SnapshotMeasurement:
    """Match frames a and b of snapshot m at Δt_k, then link and test the links.

    Parameters
    ----------
    frames : FrameDetections
        The detections.
    k, m : int
        Δt index and snapshot.
    cameras : sequence of CameraModel
        Calibrations in the order of ``frames.cameras``.
    settings : PipelineSettings
        Volume, tolerance, link radius, median test.
    frame_a : (list of int, ndarray (N, 3)), optional
        Detections per camera and matched points of frame a, already measured (as when
        every Δt shares it).
    keep_matched : bool
        Keep the matched points of both frames in the measurement.

    Returns
    -------
    SnapshotMeasurement
        With no links when a frame has no match.
    """
    if len(cameras) != len(frames.cameras):
        raise ValueError(
            f"need one calibration per camera: {len(cameras)} for {len(frames.cameras)} cameras"
        )
    points, detections = [], []
    for frame in ("a", "b"):
        if frame == "a" and frame_a is not None:
            counts, matched = frame_a
        else:
            xy = frames.detections(k, m, frame)
            counts, matched = [len(v) for v in xy], match_frame(xy, cameras, settings)
        detections.append(counts)
        points.append(matched)
    dt = float(frames.dt[k])
    if len(points[0]) and len(points[1]):
        links = link(points[0], points[1], radius=link_radius(dt, settings))
        positions, displacements = links.positions, links.displacements
    else:
        positions = displacements = np.empty((0, 3))
    if settings.outlier_threshold is None:
        outlier = np.zeros(len(positions), dtype=bool)
    else:
        outlier = median_test_outliers(
            positions,
            displacements,
            threshold=settings.outlier_threshold,
            noise=settings.position_noise,
            neighbours=settings.outlier_neighbours,
        )
    return SnapshotMeasurement(
        k=k,
        m=m,
        detections=np.asarray(detections, dtype=np.int64),
        matches=np.asarray([len(p) for p in points], dtype=np.int64),
        links=len(positions),
        positions=positions,
        displacements=displacements,
        outlier=outlier,
        matched=(points[0], points[1]) if keep_matched else None,
    )


def measure_snapshots(
    frames: FrameDetections,
    snapshots: Sequence[int],
    cameras: Sequence[CameraModel],
    settings: PipelineSettings,
    *,
    tick: Callable[[], None] | None = None,
    keep_matched: bool = False,
) -> list[list[SnapshotMeasurement]]:
    """Measure some snapshots at every Δt (a chunk of a run; snapshots are independent).

    Parameters
    ----------
    frames : FrameDetections
        The detections.
    snapshots : sequence of int
        Snapshot numbers m; those beyond a run's frames (or ``settings.snapshots``) are
        left out of it.
    cameras : sequence of CameraModel
        Calibrations in the order of ``frames.cameras``.
    settings : PipelineSettings
        Options.
    tick : callable, optional
        Called after each snapshot of each Δt.
    keep_matched : bool
        Keep the matched points of both frames in each measurement.

    Returns
    -------
    list of K lists of SnapshotMeasurement
        Per Δt, the snapshots measured in the order given.
    """
    out: list[list[SnapshotMeasurement]] = [[] for _ in frames.dt]
    for m in snapshots:
        frame_a = None  # with a shared first frame, matched once for every k
        for k in range(len(frames.dt)):
            if m >= settings.snapshot_count(frames.frames[k]):
                continue
            if frames.shared_first_frame and frame_a is None:
                xy = frames.detections(k, m, "a")
                frame_a = ([len(v) for v in xy], match_frame(xy, cameras, settings))
            out[k].append(
                measure_snapshot(
                    frames, k, m, cameras, settings, frame_a=frame_a, keep_matched=keep_matched
                )
            )
            if tick is not None:
                tick()
    return out


# ------------------------------------------------------------------------------ per run


def run_particles(
    k: int,
    dt: float,
    measured: Sequence[SnapshotMeasurement],
    n_cameras: int,
    settings: PipelineSettings,
) -> RunParticles:
    """The links of the run at Δt_k from its measured snapshots, in snapshot order.

    Snapshots without a match in a frame, or without a link, are skipped with a warning.

    Parameters
    ----------
    k : int
        Δt index.
    dt : float
        Δt, s.
    measured : sequence of SnapshotMeasurement
        The run's snapshots (:func:`measure_snapshots`), in order.
    n_cameras : int
        Cameras C.
    settings : PipelineSettings
        Link radius (for the messages) and analysis volume.

    Returns
    -------
    RunParticles
    """
    kept = []
    for res in measured:
        if res.matches.min() == 0:
            frames = " and ".join(f for f, n in zip("ab", res.matches, strict=True) if n == 0)
            log.warning(
                "Δt_%d = %.4g s, snapshot %d skipped: no matched particle in frame %s "
                "(detections a %s, b %s)",
                k,
                dt,
                res.m,
                frames,
                res.detections[0].tolist(),
                res.detections[1].tolist(),
            )
        elif res.links == 0:
            log.warning(
                "Δt_%d = %.4g s, snapshot %d skipped: no link within %.3g mm",
                k,
                dt,
                res.m,
                link_radius(dt, settings) * 1e3,
            )
        else:
            kept.append(res)
    sizes = [len(r.positions) for r in kept]
    positions = np.concatenate([r.positions for r in kept]) if kept else np.empty((0, 3))
    displacements = np.concatenate([r.displacements for r in kept]) if kept else np.empty((0, 3))
    outlier = np.concatenate([r.outlier for r in kept]) if kept else np.empty(0, dtype=bool)
    return RunParticles(
        k=k,
        dt=float(dt),
        positions=positions,
        displacements=displacements,
        offsets=np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64),
        snapshot_ids=np.asarray([r.m for r in kept], dtype=np.int64),
        detections=np.asarray([r.detections for r in measured], dtype=np.int64).reshape(
            -1, 2, n_cameras
        ),
        matches=np.asarray([r.matches for r in measured], dtype=np.int64).reshape(-1, 2),
        links=np.asarray([r.links for r in measured], dtype=np.int64),
        processed=np.asarray([r.m for r in measured], dtype=np.int64),
        in_analysis=inside_box(positions, settings.statistics.analysis_volume),
        outlier=outlier,
    )


# ----------------------------------------------------------------------------- pipeline


@dataclass(frozen=True, eq=False)
class MatchedPoints:
    """Matched 3-D points of many frames, one row per point.

    Attributes
    ----------
    k : ndarray of int, shape (N,)
        Δt index.
    snapshot : ndarray of int, shape (N,)
        Snapshot number m.
    frame : ndarray of int, shape (N,)
        0 for frame a (t), 1 for frame b (t + Δt).
    positions : ndarray, shape (N, 3)
        The points, m, in the calibration's frame.
    """

    k: np.ndarray
    snapshot: np.ndarray
    frame: np.ndarray
    positions: np.ndarray

    @classmethod
    def from_frames(cls, frames: Iterable[tuple[int, int, int, np.ndarray]]) -> "MatchedPoints":
        """The rows of frames given as (k, m, frame, points (N, 3)), in that order."""
        keys, points = [], []
        for k, m, frame, p in frames:
            keys.append(np.repeat([[k, m, frame]], len(p), axis=0))
            points.append(np.asarray(p, dtype=np.float64).reshape(-1, 3))
        keys = np.concatenate(keys).astype(np.int64) if keys else np.empty((0, 3), np.int64)
        points = np.concatenate(points) if points else np.empty((0, 3))
        return cls(keys[:, 0], keys[:, 1], keys[:, 2], points)


@dataclass(frozen=True, eq=False)
class PtvResult:
    """Everything :func:`run_pipeline` measured.

    Attributes
    ----------
    source : FrameDetections
        The detections processed (``source.folder``: the dataset or store).
    cameras : tuple of str
        Camera order of the count arrays.
    settings : PipelineSettings
        Options used.
    runs : list of RunParticles
        Particles per Δt (all Δt of the dataset).
    statistics : PtvStatistics or None
        The statistics (None when only positions and links were asked for).
    matched : MatchedPoints or None
        The matched points of the frames measured (:func:`run_pipeline`: every frame of
        every Δt, frame a repeated at each Δt that shares it).
    recording : RecordingTracks or None
        The tracks through every frame of a time-resolved recording
        (:func:`ptv.tracking.recording.run_recording`; None otherwise).
    """

    source: FrameDetections
    cameras: tuple[str, ...]
    settings: PipelineSettings
    runs: list[RunParticles]
    statistics: PtvStatistics | None
    matched: MatchedPoints | None = None
    recording: RecordingTracks | None = None


def run_pipeline(
    frames: FrameDetections,
    calibrations: Mapping[str, CameraModel],
    settings: PipelineSettings | None = None,
    *,
    progress: Progress | None = None,
    statistics: bool = True,
) -> PtvResult:
    """Detections → matches → links → S2(r), ε, u′ for a whole dataset.

    Parameters
    ----------
    frames : FrameDetections
        E.g. :class:`ptv.pipeline.frames.ImageDetector` of :func:`ptv.io.dataset.open_dataset`.
    calibrations : mapping of camera name to CameraModel
        E.g. :func:`ptv.calibration.io.load_calibrations`; must name exactly the
        dataset's cameras.
    settings : PipelineSettings, optional
        Options (defaults: the paper's volumes and ranges).
    progress : callable(done, total), optional
        Called after each snapshot of each Δt and after the statistics.
    statistics : bool
        Compute the statistics (False: positions and links only).

    Returns
    -------
    PtvResult

    Raises
    ------
    DatasetError
        "cameras don't match the calibration".
    ValueError
        Nothing left to compute statistics on.
    """
    settings = PipelineSettings() if settings is None else settings
    cameras = cameras_in_order(frames, calibrations)
    if settings.min_cameras > len(cameras):
        raise ValueError(
            f"min_cameras is {settings.min_cameras} but the dataset has {len(cameras)} cameras"
        )
    total = sum(settings.snapshot_count(n) for n in frames.frames) + 1
    done = [0]

    def tick() -> None:
        done[0] += 1
        if progress is not None:
            progress(done[0], total)

    measured = measure_snapshots(
        frames, range(max(frames.frames)), cameras, settings, tick=tick, keep_matched=True
    )
    runs = [
        run_particles(k, float(frames.dt[k]), measured[k], len(cameras), settings)
        for k in range(len(frames.dt))
    ]
    for run in runs:
        log.info(
            "Δt_%d = %.4g s: %d snapshots, %d links (%d outliers; %d used), %d skipped",
            run.k,
            run.dt,
            len(run.processed),
            len(run.positions),
            int(run.outlier.sum()),
            int(run.used.sum()),
            len(run.skipped),
        )
    computed = (
        compute_statistics(runs, settings.statistics, shared_first_frame=frames.shared_first_frame)
        if statistics
        else None
    )
    tick()
    return PtvResult(
        source=frames,
        cameras=tuple(frames.cameras),
        settings=settings,
        runs=runs,
        statistics=computed,
        matched=MatchedPoints.from_frames(
            (s.k, s.m, f, points)
            for run in measured
            for s in run
            for f, points in enumerate(s.matched)
        ),
    )
