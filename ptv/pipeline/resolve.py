"""The settings of the double-frame PTV that follow the rig and the data, resolved
before the snapshots are measured: the fewest cameras per match (from the camera
count), the matching tolerance (:mod:`ptv.matching.tolerance`), the largest particle
speed (:mod:`ptv.tracking.link_speed`) and, with a shared first frame, the radius
around each larger Δt's predicted links (:mod:`ptv.tracking.link_prediction`), each as
the settings give it or derived; and :func:`match_frame`, which matches one frame with
them."""

import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from ptv.camera_model import CameraModel
from ptv.detect.frames import FrameDetections
from ptv.matching.stereo import match
from ptv.matching.tolerance import MatchTolerance, match_tolerance
from ptv.pipeline.link_radii import link_radius
from ptv.settings import PipelineSettings, default_min_cameras
from ptv.tracking.link_prediction import LinkPrediction, measure_prediction
from ptv.tracking.link_speed import LinkSpeed, link_speed

__all__ = [
    "LINK_SPEED_SNAPSHOTS",
    "MeasuredSettings",
    "match_frame",
    "resolve_matching",
    "resolve_settings",
    "settings_with_measured_speed",
]

log = logging.getLogger(__name__)

#: Snapshots of the smallest Δt whose matches measure the tolerance, and whose links
#: max_speed, when the settings leave them out.
LINK_SPEED_SNAPSHOTS = 5


@dataclass(frozen=True)
class MeasuredSettings:
    """What :func:`resolve_settings` measured on the data.

    Attributes
    ----------
    tolerance : MatchTolerance or None
        How the matching tolerance was measured (None when the settings gave it).
    link_speed : LinkSpeed or None
        How max_speed was measured (None when the settings gave it).
    link_prediction : LinkPrediction or None
        How the radii around the predicted links were measured (None when the settings
        gave them, or without a shared first frame).
    """

    tolerance: MatchTolerance | None = None
    link_speed: LinkSpeed | None = None
    link_prediction: LinkPrediction | None = None


def resolve_matching(
    frames: FrameDetections, cameras: Sequence[CameraModel], settings: PipelineSettings
) -> tuple[PipelineSettings, MatchTolerance | None]:
    """The settings with min_cameras and the matching tolerance known: as given, or from
    the camera count (:func:`ptv.settings.default_min_cameras`) and measured on
    frame a of the first :data:`LINK_SPEED_SNAPSHOTS` snapshots of the smallest Δt
    (:func:`ptv.matching.tolerance.match_tolerance`).

    Parameters
    ----------
    frames : FrameDetections
        The detections.
    cameras : sequence of CameraModel
        Calibrations in the order of ``frames.cameras``.
    settings : PipelineSettings
        Options; min_cameras and tolerance None to derive them.

    Returns
    -------
    (PipelineSettings, MatchTolerance or None)
        The settings with both set, and the measurement (None when the settings gave the
        tolerance).

    Raises
    ------
    ValueError
        A camera does not image the matching volume's centre, or no particle matched.
    """
    if settings.min_cameras is None:
        settings = replace(settings, min_cameras=default_min_cameras(len(cameras)))
    if settings.tolerance is not None:
        return settings, None
    k = int(np.argmin(frames.dt))
    count = min(LINK_SPEED_SNAPSHOTS, settings.snapshot_count(frames.frames[k]))
    sample = [frames.detections(k, m, "a") for m in range(count)]
    try:
        measured = match_tolerance(
            cameras, sample, settings.volume, min_cameras=settings.min_cameras
        )
    except ValueError as err:
        raise ValueError(f"matching tolerance, Δt_{k} = {frames.dt[k]:.4g} s: {err}") from None
    log.info(
        "matching tolerance %.3g µm (%.3g px of %.3g µm; median ray distance %.3g µm on "
        "%d rays of %d frames)",
        measured.tolerance * 1e6,
        measured.tolerance / measured.pixel_footprint,
        measured.pixel_footprint * 1e6,
        measured.median_ray_distance * 1e6,
        measured.rays,
        measured.frames,
    )
    return replace(settings, tolerance=measured.tolerance), measured


#: What gives a frame's 3-D points: (k, m, frame) → (particles seen per camera, points
#: (N, 3) m).
Locate = Callable[[int, int, str], tuple[list[int], np.ndarray]]


def match_detections(
    frames: FrameDetections, cameras: Sequence[CameraModel], settings: PipelineSettings
) -> Locate:
    """The default :data:`Locate`: a frame's detections, matched across the cameras
    (:func:`match_frame`); the counts are the detections per camera."""

    def locate(k: int, m: int, frame: str) -> tuple[list[int], np.ndarray]:
        xy = frames.detections(k, m, frame)
        return [len(v) for v in xy], match_frame(xy, cameras, settings)

    return locate


