"""Every frame of a time-resolved recording: matched points linked into tracks.

A recording (experiment.json ``time_resolved``, :mod:`ptv.io.sequence`) holds consecutive
frames n = first … last, τ = 1 / frame rate apart. :func:`run_recording`

1. detects the particles on every frame of every camera (all of them, or those the
   first ``snapshots`` frame pairs span) and matches the cameras in each frame
   (:func:`ptv.pipeline.resolve.match_frame`): the 3-D points of every frame;
2. links them frame to frame into tracks (:func:`ptv.tracking.linking.track_frames`): the first
   link of a track within r = max_speed·τ + 5σ_b (the double-frame link radius at
   Δt = τ), a longer track within r_p = max_acceleration·τ² + 5√6·σ_b of its
   constant-velocity prediction (:func:`track_radii`; the acceleration term no more
   than 2·max_speed·τ), a track missing from up to
   ``track_gap`` frames (a particle not detected or not matched there) continued across
   the gap, s frames ahead within max_acceleration·τ²·s(s + 1)/2 + 5√6·σ_b·√((s² + s +
   1)/3) (:func:`ptv.tracking.linking.predicted_radii`), each candidate weighed by
   where it leads one frame further (the look-ahead); then tracks that continue one
   another once the last point of the earlier is left out are joined
   (:func:`ptv.tracking.stitching.stitch_tracks`: a false point taken where the particle
   was missed);
3. processes the frame pairs of the multi-Δt method (:func:`ptv.pipeline.double_frame.run_pipeline`)
   from the same detections, so that no image is read or detected twice.

Why 5√6·σ_b: the prediction 2X_f − X_{f−1} and the point it meets carry the noise of
three positions, √6·σ_b per component, and r_p allows five times that. The radius
bounds a 3-D miss, whose length follows a χ law of three degrees of freedom: five σ per
component leave it outside with probability 1.5·10⁻⁵. The 5√3·σ_b used before (3.5σ
per component) lost 0.6 % of the links, which split 11 % of the trajectories of a
50-frame recording in two (``benchmarks/bench_tracking.py``). The a τ² term is the most
a particle of acceleration up to max_acceleration leaves the prediction.
"""

import logging
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np

from ptv.camera_model import CameraModel
from ptv.detect.frames import ChunkDetections, DetectedCentres, ImageDetector, exposures
from ptv.errors import DatasetError
from ptv.io.dataset import cameras_in_order
from ptv.pipeline.double_frame import PtvResult, run_pipeline
from ptv.pipeline.link_radii import link_radius
from ptv.pipeline.resolve import match_frame, resolve_matching
from ptv.settings import PipelineSettings
from ptv.tracking.linking import RecordingTracks, Tracks, track_frames
from ptv.tracking.stitching import stitch_tracks

__all__ = [
    "MISS_NOISE_FACTOR",
    "LinkedPoints",
    "RecordedFrames",
    "measure_recording",
    "pair_detections",
    "prediction_noise",
    "run_recording",
    "track_points",
    "track_radii",
]

log = logging.getLogger(__name__)

#: The tracks' position noise, as a multiple of the rms of their prediction misses over
#: √6: the misses of rendered recordings have a kurtosis of about 6 (overlapping particle
#: images), not 3, and twice the rms kept fragmentation at its least and mislinks at a
#: third of the settings' default on the tr recording (docs/ptv.md §4).
MISS_NOISE_FACTOR = 2.0
#: Fewest prediction misses that measure the noise.
MIN_MISSES = 100

Progress = Callable[[int, int], None]


