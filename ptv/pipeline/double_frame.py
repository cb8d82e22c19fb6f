"""Double-frame 3D-PTV, from detected particles to links, then to S2(r), ε and u′.

The particles detected on every frame come from a :class:`ptv.detect.frames.FrameDetections`
source (detected from a dataset's images, or read from a detection store). For every
Δt_k and every snapshot m:

1. match the cameras in frame a and in frame b (:func:`ptv.matching.stereo.match`) inside the
   measurement volume (default: the 100 × 100 × 10 mm sheet plus 1 mm) with the stereo
   tolerance: 1.5 pixel footprints at the volume's centre, or 6 median ray distances of
   the matches when the calibration's triangulation error is larger, measured on frame a
   of the first snapshots unless the settings give it (:mod:`ptv.matching.tolerance`,
   :func:`ptv.pipeline.resolve.resolve_matching`); with a shared first frame, frame a of
   snapshot m is matched once for every Δt;
2. link frame a to frame b one-to-one (:func:`ptv.tracking.linking.link`) within the radius
   r_k = max_speed·Δt_k + 5σ_b (σ_b: the position noise, default 30 µm): the Δt-scaled
   threshold of docs/ptv.md §4, which also rejects mismatches with |ΔX| beyond it.
   max_speed is the largest particle speed: measured on the links of the first snapshots
   at the smallest Δt unless the settings give it (:mod:`ptv.tracking.link_speed`,
   :func:`ptv.pipeline.resolve.resolve_settings`). With a shared first frame, each
   larger Δt is linked around the particle's prediction from its link at the next
   smaller Δt instead, within the radius measured on the predictions' misses
   (:mod:`ptv.tracking.link_prediction`). Each snapshot counts its ambiguous
   links (a second candidate within the radius) and the spacing of its particles, and a
   Δt whose links are more than :data:`AMBIGUITY_WARNING` ambiguous is named in a
   warning;
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

from ptv.box import Box, inside_box
from ptv.camera_model import CameraModel
from ptv.detect.frames import FrameDetections
from ptv.io.dataset import cameras_in_order
from ptv.pipeline.link_radii import link_radius, predicted_radius, radius_at
from ptv.pipeline.resolve import (
    Locate,
    MeasuredSettings,
    match_detections,
    resolve_settings,
)
from ptv.settings import PipelineSettings
from ptv.stats.links import RunParticles
from ptv.stats.run_statistics import PtvStatistics, compute_statistics
from ptv.tracking.link_prediction import chained_link
from ptv.tracking.link_speed import nearest_spacing
from ptv.tracking.linking import RecordingTracks, link
from ptv.tracking.outliers import median_test_outliers

__all__ = [
    "AMBIGUITY_WARNING",
    "MatchedPoints",
    "PtvResult",
    "SnapshotMeasurement",
    "ambiguity_message",
    "measure_snapshot",
    "measure_snapshots",
    "run_particles",
    "run_pipeline",
]

log = logging.getLogger(__name__)

Progress = Callable[[int, int], None]

#: A Δt whose links have a second candidate within the radius more often than this is
#: named in a warning. Half the links is where the radius reaches the median
#: nearest-neighbour spacing (by that spacing's definition): a particle whose partner was
#: lost then finds a stranger, and with a radius of 5 rms displacements a stranger is
#: closer than the true partner for about 3.5 % of the links (n·4π/3·⟨|ΔX|³⟩ at a density
#: n that puts half the particles within 5σ of a neighbour). Below it, second candidates
#: are common (30 % at the largest Δt of a correctly linked slow flow) and harmless: the
#: assignment picks the partner.
AMBIGUITY_WARNING = 0.5


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
    ambiguous : int
        Links whose particle of frame a had a second candidate within the link radius.
    spacing : float
        Median nearest-neighbour distance of the matched points of frame a, m (nan
        below two points).
    rows_a : ndarray of int, shape (N,), or None
        Row of each link's particle among the matched points of frame a (None once
        :meth:`within` dropped links): what predicts the links of a larger Δt.
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
    ambiguous: int = 0
    spacing: float = float("nan")
    rows_a: np.ndarray | None = None

    def within(self, box: Box) -> "SnapshotMeasurement":
        """The same measurement keeping only the links whose X(t) lies in ``box``."""
        keep = inside_box(self.positions, box)
        return replace(
            self,
            positions=self.positions[keep],
            displacements=self.displacements[keep],
            outlier=self.outlier[keep],
            rows_a=None,
        )


def measure_snapshot(
    frames: FrameDetections,
    k: int,
    m: int,
    cameras: Sequence[CameraModel],
    settings: PipelineSettings,
    *,
    frame_a: tuple[list[int], np.ndarray] | None = None,
    keep_matched: bool = False,
    previous: "SnapshotMeasurement | None" = None,
    locate: Locate | None = None,
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
    previous : SnapshotMeasurement, optional
        The same snapshot measured at a smaller Δt from the same frame a: its links'
        displacements predict this Δt's, searched within ``settings.predicted_radii[k]``
        of the prediction (:func:`ptv.tracking.link_prediction.chained_link`); without
        it, or without that radius, links are searched within max_speed·Δt_k + 5σ_b of
        X(t).
    locate : callable (k, m, frame) -> (list of int, ndarray (N, 3)), optional
        What gives a frame's 3-D points and the particles seen per camera (e.g. a
        reconstruction of the frame's images, :mod:`ptv.pipeline.reconstructed`);
        default: the frame's detections matched (:func:`match_detections`).

    Returns
    -------
    SnapshotMeasurement
        With no links when a frame has no match.
    """
    if len(cameras) != len(frames.cameras):
        raise ValueError(
            f"need one calibration per camera: {len(cameras)} for {len(frames.cameras)} cameras"
        )
    if locate is None:
        locate = match_detections(frames, cameras, settings)
    points, detections = [], []
    for frame in ("a", "b"):
        if frame == "a" and frame_a is not None:
            counts, matched = frame_a
        else:
            counts, matched = locate(k, m, frame)
        detections.append(counts)
        points.append(matched)
    dt = float(frames.dt[k])
    ambiguous = 0
    rows_a = np.empty(0, dtype=np.int64)
    predicted = predicted_radius(k, settings)
    if len(points[0]) and len(points[1]):
        if previous is not None and predicted is not None:
            step = (float(frames.dt[previous.k]), previous.rows_a, previous.displacements)
            links = chained_link(points[0], points[1], dt, step, radius=predicted)
        else:
            links = link(points[0], points[1], radius=link_radius(dt, settings))
        positions, displacements, ambiguous = links.positions, links.displacements, links.ambiguous
        rows_a = links.index_a
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
        ambiguous=ambiguous,
        spacing=nearest_spacing(points[0]),
        rows_a=rows_a,
    )


