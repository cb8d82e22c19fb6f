"""The options of the double-frame PTV (:mod:`ptv.pipeline.double_frame`): matching
volume and tolerance, linking, the median test, the snapshots processed, the statistics;
and the link radius they give."""

import math
from dataclasses import dataclass, field

from ptv._checks import positive
from ptv.box import Box, check_box
from ptv.stats.run_statistics import StatisticsSettings
from ptv.tracking.linking import search_radius

__all__ = [
    "MEASUREMENT_VOLUME",
    "PipelineSettings",
    "default_min_cameras",
    "link_radius",
    "predicted_radius",
    "radius_at",
]

#: The 100 × 100 × 10 mm laser sheet plus a 1 mm margin, m: the default matching volume.
MEASUREMENT_VOLUME: Box = ((-0.051, -0.051, -0.006), (0.051, 0.051, 0.006))


@dataclass(frozen=True)
class PipelineSettings:
    """Options of :func:`run_pipeline` (SI units).

    Attributes
    ----------
    volume : (lower, upper)
        Matching volume, m (default :data:`MEASUREMENT_VOLUME`).
    tolerance : float or None
        Stereo tolerance on the ray distances, m (default None: measured on the rig and
        the data, :func:`ptv.pipeline.resolve.resolve_matching`).
    min_cameras : int or None
        Fewest cameras a match must use (at most the number of cameras; default None:
        :func:`default_min_cameras` of the camera count).
    max_speed : float or None
        Largest particle speed, m/s: sets the link radius (default None: measured on the
        data, :func:`ptv.pipeline.resolve.resolve_settings`).
    position_noise : float
        Expected position noise σ_b (one component), m: adds 5σ_b to the link radius
        (default 30 µm).
    predicted_radii : tuple of float or None
        With a shared first frame, the radius (m) around each particle's prediction at
        every Δt but the smallest, in the dataset's Δt order (NaN for the smallest): the
        link at a larger Δt is searched around X(t) + ΔX_j·Δt/Δt_j of the particle's link
        at the next smaller Δt_j (:mod:`ptv.tracking.link_prediction`). Default None:
        measured on the data (:func:`ptv.pipeline.resolve.resolve_settings`).
    max_acceleration : float
        Largest particle acceleration expected, m/s²: sets the radius around a track's
        constant-velocity prediction in a time-resolved recording
        (:func:`ptv.tracking.recording.track_radii`; default 100, about 5 times the rms of one
        component in the paper's flows).
    track_gap : int
        Frames a track of a time-resolved recording may miss and still be continued
        (:func:`ptv.tracking.linking.track_frames`; default 3, chosen on the rendered
        tr recording: docs/ptv.md §4).
    outlier_threshold : float or None
        Threshold of the normalised median test on the displacements (default 4; None
        keeps every link).
    outlier_neighbours : int
        Neighbours of the normalised median test (default 8).
    snapshots : int or None
        Process only the first N snapshots of every Δt (None: all).
    statistics : StatisticsSettings
        Analysis volume, bins, plateau, C2, bootstrap (:mod:`ptv.stats.run_statistics`).

    Examples
    --------
    A 100 × 100 × 10 mm sheet, particles no faster than 0.5 m/s, the first 10 snapshots
    of every Δt; the tolerance is left to be measured on the data:

    >>> import ptv
    >>> settings = ptv.PipelineSettings(
    ...     volume=((-0.05, -0.05, -0.005), (0.05, 0.05, 0.005)), max_speed=0.5, snapshots=10
    ... )
    >>> settings.snapshot_count(100), settings.tolerance
    (10, None)
    >>> ptv.PipelineSettings(min_cameras=1)
    Traceback (most recent call last):
    ...
    ValueError: min_cameras must be an integer >= 2, got 1
    """

    volume: Box = MEASUREMENT_VOLUME
    tolerance: float | None = None
    min_cameras: int | None = None
    max_speed: float | None = None
    position_noise: float = 30e-6
    predicted_radii: tuple[float, ...] | None = None
    max_acceleration: float = 100.0
    track_gap: int = 3
    outlier_threshold: float | None = 4.0
    outlier_neighbours: int = 8
    snapshots: int | None = None
    statistics: StatisticsSettings = field(default_factory=StatisticsSettings)

    def __post_init__(self) -> None:
        object.__setattr__(self, "volume", check_box("volume", self.volume))
        for name in ("tolerance", "max_speed", "position_noise", "max_acceleration"):
            if getattr(self, name) is not None:
                object.__setattr__(self, name, positive(name, getattr(self, name)))
        if self.outlier_threshold is not None:
            object.__setattr__(
                self, "outlier_threshold", positive("outlier_threshold", self.outlier_threshold)
            )
        if self.predicted_radii is not None:
            radii = tuple(float(r) for r in self.predicted_radii)
            if not all(r > 0 or math.isnan(r) for r in radii):
                raise ValueError(
                    f"predicted_radii must be > 0 (m; NaN at the smallest Δt), got {radii}"
                )
            object.__setattr__(self, "predicted_radii", radii)
        if self.min_cameras is not None and (
            isinstance(self.min_cameras, bool)
            or not isinstance(self.min_cameras, int)
            or self.min_cameras < 2
        ):
            raise ValueError(f"min_cameras must be an integer >= 2, got {self.min_cameras!r}")
        if (
            isinstance(self.track_gap, bool)
            or not isinstance(self.track_gap, int)
            or (self.track_gap < 0)
        ):
            raise ValueError(f"track_gap must be an integer >= 0, got {self.track_gap!r}")
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