def resolve_settings(
    frames: FrameDetections,
    cameras: Sequence[CameraModel],
    settings: PipelineSettings,
    *,
    locate: Locate | None = None,
) -> tuple[PipelineSettings, MeasuredSettings]:
    """The settings with min_cameras, the tolerance and max_speed known: as given, or
    derived from the rig and measured on the data.

    min_cameras and the tolerance come from :func:`resolve_matching`. When
    ``settings.max_speed`` is None, the first :data:`LINK_SPEED_SNAPSHOTS` snapshots of
    the smallest Δt with matched particles in both frames are matched and their links
    measure it (:func:`ptv.tracking.link_speed.link_speed`). When every Δt shares frame
    a and ``settings.predicted_radii`` is None, the first such snapshots with matched
    particles in every frame measure how far each larger Δt's links miss their
    prediction from the next smaller Δt
    (:func:`ptv.tracking.link_prediction.measure_prediction`).

    Parameters
    ----------
    frames : FrameDetections
        The detections.
    cameras : sequence of CameraModel
        Calibrations in the order of ``frames.cameras``.
    settings : PipelineSettings
        Options; min_cameras, tolerance, max_speed and predicted_radii None to derive
        them.
    locate : Locate, optional
        What gives a frame's points (e.g. a reconstruction of its images); then the
        matching is not resolved (no detections are matched). Default: the
        detections matched (:func:`match_detections`).

    Returns
    -------
    (PipelineSettings, MeasuredSettings)
        The settings with all of them set (predicted_radii only with a shared first
        frame), and what was measured.

    Raises
    ------
    ValueError
        No particle matched at the tolerance's floor; no snapshot of the smallest Δt with
        matched particles in both frames, or too few links in them to measure a speed;
        too few predicted links to measure their misses.
    """
    tolerance = None
    if locate is None:
        settings, tolerance = resolve_matching(frames, cameras, settings)
        locate = match_detections(frames, cameras, settings)
    speed = None
    if settings.max_speed is None:
        settings, speed = _with_measured_speed(frames, locate, settings)
    prediction = None
    if frames.shared_first_frame and len(frames.dt) > 1 and settings.predicted_radii is None:
        settings, prediction = _with_prediction_radii(frames, locate, settings)
    return settings, MeasuredSettings(
        tolerance=tolerance, link_speed=speed, link_prediction=prediction
    )


def _with_measured_speed(
    frames: FrameDetections, locate: Locate, settings: PipelineSettings
) -> tuple[PipelineSettings, LinkSpeed]:
    """max_speed measured on the first snapshots of the smallest Δt (resolve_settings)."""
    k = int(np.argmin(frames.dt))
    pairs = []
    for m in range(settings.snapshot_count(frames.frames[k])):
        a, b = (locate(k, m, f)[1] for f in "ab")
        if len(a) >= 2 and len(b):
            pairs.append((a, b))
        if len(pairs) == LINK_SPEED_SNAPSHOTS:
            break
    if not pairs:
        raise ValueError(
            f"no snapshot at Δt_{k} = {frames.dt[k]:.4g} s has matched particles in both "
            "frames: nothing to link (check the images, the detection settings and that the "
            "calibration is of this rig)"
        )
    return settings_with_measured_speed(settings, pairs, k, float(frames.dt[k]))


def _with_prediction_radii(
    frames: FrameDetections, locate: Locate, settings: PipelineSettings
) -> tuple[PipelineSettings, LinkPrediction]:
    """The radii around the predicted links of every larger Δt, measured on the first
    :data:`LINK_SPEED_SNAPSHOTS` snapshots with matched points in every frame."""
    dt = np.asarray(frames.dt, dtype=float)
    count = min(settings.snapshot_count(n) for n in frames.frames)
    snapshots = []
    for m in range(count):
        a = locate(0, m, "a")[1]
        b = [locate(k, m, "b")[1] for k in range(len(dt))]
        if len(a) >= 2 and all(len(p) for p in b):
            snapshots.append((a, b))
        if len(snapshots) == LINK_SPEED_SNAPSHOTS:
            break
    if not snapshots:
        raise ValueError(
            "no snapshot has matched particles in frame a and in frame b of every Δt: "
            "nothing to measure the predicted links on"
        )
    first = int(np.argmin(dt))
    prediction = measure_prediction(
        snapshots,
        dt,
        first_radius=link_radius(float(dt[first]), settings),
        search_radius=lambda step: link_radius(step, settings),
    )
    return replace(settings, predicted_radii=tuple(prediction.radii.tolist())), prediction


def settings_with_measured_speed(
    settings: PipelineSettings, pairs: Sequence[tuple[np.ndarray, np.ndarray]], k: int, dt: float
) -> tuple[PipelineSettings, LinkSpeed]:
    """The settings with max_speed measured on the matched points of some snapshots at Δt_k.

    Parameters
    ----------
    settings : PipelineSettings
        Options (position_noise is used).
    pairs : sequence of (ndarray (N_a, 3), ndarray (N_b, 3))
        Matched points of frames a and b of each snapshot, m.
    k : int
        Their Δt index (for the messages).
    dt : float
        Their Δt, s.

    Returns
    -------
    (PipelineSettings, LinkSpeed)

    Raises
    ------
    ValueError
        Too few particles to measure a speed.
    """
    try:
        measured = link_speed(pairs, dt, position_noise=settings.position_noise)
    except ValueError as err:
        raise ValueError(f"Δt_{k} = {dt:.4g} s: {err}") from None
    log.info(
        "max_speed %.3g m/s, measured on %d links of %d snapshots at Δt_%d = %.4g s "
        "(mean velocity %s m/s, rms %s m/s; particle spacing %.3g mm)",
        measured.max_speed,
        measured.links,
        measured.snapshots,
        k,
        measured.dt,
        np.round(measured.mean_velocity, 4).tolist(),
        np.round(measured.velocity_rms, 4).tolist(),
        measured.spacing * 1e3,
    )
    return replace(settings, max_speed=measured.max_speed), measured


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
        Matching volume, tolerance and fewest cameras per match (known:
        :func:`resolve_matching`).

    Returns
    -------
    ndarray, shape (N, 3)
        Matched points, m.
    """
    if len(xy) != len(cameras):
        raise ValueError(f"need detections per camera, got {len(xy)} for {len(cameras)} cameras")
    if settings.tolerance is None or settings.min_cameras is None:
        raise ValueError("the tolerance and min_cameras are not known yet: resolve_matching")
    return match(
        cameras,
        list(xy),
        settings.volume,
        tolerance=settings.tolerance,
        min_cameras=settings.min_cameras,
    ).points
