"""Every setting of the PTV stack, in one module: detection, matching and linking, the
statistics, the track fits, and ``synptv ptv``'s whole set.

The field names are the settings' names everywhere: the sections of a ``synptv ptv
--settings`` file and ``--print-settings`` (:mod:`ptv.pipeline.settings_file`) and the
``[ptv]`` table of a ``synptv run`` scenario use them unchanged. SI units (m, s, m/s,
m/s²) except pixels (px) and grey levels (DN).

- :class:`DetectorSettings`: how particles are detected on a dataset's images;
- :class:`StatisticsSettings`: the analysis volume, the separation bins, the plateau,
  C2 and the bootstrap of :func:`ptv.stats.run_statistics.compute_statistics`;
- :class:`PipelineSettings`: matching, linking, the snapshots processed, and the
  statistics;
- :class:`TrackFitSettings`: how a recording's tracks are fitted;
- :class:`PtvSettings`: the three that ``synptv ptv`` reads from one file;
- :class:`IPRSettings`: how iterative particle reconstruction works
  (:func:`ptv.reconstruct.reconstruct`; a scenario's ``[ipr]`` sets some of them).
"""

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from ptv._checks import positive
from ptv.bins import BINNINGS, LogBins
from ptv.box import Box, check_box
from ptv.tracking.fitting import MIN_FIT_POINTS

__all__ = [
    "ANALYSIS_VOLUME",
    "BACKGROUND_REMOVALS",
    "DEFAULT_C2",
    "MEASUREMENT_VOLUME",
    "DetectorSettings",
    "IPRSettings",
    "PipelineSettings",
    "PtvSettings",
    "StatisticsSettings",
    "TrackFitSettings",
    "default_min_cameras",
]

#: The background removals a detection can ask for.
BACKGROUND_REMOVALS = ("none", "tophat", "median")

#: Kolmogorov constant of the longitudinal S2 (C_K = 1.52), docs/flow.md §3.4.
DEFAULT_C2 = 2.0

#: The paper's 70 × 70 × 2 mm analysis volume centred in the sheet, m.
ANALYSIS_VOLUME: Box = ((-0.035, -0.035, -0.001), (0.035, 0.035, 0.001))

#: The 100 × 100 × 10 mm laser sheet plus a 1 mm margin, m: the default matching volume.
MEASUREMENT_VOLUME: Box = ((-0.051, -0.051, -0.006), (0.051, 0.051, 0.006))