@dataclass(frozen=True, eq=False)
class RecordedFrames:
    """The detections and matched points of consecutive frames of a recording.

    Attributes
    ----------
    numbers : ndarray of int, shape (F,)
        Frame numbers n, consecutive.
    centres : tuple of F tuples of C DetectedCentres
        The particle image centres of each frame on each camera, px.
    points : tuple of F ndarray, shape (N_f, 3)
        The matched points of each frame, m, in the calibration's frame.
    """

    numbers: np.ndarray
    centres: tuple[tuple[DetectedCentres, ...], ...]
    points: tuple[np.ndarray, ...]

    @property
    def detections(self) -> np.ndarray:
        """Particles detected per frame and camera, shape (F, C)."""
        counts = [[len(c.xy) for c in frame] for frame in self.centres]
        return np.asarray(counts, dtype=np.int64).reshape(len(self.numbers), -1)


def measure_recording(
    detector: ImageDetector,
    cameras: Sequence[CameraModel],
    settings: PipelineSettings,
    numbers: Sequence[int],
    *,
    tick: Callable[[], None] | None = None,
) -> RecordedFrames:
    """Detect and match the particles of the recorded frames ``numbers``.

    Parameters
    ----------
    detector : ImageDetector
        Of a time-resolved dataset.
    cameras : sequence of CameraModel
        Calibrations in the order of ``detector.cameras``.
    settings : PipelineSettings
        Matching volume, tolerance and fewest cameras per match.
    numbers : sequence of int
        Frame numbers, consecutive.
    tick : callable, optional
        Called after each frame.

    Returns
    -------
    RecordedFrames
    """
    centres, points = [], []
    for n in numbers:
        found = detector.detect_recorded(n)
        centres.append(tuple(DetectedCentres.of(d) for d in found))
        points.append(match_frame([d.xy for d in found], cameras, settings))
        if tick is not None:
            tick()
    return RecordedFrames(np.asarray(numbers, dtype=np.int64), tuple(centres), tuple(points))


def pair_detections(
    detector: ImageDetector, recorded: RecordedFrames, snapshots: int
) -> ChunkDetections:
    """The frame pairs of the first ``snapshots`` snapshots, from the detections of the
    recorded frames (which must include every frame they use)."""
    sequence = detector.dataset.sequence
    row = {int(n): i for i, n in enumerate(recorded.numbers)}
    found = {
        (k, m, frame): recorded.centres[row[sequence.frame_number(max(k, 0), m, frame)]]
        for k, m, frame in exposures(detector.frames, range(snapshots), shared_first_frame=True)
    }
    return ChunkDetections.of(detector, (0, snapshots), found)


def track_radii(frame_rate: float, settings: PipelineSettings) -> tuple[float, float, float]:
    """The search radii of :func:`ptv.tracking.linking.track_frames` at a frame rate, m.

    Returns
    -------
    (float, float, float)
        The first link's r = max_speed·τ + 5σ_b, the constant-velocity prediction's
        r_p = min(max_acceleration·τ², 2·max_speed·τ) + 5√6·σ_b one frame ahead, and
        the part 5√6·σ_b of it from the noise, τ = 1 / frame_rate (module docstring).
        The prediction X_f + (X_f − X_{f−1}) misses by τ times the change of the
        velocity over one frame, which is at most 2·max_speed: in a slow flow at a low
        frame rate the acceleration bound can ask more than that (100 m/s² over 30 ms
        is 90 mm), and then the speed bounds the radius.
    """
    tau = 1.0 / frame_rate
    noise = 5 * np.sqrt(6) * settings.position_noise
    reach = link_radius(tau, settings)
    change = min(settings.max_acceleration * tau**2, 2 * settings.max_speed * tau)
    return reach, float(change + noise), float(noise)


@dataclass(frozen=True, eq=False)
class LinkedPoints:
    """What :func:`track_points` gives.

    Attributes
    ----------
    tracks : Tracks
    joins : int
        Tracks joined (:func:`ptv.tracking.stitching.stitch_tracks`).
    radius, predicted_radius : float
        The first link's radius and the prediction's one frame ahead, m.
    miss_noise : float or None
        σ̂ of the first pass's prediction misses (:func:`prediction_noise`), m.
    """

    tracks: Tracks
    joins: int
    radius: float
    predicted_radius: float
    miss_noise: float | None