def measure_snapshots(
    frames: FrameDetections,
    snapshots: Sequence[int],
    cameras: Sequence[CameraModel],
    settings: PipelineSettings,
    *,
    tick: Callable[[], None] | None = None,
    keep_matched: bool = False,
    locate: Locate | None = None,
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
    locate : callable (k, m, frame) -> (list of int, ndarray (N, 3)), optional
        As :func:`measure_snapshot`.

    Returns
    -------
    list of K lists of SnapshotMeasurement
        Per Δt, the snapshots measured in the order given.
    """
    if locate is None:
        locate = match_detections(frames, cameras, settings)
    out: list[list[SnapshotMeasurement]] = [[] for _ in frames.dt]
    shared = frames.shared_first_frame
    # With a shared first frame the Δt are measured from the smallest up, each predicted
    # from the last one linked; otherwise in the dataset's order, each on its own.
    order = np.argsort(frames.dt, kind="stable") if shared else range(len(frames.dt))
    for m in snapshots:
        frame_a = None  # with a shared first frame, matched once for every k
        previous = None
        measured = {}
        for k in order:
            k = int(k)
            if m >= settings.snapshot_count(frames.frames[k]):
                continue
            if shared and frame_a is None:
                frame_a = locate(k, m, "a")
            measured[k] = measure_snapshot(
                frames,
                k,
                m,
                cameras,
                settings,
                frame_a=frame_a,
                keep_matched=keep_matched,
                previous=previous,
                locate=locate,
            )
            if shared:
                previous = measured[k]
            if tick is not None:
                tick()
        for k, measurement in sorted(measured.items()):
            out[k].append(measurement)
    return out


# ------------------------------------------------------------------------------ per run


def run_particles(
    k: int,
    dt: float,
    measured: Sequence[SnapshotMeasurement],
    n_cameras: int,
    settings: PipelineSettings,
    *,
    speed_measured: bool = False,
) -> RunParticles:
    """The links of the run at Δt_k from its measured snapshots, in snapshot order.

    Snapshots without a match in a frame, or without a link, are skipped with a warning,
    and a Δt whose links are more than :data:`AMBIGUITY_WARNING` ambiguous is named in one
    (:func:`ambiguity_message`).

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
    speed_measured : bool
        max_speed was measured on the data
        (:func:`ptv.pipeline.resolve.resolve_settings`), not given: the
        ambiguity warning then advises on the data rather than the setting.

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
                radius_at(k, dt, settings) * 1e3,
            )
        else:
            kept.append(res)
    sizes = [len(r.positions) for r in kept]
    positions = np.concatenate([r.positions for r in kept]) if kept else np.empty((0, 3))
    displacements = np.concatenate([r.displacements for r in kept]) if kept else np.empty((0, 3))
    outlier = np.concatenate([r.outlier for r in kept]) if kept else np.empty(0, dtype=bool)
    run = RunParticles(
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
        ambiguous=np.asarray([r.ambiguous for r in measured], dtype=np.int64),
        spacing=np.asarray([r.spacing for r in measured], dtype=np.float64),
    )
    message = ambiguity_message(run, settings, speed_measured=speed_measured)
    if message is not None:
        log.warning(message)
    return run