@dataclass(frozen=True)
class DetectorSettings:
    """How particles are detected on a dataset's images (:mod:`ptv.detect.preprocess`
    for the options real images need).

    Attributes
    ----------
    threshold_sigmas : float
        Detection threshold in noise units above background (default 6), > 0.
    saturation : float or None
        Saturation level of the images, DN (None: the dtype's maximum).
    particles : {"bright", "dark"}
        Bright particles on a dark background (laser sheet) or dark on bright
        (back-lit): dark images are inverted, saturation − I, before detection.
    background : {"none", "tophat", "median"}
        Background removed before detection: none, a morphological top-hat of each
        frame, or the per-pixel median of ``median_frames`` frames of the camera.
    tophat_radius : int
        Disc radius of the top-hat, px, >= 1 (above the largest particle image radius).
    median_frames : int
        Frames, spread over the recording, whose median is the background, >= 3.
    min_peak : float
        Particles whose brightest pixel is less than this above the background are
        dropped, DN, >= 0.
    min_size : int
        Particles with fewer pixels above threshold are dropped, >= 1.
    diameter : float or None
        Expected particle image diameter, px (e⁻² diameter, σ = diameter/4), > 0; with
        ``background = "tophat"``, at most 2·``tophat_radius``. None (default): spots of
        about 3 px. From 6 px the detector works at the particles' scale
        (:func:`ptv.detect.detect_particles`), so that a large particle is one
        detection.

    Examples
    --------
    Back-lit particles (shadows) on an unevenly lit background, 15 px across:

    >>> import ptv
    >>> settings = ptv.DetectorSettings(
    ...     particles="dark", background="tophat", tophat_radius=8, diameter=15.0
    ... )
    >>> settings.raw, ptv.DetectorSettings().raw  # images prepared, or detected as recorded
    (False, True)
    >>> ptv.DetectorSettings(background="tophat", diameter=15.0)
    Traceback (most recent call last):
    ...
    ValueError: diameter 15.0 px is wider than the top-hat's disc ... set tophat_radius >= 8
    """

    threshold_sigmas: float = 6.0
    saturation: float | None = None
    particles: str = "bright"
    background: str = "none"
    tophat_radius: int = 4
    median_frames: int = 25
    min_peak: float = 0.0
    min_size: int = 1
    diameter: float | None = None

    def __post_init__(self) -> None:
        positive("threshold_sigmas", self.threshold_sigmas)
        if self.saturation is not None:
            positive("saturation", self.saturation)
        if self.particles not in ("bright", "dark"):
            raise ValueError(f"particles must be 'bright' or 'dark', got {self.particles!r}")
        if self.background not in BACKGROUND_REMOVALS:
            raise ValueError(
                f"background must be one of {', '.join(BACKGROUND_REMOVALS)}, got "
                f"{self.background!r}"
            )
        for name, low in (("tophat_radius", 1), ("median_frames", 3), ("min_size", 1)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < low:
                raise ValueError(f"{name} must be an integer >= {low}, got {value!r}")
        if isinstance(self.min_peak, bool) or not (
            isinstance(self.min_peak, int | float) and self.min_peak >= 0
        ):
            raise ValueError(f"min_peak must be a number >= 0 (DN), got {self.min_peak!r}")
        if self.diameter is not None:
            positive("diameter", self.diameter)
            if self.background == "tophat" and self.diameter > 2 * self.tophat_radius:
                raise ValueError(
                    f"diameter {self.diameter!r} px is wider than the top-hat's disc "
                    f"(tophat_radius {self.tophat_radius} px), which would remove the "
                    f"particles: set tophat_radius >= {math.ceil(self.diameter / 2)}"
                )

    @property
    def raw(self) -> bool:
        """Whether the images are detected as recorded (no inversion, no removal)."""
        return self.particles == "bright" and self.background == "none"

    def as_dict(self) -> dict:
        """JSON-able form (what detections depend on besides the images); ``diameter``
        only when given, so that the records of earlier runs stay as they were."""
        fields = dataclasses.asdict(self)
        if self.diameter is None:
            del fields["diameter"]
        return fields


@dataclass(frozen=True)
class StatisticsSettings:
    """Options of :func:`ptv.stats.run_statistics.compute_statistics` (SI units).

    Attributes
    ----------
    analysis_volume : (lower, upper)
        Box the statistics are restricted to by X(t), m (default :data:`ANALYSIS_VOLUME`).
    r_min, r_max : float
        Outer edges of the log-spaced separation bins, m (default 0.5 and 35 mm).
    n_bins : int
        Separation bins (default 24).
    binning : {"start", "midpoint"}
        A pair's separation for its bin and its direction: at t (default), or the chord
        midpoint of t and t + Δt (docs/statistics.md §4; a shared first frame only).
    plateau : (float, float)
        Range of r over which ε(r) is averaged, m (default 2–20 mm).
    plateau_method : {"mean", "max"}
        Mean of ε(r) over the range (the paper's Table 3) or its maximum.
    kolmogorov_c2 : float
        C2 of ε = (S2/C2)^{3/2}/r (default 2.0).
    n_boot : int
        Bootstrap replicates over snapshots (default 200).
    eulerian_cells : (int, int, int)
        Cells of the Eulerian grid over the analysis volume (default 4 × 4 × 1); one
        cell is used when none of them holds enough displacements.
    min_cell_count : int
        Displacements a cell needs at every Δt to be fitted (default 10).
    trajectory_threshold : float or None
        With a shared first frame and K ≥ 4 Δt: particles whose displacements stray
        from a smooth path in Δt by more than this many times the median residual of
        all particles (:func:`ptv.tracking.linking.trajectory_residuals`) are mislinked at some
        Δt and left out of S2 (default 5; None keeps them).
    snapshot_block : int or None
        Consecutive snapshots the bootstrap draws together: None (default) to follow
        the correlation of successive snapshots measured on the data
        (:func:`ptv.stats.resampling.block_length`: 1 for independent snapshots), or a
        given block length ≥ 1.
    seed : int
        Seed of the bootstrap.

    Examples
    --------
    >>> import ptv
    >>> settings = ptv.StatisticsSettings(r_min=1e-3, r_max=8e-3, n_bins=3, n_boot=100)
    >>> settings.bins.edges  # m
    array([0.001, 0.002, 0.004, 0.008])
    >>> ptv.StatisticsSettings(plateau=(0.02, 0.002))
    Traceback (most recent call last):
    ...
    ValueError: plateau must be (r_min, r_max) with 0 < r_min < r_max, got (0.02, 0.002)
    """

    analysis_volume: Box = ANALYSIS_VOLUME
    r_min: float = 0.5e-3
    r_max: float = 35e-3
    n_bins: int = 24
    binning: str = "start"
    plateau: tuple[float, float] = (2e-3, 20e-3)
    plateau_method: str = "mean"
    kolmogorov_c2: float = DEFAULT_C2
    n_boot: int = 200
    eulerian_cells: tuple[int, int, int] = (4, 4, 1)
    min_cell_count: int = 10
    trajectory_threshold: float | None = 5.0
    snapshot_block: int | None = None
    seed: int = 0

    def __post_init__(self) -> None:
        object.__setattr__(
            self, "analysis_volume", check_box("analysis_volume", self.analysis_volume)
        )
        object.__setattr__(self, "kolmogorov_c2", positive("kolmogorov_c2", self.kolmogorov_c2))
        LogBins(self.r_min, self.r_max, self.n_bins)  # validates
        if self.binning not in BINNINGS:
            raise ValueError(f"binning must be one of {', '.join(BINNINGS)}, got {self.binning!r}")
        lo, hi = self.plateau
        if not 0 < lo < hi:
            raise ValueError(
                f"plateau must be (r_min, r_max) with 0 < r_min < r_max, got {self.plateau}"
            )
        if self.plateau_method not in ("mean", "max"):
            raise ValueError(f"plateau_method must be 'mean' or 'max', got {self.plateau_method!r}")
        if not isinstance(self.n_boot, int) or self.n_boot < 2:
            raise ValueError(f"n_boot must be an integer >= 2, got {self.n_boot!r}")
        cells = self.eulerian_cells
        if len(cells) != 3 or not all(
            isinstance(n, int) and not isinstance(n, bool) and n >= 1 for n in cells
        ):
            raise ValueError(f"eulerian_cells must be 3 integers >= 1, got {cells!r}")
        if not isinstance(self.min_cell_count, int) or self.min_cell_count < 3:
            raise ValueError(f"min_cell_count must be an integer >= 3, got {self.min_cell_count!r}")
        block = self.snapshot_block
        if block is not None and (
            not isinstance(block, int) or isinstance(block, bool) or block < 1
        ):
            raise ValueError(f"snapshot_block must be None or an integer >= 1, got {block!r}")
        if self.trajectory_threshold is not None:
            object.__setattr__(
                self,
                "trajectory_threshold",
                positive("trajectory_threshold", self.trajectory_threshold),
            )

    @property
    def bins(self) -> LogBins:
        """The separation bins."""
        return LogBins(self.r_min, self.r_max, self.n_bins)


@dataclass(frozen=True)
class PipelineSettings:
    """Options of :func:`ptv.pipeline.double_frame.run_pipeline` (SI units).

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
        (:func:`ptv.pipeline.time_resolved.track_radii`; default 100, about 5 times the rms of one
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


@dataclass(frozen=True)
class TrackFitSettings:
    """How tracks are fitted (``[tracks]`` of ``synptv ptv --settings``).

    Attributes
    ----------
    fit_window : int or None
        Points per fit, odd, ≥ 5 (None: chosen from the noise and the tracks).
    min_points : int
        Fewest points of a track that is fitted, ≥ 5.

    Examples
    --------
    >>> import ptv
    >>> ptv.TrackFitSettings(fit_window=7)
    TrackFitSettings(fit_window=7, min_points=5)
    >>> ptv.TrackFitSettings(fit_window=6)
    Traceback (most recent call last):
    ...
    ValueError: fit_window must be an odd integer >= 5, got 6
    """

    fit_window: int | None = None
    min_points: int = MIN_FIT_POINTS

    def __post_init__(self) -> None:
        if self.fit_window is not None and not (
            isinstance(self.fit_window, int)
            and self.fit_window >= MIN_FIT_POINTS
            and self.fit_window % 2 == 1
        ):
            raise ValueError(
                f"fit_window must be an odd integer >= {MIN_FIT_POINTS}, got {self.fit_window!r}"
            )
        if not isinstance(self.min_points, int) or self.min_points < MIN_FIT_POINTS:
            raise ValueError(
                f"min_points must be an integer >= {MIN_FIT_POINTS}, got {self.min_points!r}"
            )


@dataclass(frozen=True)
class PtvSettings:
    """What ``synptv ptv`` needs besides the dataset and the calibration.

    Attributes
    ----------
    detection : DetectorSettings
        Particle detection on the images.
    pipeline : PipelineSettings
        Matching, linking, the snapshots processed and the statistics.
    tracks : TrackFitSettings
        How ``--tracks`` fits the tracks.

    Examples
    --------
    The defaults, and the same with only the first 5 snapshots processed:

    >>> import dataclasses
    >>> import ptv
    >>> settings = ptv.PtvSettings()
    >>> settings.detection.threshold_sigmas, settings.pipeline.statistics.n_boot
    (6.0, 200)
    >>> pipeline = dataclasses.replace(settings.pipeline, snapshots=5)
    >>> dataclasses.replace(settings, pipeline=pipeline).pipeline.snapshots
    5
    """

    detection: DetectorSettings = field(default_factory=DetectorSettings)
    pipeline: PipelineSettings = field(default_factory=PipelineSettings)
    tracks: TrackFitSettings = field(default_factory=TrackFitSettings)


def _ipr_int(name: str, value: object, low: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < low:
        raise ValueError(f"{name} must be an integer >= {low}, got {value!r}")
    return int(value)


def _ipr_float(name: str, value: object, low: float, *, strict: bool = True, high=np.inf) -> float:
    ok = isinstance(value, int | float | np.integer | np.floating) and not isinstance(value, bool)
    if not ok or not np.isfinite(value) or value < low or (strict and value == low) or value > high:
        bound = f"> {low}" if strict else f">= {low}"
        raise ValueError(f"{name} must be a finite number {bound} and <= {high}, got {value!r}")
    return float(value)


@dataclass(frozen=True)
class IPRSettings:
    """How :func:`ptv.reconstruct.reconstruct` works (Wieneke 2013; Jahn et al. 2021).

    Attributes
    ----------
    outer_iterations : int
        Outer iterations (peaks → triangulation → shaking → removal) at most, >= 0.
    reduced_iterations : int
        The last ones of these triangulate with one camera fewer too (a particle whose
        image is hidden in one camera) if that has not begun before, >= 0.
    reduce_below : float
        Triangulation with one camera fewer begins once an iteration increases the
        number of particles by less than this fraction, >= 0.
    converged : float
        The iterations stop when, after at least two with one camera fewer, one adds at
        most this fraction of the particles, >= 0.
    shake_iterations : int
        Shaking passes per outer iteration, >= 0 (0: no shaking).
    final_shakes : int
        Shaking passes after the last outer iteration, >= 0.
    tolerance : float
        Largest distance between a candidate's projection and its peak in each camera,
        px, > 0.
    tolerance_start : float
        The tolerance of the first iteration, px, > 0, at most ``tolerance``; it grows
        linearly to ``tolerance`` over ``tolerance_ramp`` iterations (the first
        particles, taken with a tight tolerance, are the surest: fewer ghosts borrow
        the light of particles not yet found).
    tolerance_ramp : int
        Iterations over which the tolerance grows, >= 0.
    peak_threshold : float
        Peaks of the residual below this fraction of a typical particle image's peak
        (from the OTF) are ignored, >= 0.
    noise_threshold : float
        … and below this many background noise σ, >= 0.
    shake_step : float
        Shaking step of the first pass of each outer iteration, as the image motion it
        causes, px (rms over the cameras; about one voxel per px laterally), > 0.
    shake_step_min : float
        Step of the last pass of each outer iteration (geometric in between), px, > 0,
        at most ``shake_step``.
    intensity_threshold : float
        Particles whose intensity falls below this fraction of a typical particle's
        (the OTF's intensity, E = 1) are removed after the shaking (ghosts are faint),
        >= 0 and < 1. The reference is the OTF's, not the mean of the reconstructed
        particles, which ghosts drag down at high density.
    camera_ratio : float
        Particles whose intensity seen by one camera alone is below this fraction of
        their intensity are removed (a ghost borrows light in some cameras only),
        >= 0 and < 1 (0: no such test).
    peak_uses : int
        A peak may serve this many new candidates of one iteration at most
        (:func:`ptv.reconstruct.triangulation.select_candidates`), >= 1.
    merge_distance : float
        Particles closer than this are merged into one, voxels, >= 0.
    epipolar_samples : int
        Points along each reference ray whose projections form the epipolar polylines,
        >= 2.
    radius_sigmas : float
        Half-width of a particle image's window, in its σ, >= 2.5.
    margin : float
        Particles may lie this far outside the measurement volume, voxels, >= 0.
    min_cameras : int
        Particles seen by fewer cameras are removed, >= 2.
    mapping_grid : float
        0: the cameras' ``project`` is called directly. > 0: it is interpolated from a
        grid of this step, voxels (:class:`ptv.reconstruct.mapping.GridMapping`), for
        calibrations whose ``project`` is slow (model-free: about 6·10³ points/s);
        32 voxels (about 2 mm at 60 µm) interpolate to 2·10⁻⁵ px.
    """

    outer_iterations: int = 60
    reduced_iterations: int = 4
    reduce_below: float = 0.05
    converged: float = 0.005
    shake_iterations: int = 4
    final_shakes: int = 4
    tolerance: float = 1.0
    tolerance_start: float = 1.0
    tolerance_ramp: int = 0
    peak_threshold: float = 0.1
    noise_threshold: float = 4.0
    shake_step: float = 0.5
    shake_step_min: float = 0.05
    intensity_threshold: float = 0.35
    camera_ratio: float = 0.5
    peak_uses: int = 1
    merge_distance: float = 1.0
    epipolar_samples: int = 9
    radius_sigmas: float = 3.5
    margin: float = 2.0
    min_cameras: int = 3
    mapping_grid: float = 0.0

    def __post_init__(self) -> None:
        _ipr_int("outer_iterations", self.outer_iterations, 0)
        _ipr_int("reduced_iterations", self.reduced_iterations, 0)
        _ipr_int("shake_iterations", self.shake_iterations, 0)
        _ipr_int("final_shakes", self.final_shakes, 0)
        _ipr_int("epipolar_samples", self.epipolar_samples, 2)
        _ipr_int("min_cameras", self.min_cameras, 2)
        _ipr_int("peak_uses", self.peak_uses, 1)
        _ipr_float("tolerance", self.tolerance, 0.0)
        _ipr_float("tolerance_start", self.tolerance_start, 0.0, high=self.tolerance)
        _ipr_int("tolerance_ramp", self.tolerance_ramp, 0)
        _ipr_float("peak_threshold", self.peak_threshold, 0.0, strict=False)
        _ipr_float("noise_threshold", self.noise_threshold, 0.0, strict=False)
        _ipr_float("shake_step", self.shake_step, 0.0)
        _ipr_float("shake_step_min", self.shake_step_min, 0.0, high=self.shake_step)
        _ipr_float("intensity_threshold", self.intensity_threshold, 0.0, strict=False, high=0.999)
        _ipr_float("reduce_below", self.reduce_below, 0.0, strict=False)
        _ipr_float("converged", self.converged, 0.0, strict=False)
        _ipr_float("camera_ratio", self.camera_ratio, 0.0, strict=False, high=0.999)
        _ipr_float("merge_distance", self.merge_distance, 0.0, strict=False)
        _ipr_float("radius_sigmas", self.radius_sigmas, 2.5, strict=False, high=8.0)
        _ipr_float("margin", self.margin, 0.0, strict=False)
        _ipr_float("mapping_grid", self.mapping_grid, 0.0, strict=False)