def prediction_noise(tracks: Tracks) -> float | None:
    """The noise of tracks' constant-velocity predictions one frame ahead, m.

    The miss X_{f+1} − (2X_f − X_{f−1}) of every three consecutive points of a track has
    variance 6σ_c² per component for white noise of σ_c (the acceleration adds a τ²,
    negligible at a frame rate that tracks). Returns the largest over the components of
    rms(miss_c)/√6, the rms taken over every miss, tails included; None with fewer than
    :data:`MIN_MISSES` misses.
    """
    t, f, x = tracks.track, tracks.frame, tracks.positions
    whole = (t[2:] == t[:-2]) & (f[2:] - f[:-2] == 2) & (f[1:-1] - f[:-2] == 1)
    if np.count_nonzero(whole) < MIN_MISSES:
        return None
    miss = (x[2:] - 2 * x[1:-1] + x[:-2])[whole]
    return float(np.sqrt(np.mean(miss**2, axis=0)).max() / np.sqrt(6))


def _link(points, radius: float, predicted: float, noise: float, gap: int):
    tracks = track_frames(
        points, radius=radius, predicted_radius=predicted, predicted_noise=noise, gap=gap
    )
    return stitch_tracks(tracks, predicted_radius=predicted, predicted_noise=noise, gap=gap)


def track_points(
    points: Sequence[np.ndarray], frame_rate: float, settings: PipelineSettings
) -> LinkedPoints:
    """Link the matched points of consecutive frames into tracks, in two passes.

    The first pass links with the radii of the settings (:func:`track_radii`), whose
    position noise is a guess made before the data; the second with the noise the
    first pass's tracks show, :data:`MISS_NOISE_FACTOR` × :func:`prediction_noise`,
    where that is smaller. Each pass is :func:`ptv.tracking.linking.track_frames`, then
    :func:`ptv.tracking.stitching.stitch_tracks`.

    Parameters
    ----------
    points : sequence of F ndarray, shape (N_f, 3)
        The matched points of each frame, m.
    frame_rate : float
        Hz.
    settings : PipelineSettings
        max_speed (measured or given), position_noise, max_acceleration, track_gap.

    Returns
    -------
    LinkedPoints
    """
    radius, predicted, noise = track_radii(frame_rate, settings)
    tracks, joins = _link(points, radius, predicted, noise, settings.track_gap)
    sigma = prediction_noise(tracks)
    if sigma is not None and MISS_NOISE_FACTOR * sigma < settings.position_noise:
        measured = replace(settings, position_noise=MISS_NOISE_FACTOR * sigma)
        _, predicted, noise = track_radii(frame_rate, measured)
        tracks, joins = _link(points, radius, predicted, noise, settings.track_gap)
        log.info(
            "tracks: prediction noise %.3g µm, radius one frame ahead %.3g µm",
            sigma * 1e6,
            predicted * 1e6,
        )
    return LinkedPoints(tracks, joins, radius, predicted, sigma)