def ambiguity_message(
    run: RunParticles, settings: PipelineSettings, *, speed_measured: bool
) -> str | None:
    """The warning for a Δt whose links are more than :data:`AMBIGUITY_WARNING` ambiguous
    (None below that).

    Parameters
    ----------
    run : RunParticles
        The run at one Δt, with its ambiguity counts.
    settings : PipelineSettings
        Its settings, max_speed known.
    speed_measured : bool
        max_speed was measured on the data rather than given.
    """
    if not run.ambiguity > AMBIGUITY_WARNING:
        return None
    spacing = np.nanmedian(run.spacing) if np.isfinite(run.spacing).any() else np.nan
    advice = (
        "the radius follows the measured speed, so the particles move too far between frames "
        "for this seeding: a shorter Δt or fewer particles"
        if speed_measured
        else f"[linking] max_speed = {settings.max_speed:g} m/s was given: leave it out to "
        "measure it on the data, or lower it"
    )
    return (
        f"Δt_{run.k} = {run.dt:.4g} s: {100 * run.ambiguity:.0f} % of the links had a second "
        f"candidate within the link radius ({radius_at(run.k, run.dt, settings) * 1e3:.3g} mm; "
        f"particle spacing {spacing * 1e3:.3g} mm): linking is ambiguous; {advice}"
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
        (:func:`ptv.pipeline.time_resolved.run_recording`; None otherwise).
    measured : MeasuredSettings
        How the tolerance and max_speed were measured on the data (None where the
        settings gave them).
    """

    source: FrameDetections
    cameras: tuple[str, ...]
    settings: PipelineSettings
    runs: list[RunParticles]
    statistics: PtvStatistics | None
    matched: MatchedPoints | None = None
    recording: RecordingTracks | None = None
    measured: MeasuredSettings = field(default_factory=MeasuredSettings)


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
        E.g. :class:`ptv.detect.frames.ImageDetector` of :func:`ptv.io.dataset.open_dataset`.
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

    Examples
    --------
    A dataset folder written here: two cameras (Tsai, ±20° about Y) image 12 particles
    moving at 0.2 m/s along X, one frame pair at each of Δt = 1 and 2 ms.
    The pipeline links every particle at every Δt and measures its velocity (the
    tolerance and max_speed are given: left out, they are measured on the data; the
    statistics need more snapshots):

    >>> import json, pathlib, tempfile
    >>> import numpy as np
    >>> import tifffile
    >>> import ptv
    >>> from scipy.spatial.transform import Rotation
    >>> def camera(angle):  # 0.5 m from the origin, turned ``angle`` degrees about Y
    ...     turn = Rotation.from_euler("y", angle, degrees=True).as_matrix()
    ...     return ptv.TsaiCalibration(turn, [0, 0, 0.5], focal_length=0.05, kappa1=0.0,
    ...                                sx=1.0, principal_point=(63.5, 63.5),
    ...                                pixel_size=(1e-5, 1e-5))
    >>> rig = {"left": camera(-20), "right": camera(20)}
    >>> rows, cols = np.mgrid[:128, :128]
    >>> def image(points, camera):  # spots of σ = 1 px and 2000 DN on 100 ± 2 DN
    ...     xy = camera.project(points)
    ...     spots = [np.exp(-((cols - x) ** 2 + (rows - y) ** 2) / 2) for x, y in xy]
    ...     noise = np.random.default_rng(0).normal(0, 2, rows.shape)
    ...     return (100 + 2000 * np.sum(spots, axis=0) + noise).astype(np.uint16)
    >>> tmp = tempfile.TemporaryDirectory()
    >>> folder = pathlib.Path(tmp.name)
    >>> x = np.random.default_rng(2).uniform(-4e-3, 4e-3, (12, 3))  # particles at t, m
    >>> u = np.array([0.2, 0.0, 0.0])  # their velocity, m/s
    >>> spec = {"cameras": {name: {"image_size": [128, 128]} for name in rig},
    ...         "dt": [1e-3, 2e-3], "frames_per_dt": 1,
    ...         "particle_images": "{camera}_{k}_{m}_{a|b}.tif"}
    >>> _ = (folder / "experiment.json").write_text(json.dumps(spec))
    >>> for k, dt in enumerate(spec["dt"]):  # one frame pair per Δt
    ...     for name, cam in rig.items():
    ...         tifffile.imwrite(folder / f"{name}_{k}_0_a.tif", image(x, cam))
    ...         tifffile.imwrite(folder / f"{name}_{k}_0_b.tif", image(x + u * dt, cam))
    >>> _ = ptv.save_calibrations(folder / "tsai.h5", rig)
    >>> settings = ptv.PipelineSettings(volume=((-6e-3,) * 3, (6e-3,) * 3),
    ...                                 tolerance=1e-4, max_speed=0.5)
    >>> detector = ptv.ImageDetector(ptv.open_dataset(folder))
    >>> calibrations = ptv.load_calibrations(folder / "tsai.h5")
    >>> result = ptv.run_pipeline(detector, calibrations, settings, statistics=False)
    >>> [len(run.positions) for run in result.runs]  # links per Δt
    [12, 12]
    >>> all(np.allclose(run.displacements / run.dt, u, atol=2e-3) for run in result.runs)
    True
    >>> tmp.cleanup()
    """
    settings = PipelineSettings() if settings is None else settings
    cameras = cameras_in_order(frames, calibrations)
    if settings.min_cameras is not None and settings.min_cameras > len(cameras):
        raise ValueError(
            f"min_cameras is {settings.min_cameras} but the dataset has {len(cameras)} cameras"
        )
    settings, measured_settings = resolve_settings(frames, cameras, settings)
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
        run_particles(
            k,
            float(frames.dt[k]),
            measured[k],
            len(cameras),
            settings,
            speed_measured=measured_settings.link_speed is not None,
        )
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
        measured=measured_settings,
    )