def default_min_cameras(n_cameras: int) -> int:
    """Fewest cameras a match must use when the settings leave it out: all but one of
    four or more cameras, two of two or three.

    With two cameras every match is a pair. With three, a particle hidden from one camera
    (behind another, or outside its view) is still matched by the other two. With four
    or more, a pair of rays meets a wrong ray within the tolerance far more often than
    three do, and every particle in the common view is still seen by all but one.
    """
    return max(2, n_cameras - 1) if n_cameras >= 4 else 2


def link_radius(dt: float, settings: PipelineSettings) -> float:
    """Link search radius max_speed·Δt + 5·position_noise, m.

    Raises
    ------
    ValueError
        ``settings.max_speed`` is None (not yet measured:
        :func:`ptv.pipeline.resolve.resolve_settings`).
    """
    if settings.max_speed is None:
        raise ValueError("max_speed is not known yet: measure it with resolve_settings")
    return search_radius(
        dt, u_rms=settings.max_speed, sigma_b=settings.position_noise, k_v=1.0, k_b=5.0
    )


def predicted_radius(k: int, settings: PipelineSettings) -> float | None:
    """The radius around the predicted links at Δt_k.

    Parameters
    ----------
    k : int
        Index of Δt_k in the dataset's Δt order.
    settings : PipelineSettings
        Their ``predicted_radii``.

    Returns
    -------
    float or None
        The radius, m; None where Δt_k is linked around X(t) (the smallest Δt, or
        settings without predicted radii).
    """
    radii = settings.predicted_radii
    if radii is None or k >= len(radii) or math.isnan(radii[k]):
        return None
    return radii[k]


def radius_at(k: int, dt: float, settings: PipelineSettings) -> float:
    """The radius the links of Δt_k are searched within.

    Parameters
    ----------
    k : int
        Index of Δt_k in the dataset's Δt order.
    dt : float
        Δt_k, s.
    settings : PipelineSettings
        Their ``predicted_radii``, ``max_speed`` and ``position_noise``.

    Returns
    -------
    float
        Around the link's prediction (:func:`predicted_radius`) where the settings have
        one, else around X(t) (:func:`link_radius`), m.
    """
    predicted = predicted_radius(k, settings)
    return link_radius(dt, settings) if predicted is None else predicted