def run_recording(
    detector: ImageDetector,
    calibrations: Mapping[str, CameraModel],
    settings: PipelineSettings | None = None,
    *,
    progress: Progress | None = None,
    statistics: bool = True,
) -> PtvResult:
    """The tracks of a time-resolved recording, and what :func:`run_pipeline` gives of
    its frame pairs.

    Parameters
    ----------
    detector : ImageDetector
        Of a dataset with a ``time_resolved`` recording.
    calibrations : mapping of camera name to CameraModel
        Must name exactly the dataset's cameras.
    settings : PipelineSettings, optional
        Options; with ``snapshots``, only the frames of the first snapshots are tracked.
    progress : callable(done, total), optional
        Called after each frame and then as :func:`run_pipeline` calls it.
    statistics : bool
        Compute the statistics of the frame pairs (False: positions and links only).

    Returns
    -------
    PtvResult
        With ``recording``.

    Raises
    ------
    DatasetError
        Not a time-resolved dataset; cameras that do not match the calibration.
    FileNotFoundError
        A frame of the recording is missing.

    Examples
    --------
    A time-resolved recording written here: two cameras (Tsai, ±20° about Y) image 12
    particles moving at 0.2 m/s along X in six frames at 1 kHz, cut into frame pairs of
    Δt = 1 and 2 ms. Every particle is one track through the six frames:

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
    ...         "time_resolved": {"frame_rate": 1000.0, "images": "{camera}_{n}.tif",
    ...                           "steps": [1, 2], "last": 5}}
    >>> _ = (folder / "experiment.json").write_text(json.dumps(spec))
    >>> for n in range(6):
    ...     for name, cam in rig.items():
    ...         tifffile.imwrite(folder / f"{name}_{n}.tif", image(x + u * n / 1000.0, cam))
    >>> settings = ptv.PipelineSettings(volume=((-6e-3,) * 3, (6e-3,) * 3),
    ...                                 tolerance=1e-4, max_speed=0.5)
    >>> detector = ptv.ImageDetector(ptv.open_dataset(folder))
    >>> result = ptv.run_recording(detector, rig, settings, statistics=False)
    >>> tracks = result.recording.tracks
    >>> tracks.n_tracks, tracks.lengths
    (12, array([6, 6, 6, 6, 6, 6, 6, 6, 6, 6, 6, 6]))
    >>> result.recording.time[tracks.track == 0]  # s
    array([0.   , 0.001, 0.002, 0.003, 0.004, 0.005])
    >>> [len(run.positions) for run in result.runs]  # links of the frame pairs per Δt
    [24, 24]
    >>> tmp.cleanup()
    """
    settings = PipelineSettings() if settings is None else settings
    sequence = detector.dataset.sequence
    if sequence is None:
        raise DatasetError(f"{detector.folder}: frame pairs, not a time-resolved recording")
    cameras = cameras_in_order(detector, calibrations)
    numbers = sequence.frame_numbers(settings.snapshots)
    missing = detector.dataset.missing_recorded(numbers)
    if missing:
        more = f" (and {len(missing) - 1} more)" if len(missing) > 1 else ""
        raise FileNotFoundError(f"particle image {missing[0]} is missing{more}")
    # One count for all: the frames, then the steps of run_pipeline (its snapshots + 1).
    steps = len(numbers) + sum(settings.snapshot_count(n) for n in detector.frames) + 1
    done = [0]

    def tick() -> None:
        done[0] += 1
        if progress is not None:
            progress(done[0], steps)

    settings, tolerance = resolve_matching(detector, cameras, settings)
    recorded = measure_recording(detector, cameras, settings, numbers, tick=tick)
    pairs = pair_detections(detector, recorded, settings.snapshot_count(sequence.snapshots))

    def pairs_progress(done_pairs: int, total: int) -> None:
        if progress is not None:
            progress(len(numbers) + done_pairs, len(numbers) + total)

    result = run_pipeline(
        pairs, calibrations, settings, progress=pairs_progress, statistics=statistics
    )
    linked = track_points(recorded.points, sequence.frame_rate, result.settings)
    tracks = linked.tracks
    log.info(
        "frames %d … %d: %d points in %d tracks (%d links)",
        numbers[0],
        numbers[-1],
        len(tracks),
        tracks.n_tracks,
        tracks.links,
    )
    recording = RecordingTracks(
        numbers=recorded.numbers,
        frame_rate=sequence.frame_rate,
        detections=recorded.detections,
        tracks=tracks,
        radius=linked.radius,
        predicted_radius=linked.predicted_radius,
        gap=result.settings.track_gap,
        joins=linked.joins,
        miss_noise=linked.miss_noise,
    )
    measured = replace(result.measured, tolerance=tolerance)
    return replace(result, recording=recording, measured=measured)
