"""Double-frame 3D-PTV on a dataset folder, from images to S2(r), ε and u′.

For every Δt_k and every snapshot m (a frame pair per camera, see :mod:`ptv.dataset`):

1. detect the particles on frames a and b of each camera (:func:`ptv.detect.detect_particles`,
   saturation from the dataset's bit depth);
2. match the cameras in frame a and in frame b (:func:`ptv.match.match`) inside the
   measurement volume (default: the 100 × 100 × 10 mm sheet plus 1 mm) with the stereo
   tolerance (default 0.15 mm, 2–3× the calibration error);
3. link frame a to frame b one-to-one (:func:`ptv.track.link`) within the radius
   r_k = max_speed·Δt_k + 5σ_b (max_speed: the largest speed expected, default
   1.5 m/s; σ_b: the position noise, default 30 µm): the Δt-scaled threshold of
   PHYSICS.md §4, which also rejects mismatches with |ΔX| beyond it;
4. flag mislinks by the normalised median test (Westerweel & Scarano 2005) on the
   3-D displacements: a link is an outlier when |ΔX − m| > threshold·(r̃ + ε0), m the
   median displacement of its 8 nearest linked neighbours (same snapshot, by X(t)), r̃
   the median of the neighbours' own |ΔX_j − m| and ε0 = σ_b (default threshold 4);
5. keep X(t) and ΔX = X(t + Δt) − X(t) of every link, with the outlier flag.

Why step 4: a link whose end is a stereo ghost, or a particle whose partner was lost,
is taken up to the link radius away (~0.9 mm at Δt = 0.5 ms) and its displacement is
unrelated to the flow. Such links are rare (0.1–0.3 % in the analysis volume on a
rendered paper-stereo dataset) but q grows as |ΔX|², and their share grows with Δt,
so they added +4–8 % to the multi-Δt S2 and pushed c2 negative there; the test
removed the harmful half of them and no correct link. Ghost-to-ghost links that
move with their neighbours pass it, and do no harm.

A snapshot whose frames give no match (an empty frame, a dark laser pulse) or no link
is skipped with a warning; a Δt left without snapshots is dropped from the statistics;
fewer than two Δt left is an error.

Statistics use the links that are not outliers and whose X(t) lies in the analysis
volume (default the paper's 70 × 70 × 2 mm centred box; bin by X(t), PHYSICS.md §4):

- S2(r) by the multi-Δt fit ⟨q⟩_k = S2·Δt_k² + N per log-spaced separation bin
  (0.5–35 mm, 24 bins), errors by bootstrap over snapshots
  (:func:`ptv.stats.structure.structure_function`); the raw ⟨q⟩_k/Δt_k² per Δt and the
  noise term c2 = N(r) beside it;
- ε(r) = (S2/C2)^{3/2}/r with C2 = 2.0 and the paper's uncorrected S2^{3/2}/r, and
  their plateau (mean over 2–20 mm by default);
- the same fit on Δt subsets (the 3 largest; the smallest and the largest) and their
  plateau ε (the paper's subset study);
- the spatially averaged mean displacement against Δt with the line αΔt + β0 (β0 = 0
  for zero-mean noise: the linearity check) and u′ from the Eulerian variance fit
  Var ΔX = u′²Δt² + 2σ_b² per cell (:mod:`ptv.stats.eulerian`), whose intercept also
  estimates the position noise σ_b per component. The cell mean is taken over the
  run's snapshots and subtracted, so with few snapshots u′ comes out low by about
  the variance of a cell mean over them (rendered lem-10hz data: −4 % with 30
  snapshots per Δt, −25 % with 3).

Nothing here reads a ground truth, plots or prints; :mod:`ptv.results` writes the
results, ``validation`` draws and compares.
"""

import hashlib
import logging
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TypeVar

import numpy as np
from scipy.spatial import cKDTree
from scipy.stats import chi2 as chi2_distribution
from scipy.stats import f as f_distribution

from ptv.camera_model import CameraModel
from ptv.dataset import Dataset, DatasetError, Snapshot, cameras_in_order
from ptv.detect import Detections, detect_particles
from ptv.match import Matches, match
from ptv.stats.dissipation import (
    DEFAULT_C2,
    DissipationProfile,
    Plateau,
    dissipation_profile,
    plateau_epsilon,
)
from ptv.stats.eulerian import EulerianFit, Grid, UPrime, eulerian_fit, eulerian_moments, u_prime
from ptv.stats.multidt import LineFit, largest_dt, smallest_and_largest_dt, wls_line
from ptv.stats.pairs import LogBins
from ptv.stats.snapshots import cluster_mean
from ptv.stats.structure import (
    StructureFunction,
    double_frame_sums,
    structure_function,
    time_resolved_sums,
)
from ptv.track import link, search_radius, trajectory_residuals

__all__ = [
    "ANALYSIS_VOLUME",
    "MEASUREMENT_VOLUME",
    "FramePoints",
    "MeanDisplacement",
    "PipelineSettings",
    "PtvResult",
    "PtvStatistics",
    "RunParticles",
    "S2Population",
    "SharedFirstFrames",
    "SnapshotMeasurement",
    "Subset",
    "compute_statistics",
    "detect_and_match",
    "inside_box",
    "link_radius",
    "measure_frame",
    "measure_run",
    "measure_snapshot",
    "median_test_outliers",
    "run_pipeline",
    "shared_snapshots",
]

log = logging.getLogger(__name__)

T = TypeVar("T")

Progress = Callable[[int, int], None]
Box = tuple[tuple[float, float, float], tuple[float, float, float]]

#: The 100 × 100 × 10 mm laser sheet plus a 1 mm margin, m: the default matching volume.
MEASUREMENT_VOLUME: Box = ((-0.051, -0.051, -0.006), (0.051, 0.051, 0.006))
#: The paper's 70 × 70 × 2 mm analysis volume centred in the sheet, m.
ANALYSIS_VOLUME: Box = ((-0.035, -0.035, -0.001), (0.035, 0.035, 0.001))


def _box(name: str, value) -> Box:
    try:
        lower, upper = (np.asarray(v, dtype=np.float64) for v in value)
    except (TypeError, ValueError):
        raise ValueError(
            f"{name} must be (lower, upper) corners of 3 numbers, got {value!r}"
        ) from None
    if lower.shape != (3,) or upper.shape != (3,):
        raise ValueError(f"{name} corners must have 3 entries each, got {value!r}")
    if not (np.all(np.isfinite(lower)) and np.all(np.isfinite(upper)) and np.all(lower < upper)):
        raise ValueError(f"{name} needs finite corners with lower < upper, got {value!r}")
    return (tuple(float(v) for v in lower), tuple(float(v) for v in upper))  # type: ignore[return-value]


def _positive(name: str, value) -> float:
    ok = isinstance(value, int | float | np.integer | np.floating) and not isinstance(value, bool)
    if not (ok and np.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
    return float(value)


@dataclass(frozen=True)
class PipelineSettings:
    """Options of :func:`run_pipeline` (SI units).

    Attributes
    ----------
    volume : (lower, upper)
        Matching volume, m (default :data:`MEASUREMENT_VOLUME`).
    tolerance : float
        Stereo tolerance on the ray distances, m (default 0.15 mm).
    max_speed : float
        Largest particle speed expected, m/s: sets the link radius (default 1.5).
    position_noise : float
        Expected position noise σ_b (one component), m: adds 5σ_b to the link radius
        (default 30 µm).
    analysis_volume : (lower, upper)
        Box the statistics are restricted to by X(t), m (default :data:`ANALYSIS_VOLUME`).
    r_min, r_max : float
        Outer edges of the log-spaced separation bins, m (default 0.5 and 35 mm).
    n_bins : int
        Separation bins (default 24).
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
    threshold : float
        Detection threshold in noise units above background (default 6).
    outlier_threshold : float or None
        Threshold of the normalised median test on the displacements (default 4; None
        keeps every link).
    outlier_neighbours : int
        Neighbours of the normalised median test (default 8).
    trajectory_threshold : float or None
        With a shared first frame and K ≥ 4 Δt: particles whose displacements stray
        from a smooth path in Δt by more than this many times the median residual of
        all particles (:func:`ptv.track.trajectory_residuals`) are mislinked at some
        Δt and left out of S2 (default 5; None keeps them).
    snapshots : int or None
        Process only the first N snapshots of every Δt (None: all).
    seed : int
        Seed of the bootstrap.
    """

    volume: Box = MEASUREMENT_VOLUME
    tolerance: float = 1.5e-4
    max_speed: float = 1.5
    position_noise: float = 30e-6
    analysis_volume: Box = ANALYSIS_VOLUME
    r_min: float = 0.5e-3
    r_max: float = 35e-3
    n_bins: int = 24
    plateau: tuple[float, float] = (2e-3, 20e-3)
    plateau_method: str = "mean"
    kolmogorov_c2: float = DEFAULT_C2
    n_boot: int = 200
    eulerian_cells: tuple[int, int, int] = (4, 4, 1)
    min_cell_count: int = 10
    threshold: float = 6.0
    outlier_threshold: float | None = 4.0
    outlier_neighbours: int = 8
    trajectory_threshold: float | None = 5.0
    snapshots: int | None = None
    seed: int = 0

    def __post_init__(self) -> None:
        object.__setattr__(self, "volume", _box("volume", self.volume))
        object.__setattr__(self, "analysis_volume", _box("analysis_volume", self.analysis_volume))
        for name in ("tolerance", "max_speed", "position_noise", "kolmogorov_c2", "threshold"):
            object.__setattr__(self, name, _positive(name, getattr(self, name)))
        LogBins(self.r_min, self.r_max, self.n_bins)  # validates
        lo, hi = self.plateau
        if not 0 < lo < hi:
            raise ValueError(
                f"plateau must be (r_min, r_max) with 0 < r_min < r_max, got {self.plateau}"
            )
        if self.plateau_method not in ("mean", "max"):
            raise ValueError(f"plateau_method must be 'mean' or 'max', got {self.plateau_method!r}")
        if not isinstance(self.n_boot, int) or self.n_boot < 2:
            raise ValueError(f"n_boot must be an integer >= 2, got {self.n_boot!r}")
        Grid((0.0, 0.0, 0.0), (1.0, 1.0, 1.0), self.eulerian_cells)  # validates the shape
        if not isinstance(self.min_cell_count, int) or self.min_cell_count < 3:
            raise ValueError(f"min_cell_count must be an integer >= 3, got {self.min_cell_count!r}")
        if self.outlier_threshold is not None:
            object.__setattr__(
                self, "outlier_threshold", _positive("outlier_threshold", self.outlier_threshold)
            )
        if self.trajectory_threshold is not None:
            object.__setattr__(
                self,
                "trajectory_threshold",
                _positive("trajectory_threshold", self.trajectory_threshold),
            )
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

    @property
    def bins(self) -> LogBins:
        """The separation bins."""
        return LogBins(self.r_min, self.r_max, self.n_bins)


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
    positions : ndarray, shape (N, 3)
        X(t) of the links, m.
    displacements : ndarray, shape (N, 3)
        ΔX = X(t + Δt) − X(t), m.
    outlier : ndarray of bool, shape (N,)
        Links failing the normalised median test.
    """

    k: int
    m: int
    detections: np.ndarray
    matches: np.ndarray
    positions: np.ndarray
    displacements: np.ndarray
    outlier: np.ndarray

    @property
    def links(self) -> int:
        """Number of links N."""
        return len(self.positions)


def detect_and_match(
    images: Sequence[np.ndarray],
    cameras: Sequence[CameraModel],
    settings: PipelineSettings,
    *,
    saturation: float | None = None,
) -> tuple[list[Detections], Matches]:
    """Detect the particles on one frame of every camera and match them in 3-D.

    Parameters
    ----------
    images : sequence of C ndarray, shape (H, W)
        One image per camera (the same instant).
    cameras : sequence of C CameraModel
        Their calibrations.
    settings : PipelineSettings
        Detection threshold, matching volume and tolerance.
    saturation : float, optional
        Saturation level of the images, DN (None: the dtype's maximum).

    Returns
    -------
    (list of Detections, Matches)
        ``Matches.indices`` refer to the rows of each camera's detections.
    """
    if len(images) != len(cameras):
        raise ValueError(f"need one image per camera, got {len(images)} for {len(cameras)}")
    found = [detect_particles(im, k=settings.threshold, saturation=saturation) for im in images]
    matches = match(cameras, [d.xy for d in found], settings.volume, tolerance=settings.tolerance)
    return found, matches


#: One frame of every camera measured: detections per camera and the matched points (N, 3).
FramePoints = tuple[list[int], np.ndarray]


def measure_frame(
    images: Sequence[np.ndarray],
    cameras: Sequence[CameraModel],
    settings: PipelineSettings,
    *,
    saturation: float | None = None,
) -> FramePoints:
    """The detection count per camera and the matched 3-D points of one frame.

    Parameters as :func:`detect_and_match`.

    Returns
    -------
    FramePoints
        Detections per camera (list of C int) and matched points, shape (N, 3), m.
    """
    found, matched = detect_and_match(images, cameras, settings, saturation=saturation)
    return [len(d) for d in found], matched.points


class SharedFirstFrames:
    """Frame a of each snapshot, measured once for every Δt of a dataset that shares it.

    Each use checks that the images are the ones measured (a content digest per camera),
    so a dataset that declares a shared first frame wrongly is an error, not a silent mix
    of frames. What is stored is what the ``measure`` callable returns (the PTV stack
    keeps :data:`FramePoints`).
    """

    def __init__(self) -> None:
        self._frames: dict[int, tuple[tuple[bytes, ...], object]] = {}

    def __len__(self) -> int:
        return len(self._frames)

    def measure(self, snapshot: Snapshot, measure: Callable[[list[np.ndarray]], T]) -> T:
        """Frame a of ``snapshot``: ``measure(images)`` the first time, the stored result after.

        Raises
        ------
        DatasetError
            Frame a differs from the one stored for the same snapshot number.
        """
        images = [pair.a for pair in snapshot.frames]
        digest = tuple(
            hashlib.blake2b(np.ascontiguousarray(image), digest_size=16).digest()
            for image in images
        )
        if snapshot.m not in self._frames:
            self._frames[snapshot.m] = (digest, measure(images))
        stored, points = self._frames[snapshot.m]
        if stored != digest:
            raise DatasetError(
                f"{snapshot.frames[0].path_a}: the dataset declares a shared first frame, but "
                f"frame a of snapshot {snapshot.m} at Δt_{snapshot.k} is not the one of the "
                "first Δt"
            )
        return points


def measure_snapshot(
    snapshot: Snapshot,
    cameras: Sequence[CameraModel],
    settings: PipelineSettings,
    *,
    saturation: float | None = None,
    frame_a: FramePoints | None = None,
) -> SnapshotMeasurement:
    """Detect, match (frames a and b) and link one snapshot.

    Parameters
    ----------
    snapshot : Snapshot
        The frame pairs of every camera (:meth:`ptv.dataset.Dataset.snapshot`).
    cameras : sequence of CameraModel
        Calibrations in the order of ``snapshot.frames``.
    settings : PipelineSettings
        Volume, tolerance, link radius, detection threshold.
    saturation : float, optional
        Saturation level of the images, DN (None: the dtype's maximum).
    frame_a : FramePoints, optional
        Frame a already measured (:func:`measure_frame`), as when every Δt shares it.

    Returns
    -------
    SnapshotMeasurement
        With no links when a frame has no match.
    """
    if len(cameras) != len(snapshot.frames):
        raise ValueError(
            f"need one calibration per camera: {len(cameras)} for {len(snapshot.frames)} cameras"
        )
    points, detections, matches = [], [], []
    for frame in ("a", "b"):
        if frame == "a" and frame_a is not None:
            counts, matched = frame_a
        else:
            images = [getattr(pair, frame) for pair in snapshot.frames]
            counts, matched = measure_frame(images, cameras, settings, saturation=saturation)
        detections.append(counts)
        matches.append(len(matched))
        points.append(matched)
    if len(points[0]) and len(points[1]):
        links = link(points[0], points[1], radius=link_radius(snapshot.dt, settings))
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
        k=snapshot.k,
        m=snapshot.m,
        detections=np.asarray(detections, dtype=np.int64),
        matches=np.asarray(matches, dtype=np.int64),
        positions=positions,
        displacements=displacements,
        outlier=outlier,
    )


# ------------------------------------------------------------------------------ per run


@dataclass(frozen=True, eq=False)
class RunParticles:
    """All links of the run at one Δt, snapshots concatenated.

    Attributes
    ----------
    k : int
        Δt index in the dataset.
    dt : float
        Δt, s.
    positions : ndarray, shape (N, 3)
        X(t), m.
    displacements : ndarray, shape (N, 3)
        ΔX, m.
    offsets : ndarray of int, shape (M + 1,)
        Rows offsets[i]:offsets[i + 1] belong to snapshot ``snapshot_ids[i]``.
    snapshot_ids : ndarray of int, shape (M,)
        Snapshot numbers kept (those with links).
    detections : ndarray of int, shape (S, 2, C)
        Detections per processed snapshot, frame (a, b) and camera.
    matches : ndarray of int, shape (S, 2)
        Matches per processed snapshot and frame.
    links : ndarray of int, shape (S,)
        Links per processed snapshot.
    processed : ndarray of int, shape (S,)
        Snapshot numbers processed (S ≥ M).
    in_analysis : ndarray of bool, shape (N,)
        X(t) inside the analysis volume.
    outlier : ndarray of bool, shape (N,)
        Links failing the normalised median test (not used by the statistics).
    """

    k: int
    dt: float
    positions: np.ndarray
    displacements: np.ndarray
    offsets: np.ndarray
    snapshot_ids: np.ndarray
    detections: np.ndarray
    matches: np.ndarray
    links: np.ndarray
    processed: np.ndarray
    in_analysis: np.ndarray
    outlier: np.ndarray

    @property
    def used(self) -> np.ndarray:
        """(N,) bool: links the statistics use (in the analysis volume, not outliers)."""
        return self.in_analysis & ~self.outlier

    @property
    def skipped(self) -> np.ndarray:
        """Snapshot numbers processed but skipped (no match or no link)."""
        return np.setdiff1d(self.processed, self.snapshot_ids)

    def snapshot_arrays(self, *, analysis: bool = True) -> list[tuple[np.ndarray, np.ndarray]]:
        """(positions, displacements) per kept snapshot; with ``analysis``, the used links."""
        out = []
        for i in range(len(self.snapshot_ids)):
            rows = slice(int(self.offsets[i]), int(self.offsets[i + 1]))
            x, d = self.positions[rows], self.displacements[rows]
            if analysis:
                keep = self.used[rows]
                x, d = x[keep], d[keep]
            out.append((x, d))
        return out


def inside_box(points: np.ndarray, box: Box) -> np.ndarray:
    """Points (..., 3) inside ``box`` = (lower corner, upper corner), m, boundary included."""
    lower, upper = (np.asarray(v) for v in box)
    return np.all((points >= lower) & (points <= upper), axis=-1)


def measure_run(
    dataset: Dataset,
    k: int,
    cameras: Sequence[CameraModel],
    settings: PipelineSettings,
    *,
    tick: Callable[[], None] | None = None,
    first_frames: SharedFirstFrames | None = None,
) -> RunParticles:
    """Process every snapshot of the run at Δt_k (the first ``settings.snapshots``).

    Parameters
    ----------
    dataset : Dataset
        The folder.
    k : int
        Δt index.
    cameras : sequence of CameraModel
        Calibrations in the dataset's camera order.
    settings : PipelineSettings
        Options.
    tick : callable, optional
        Called after each snapshot.
    first_frames : SharedFirstFrames, optional
        Frame a of each snapshot, measured once for every Δt when the dataset shares its
        first frames: read from, and filled with what is measured now.

    Returns
    -------
    RunParticles
    """
    kept, det, mat, lnk, processed = [], [], [], [], []
    for snap in dataset.snapshots(k, limit=settings.snapshots):
        frame_a = None
        if first_frames is not None:
            frame_a = first_frames.measure(
                snap,
                lambda images: measure_frame(
                    images, cameras, settings, saturation=dataset.saturation
                ),
            )
        res = measure_snapshot(
            snap, cameras, settings, saturation=dataset.saturation, frame_a=frame_a
        )
        processed.append(snap.m)
        det.append(res.detections)
        mat.append(res.matches)
        lnk.append(res.links)
        if res.matches.min() == 0:
            frames = " and ".join(f for f, n in zip("ab", res.matches, strict=True) if n == 0)
            log.warning(
                "Δt_%d = %.4g s, snapshot %d skipped: no matched particle in frame %s "
                "(detections a %s, b %s)",
                k,
                snap.dt,
                snap.m,
                frames,
                res.detections[0].tolist(),
                res.detections[1].tolist(),
            )
        elif res.links == 0:
            log.warning(
                "Δt_%d = %.4g s, snapshot %d skipped: no link within %.3g mm",
                k,
                snap.dt,
                snap.m,
                link_radius(snap.dt, settings) * 1e3,
            )
        else:
            kept.append(res)
        if tick is not None:
            tick()
    n_cam = len(cameras)
    sizes = [r.links for r in kept]
    positions = np.concatenate([r.positions for r in kept]) if kept else np.empty((0, 3))
    displacements = np.concatenate([r.displacements for r in kept]) if kept else np.empty((0, 3))
    outlier = np.concatenate([r.outlier for r in kept]) if kept else np.empty(0, dtype=bool)
    return RunParticles(
        k=k,
        dt=float(dataset.dt[k]),
        positions=positions,
        displacements=displacements,
        offsets=np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64),
        snapshot_ids=np.asarray([r.m for r in kept], dtype=np.int64),
        detections=np.asarray(det, dtype=np.int64).reshape(-1, 2, n_cam),
        matches=np.asarray(mat, dtype=np.int64).reshape(-1, 2),
        links=np.asarray(lnk, dtype=np.int64),
        processed=np.asarray(processed, dtype=np.int64),
        in_analysis=inside_box(positions, settings.analysis_volume),
        outlier=outlier,
    )


# --------------------------------------------------------------------------- statistics


@dataclass(frozen=True, eq=False)
class MeanDisplacement:
    """Spatially averaged mean displacement against Δt and its line αΔt + β0.

    Attributes
    ----------
    dt : ndarray, shape (K,)
        s.
    mean : ndarray, shape (K, 3)
        ⟨ΔX⟩ over the links in the analysis volume (with a shared first frame: over the
        particles linked at every Δt), m.
    se : ndarray, shape (K, 3)
        Its standard error from the scatter of the snapshot means (snapshots are the
        independent units), m; from the particles when a run has one snapshot.
    count : ndarray of int, shape (K,)
        Links averaged.
    fit : LineFit
        Per component (3 rows): c1 = α, the mean velocity, m/s; c2 = β0, m (zero
        within se_c2 for zero-mean noise); chi2_dof of the line. A WLS line for
        independent runs; with shared particles, the least-squares line and the
        snapshot covariance of the K means (:func:`_mean_displacement_joined`).
    offset_covariance : ndarray, shape (3, 3), or None
        Covariance of the three β0, m² (shared particles only: their components are
        correlated through the snapshots).
    snapshots : int or None
        Snapshots M that covariance was estimated from.
    """

    dt: np.ndarray
    mean: np.ndarray
    se: np.ndarray
    count: np.ndarray
    fit: LineFit
    offset_covariance: np.ndarray | None = None
    snapshots: int | None = None

    @property
    def se_offset_scaled(self) -> np.ndarray:
        """se of β0 times the Birge ratio max(1, sqrt(χ²/dof)), m, shape (3,).

        With a few snapshots per Δt the snapshot scatter underestimates the errors; the
        scatter of the points about the line then shows it, and this scales them up.
        """
        chi2 = np.nan_to_num(self.fit.chi2_dof, nan=1.0)
        return self.fit.se_c2 * np.sqrt(np.maximum(chi2, 1.0))

    def offset_test(self, false_alarm: float = 0.01) -> tuple[float, float]:
        """β0ᵀ C⁻¹ β0 and the limit it stays below when β0 = 0, but for ``false_alarm``.

        C is ``offset_covariance`` when the K means share their particles: estimated
        from M snapshots, so the statistic follows Hotelling's T², 3(M − 1)/(M − 3)
        F(3, M − 3). Otherwise C = diag(``se_offset_scaled``²) and the limit is χ²₃'s.
        """
        if self.offset_covariance is None:
            statistic = float(np.sum((self.fit.c2 / self.se_offset_scaled) ** 2))
            return statistic, float(chi2_distribution.ppf(1 - false_alarm, 3))
        beta = self.fit.c2
        statistic = float(beta @ np.linalg.solve(self.offset_covariance, beta))
        m = self.snapshots
        limit = 3 * (m - 1) / (m - 3) * f_distribution.ppf(1 - false_alarm, 3, m - 3)
        return statistic, float(limit)


@dataclass(frozen=True, eq=False)
class Subset:
    """The multi-Δt fit on a subset of the Δt values.

    Attributes
    ----------
    name : str
        "3 largest dt" or "smallest and largest dt".
    used : ndarray of bool, shape (K,)
        Δt used.
    structure : StructureFunction
        The fit.
    profile : DissipationProfile
        ε(r) of the fit.
    plateau : Plateau or None
        Plateau ε (None when no bin of the range was fitted).
    """

    name: str
    used: np.ndarray
    structure: StructureFunction
    profile: DissipationProfile
    plateau: Plateau | None


@dataclass(frozen=True, eq=False)
class S2Population:
    """The particles whose pairs enter S2 when every Δt shares frame a.

    Attributes
    ----------
    snapshot_ids : ndarray of int, shape (S,)
        Snapshots kept at every Δt.
    positions : tuple of S ndarray, shape (P_s, 3)
        X(t) of the particles linked at every Δt and not dropped by the trajectory test,
        m (in the calibration's frame).
    displacements : tuple of S ndarray, shape (P_s, K, 3)
        Their ΔX at every Δt, m.
    trajectory_outliers : int
        Particles linked at every Δt that the trajectory test dropped.
    """

    snapshot_ids: np.ndarray
    positions: tuple[np.ndarray, ...]
    displacements: tuple[np.ndarray, ...]
    trajectory_outliers: int

    @property
    def count(self) -> int:
        """Particles in the population."""
        return sum(len(x) for x in self.positions)


@dataclass(frozen=True, eq=False)
class PtvStatistics:
    """Second-order statistics of the measured displacements.

    Attributes
    ----------
    dt_index : ndarray of int, shape (K,)
        Dataset Δt indices the statistics use (runs with links).
    dt : ndarray, shape (K,)
        Their Δt, s.
    bins : LogBins
        Separation bins.
    structure : StructureFunction
        S2 = c1 (m²/s²), noise c2 (m²), raw ⟨q⟩/Δt² per Δt, errors, pair counts.
    profile : DissipationProfile
        ε(r) = (S2/C2)^{3/2}/r and the paper's S2^{3/2}/r, m²/s³.
    plateau : Plateau or None
        Plateau ε over ``settings.plateau`` (None when no bin there was fitted).
    subsets : dict of str to Subset
        The paper's Δt subset study (only subsets smaller than the full set).
    mean_displacement : MeanDisplacement
        Linearity check of ⟨ΔX⟩ in Δt.
    grid : Grid
        Eulerian cells.
    eulerian : EulerianFit
        Per-cell fits of ⟨ΔX⟩ and Var ΔX against Δt.
    u_prime : UPrime or None
        u′ from the fitted variance (None when no cell could be fitted).
    position_noise : ndarray, shape (3,)
        σ_b per component from the variance intercept 2σ_b², averaged over cells, m
        (NaN where the average intercept is negative).
    errors : str
        "bootstrap" or "pairs" (when a run has fewer than two snapshots).
    n_snapshots : ndarray of int, shape (K,)
        Snapshots per Δt used.
    population : S2Population or None
        The particles of S2 with a shared first frame (None: each run's own links).
    """

    dt_index: np.ndarray
    dt: np.ndarray
    bins: LogBins
    structure: StructureFunction
    profile: DissipationProfile
    plateau: Plateau | None
    subsets: dict[str, Subset]
    mean_displacement: MeanDisplacement
    grid: Grid
    eulerian: EulerianFit
    u_prime: UPrime | None
    position_noise: np.ndarray
    errors: str
    n_snapshots: np.ndarray
    population: S2Population | None = None


def _plateau(profile: DissipationProfile, settings: PipelineSettings, what: str) -> Plateau | None:
    try:
        return plateau_epsilon(
            profile,
            r_min=settings.plateau[0],
            r_max=settings.plateau[1],
            method=settings.plateau_method,  # type: ignore[arg-type]
        )
    except ValueError as err:
        log.warning("%s: no plateau ε (%s)", what, err)
        return None


def _mean_displacement(runs: Sequence[RunParticles]) -> MeanDisplacement:
    k = len(runs)
    mean, se = np.zeros((k, 3)), np.zeros((k, 3))
    count = np.zeros(k, dtype=np.int64)
    for i, run in enumerate(runs):
        per = [d for _, d in run.snapshot_arrays() if len(d)]
        d = np.concatenate(per) if per else np.empty((0, 3))
        count[i] = len(d)
        if len(d) < 2:
            raise ValueError(
                f"Δt_{run.k} = {run.dt:.4g} s: {len(d)} link(s) in the analysis volume; "
                "too few for statistics"
            )
        if len(per) >= 2:  # cluster (snapshot) standard error
            n = np.array([len(p) for p in per], dtype=np.float64)
            mean[i], se[i] = cluster_mean(n, np.array([p.mean(axis=0) for p in per]))
        else:
            mean[i] = d.mean(axis=0)
            se[i] = d.std(axis=0, ddof=1) / np.sqrt(len(d))
    dt = np.array([r.dt for r in runs])
    sigma = np.where(se > 0, se, np.max(se) if np.max(se) > 0 else 1.0)
    fit = wls_line(np.broadcast_to(dt, (3, k)), mean.T, sigma.T)
    return MeanDisplacement(dt=dt, mean=mean, se=se, count=count, fit=fit)


def _mean_displacement_joined(joined, dt: np.ndarray) -> MeanDisplacement | None:
    """:class:`MeanDisplacement` of the particles followed over every Δt (shared frame a).

    The K means then share their particles, so their errors are correlated, across Δt
    and across components: their covariance Σ comes from the scatter of the snapshot
    means (snapshots are the independent units, :func:`ptv.stats.snapshots.cluster_mean`).
    The line is the least-squares one, c = L·⟨ΔX⟩ with L = (XᵀX)⁻¹Xᵀ fixed by the Δt
    alone, so Cov(c) = L Σ Lᵀ holds exactly and β0ᵀC⁻¹β0 follows Hotelling's T² (a
    GLS line would weigh the Δt by the estimated Σ, and its χ² test raise 2-3 % false
    alarms instead of 1 % at M = 30-40). None when there are too few snapshots (M ≤ K)
    for Σ to be positive definite.
    """
    groups = [d for _, d in joined if len(d)]
    k = len(dt)
    if len(groups) <= k:
        return None
    n = np.array([len(d) for d in groups], dtype=np.float64)
    mean, cov = cluster_mean(n, np.array([d.mean(axis=0) for d in groups]), full=True)
    cov = cov.reshape(k, 3, k, 3)
    per_component = np.stack([cov[:, c, :, c] for c in range(3)])  # (3, K, K)
    if not np.all(np.linalg.eigvalsh(per_component) > 0):
        return None
    design = np.stack([dt, np.ones_like(dt)], axis=1)
    operator = np.linalg.pinv(design)  # (2, K): slope and intercept rows
    coef = np.einsum("pk,kc->pc", operator, mean)  # (2, 3)
    cov_coef = np.einsum("pk,kcld,ql->pcqd", operator, cov, operator)  # (2, 3, 2, 3)
    residual = mean - design @ coef  # (K, 3)
    chi2 = np.array(
        [residual[:, c] @ np.linalg.solve(per_component[c], residual[:, c]) for c in range(3)]
    )
    fit = LineFit(
        c1=coef[0],
        c2=coef[1],
        se_c1=np.sqrt(np.diagonal(cov_coef[0, :, 0, :])),
        se_c2=np.sqrt(np.diagonal(cov_coef[1, :, 1, :])),
        cov_c1c2=np.diagonal(cov_coef[0, :, 1, :]).copy(),
        chi2_dof=chi2 / (k - 2) if k > 2 else np.full(3, np.nan),
        n_points=k,
        method="ols-cluster",
    )
    return MeanDisplacement(
        dt=dt,
        mean=mean,
        se=np.sqrt(np.diagonal(per_component, axis1=1, axis2=2)).T,
        count=np.full(k, int(n.sum())),
        fit=fit,
        offset_covariance=cov_coef[1, :, 1, :].copy(),
        snapshots=len(groups),
    )


def _eulerian(runs: Sequence[RunParticles], dt: np.ndarray, settings: PipelineSettings):
    x, d = [], []
    for run in runs:
        sel = run.used
        x.append(run.positions[sel])
        d.append(run.displacements[sel])
    lower, upper = settings.analysis_volume
    grid = Grid(lower, upper, settings.eulerian_cells)
    fit = eulerian_fit(eulerian_moments(x, d, dt, grid), min_count=settings.min_cell_count)
    if not fit.valid.any() and grid.n_cells > 1:
        log.warning(
            "no Eulerian cell of %s holds %d displacements at every Δt; using one cell",
            "×".join(map(str, settings.eulerian_cells)),
            settings.min_cell_count,
        )
        grid = Grid(lower, upper, (1, 1, 1))
        fit = eulerian_fit(eulerian_moments(x, d, dt, grid), min_count=settings.min_cell_count)
    if fit.valid.any():
        up = u_prime(fit)
        noise = np.nanmean(fit.noise[fit.valid], axis=0)
        with np.errstate(invalid="ignore"):
            sigma_b = np.sqrt(np.where(noise >= 0, noise / 2.0, np.nan))
    else:
        log.warning("no Eulerian cell could be fitted: no u'")
        up, sigma_b = None, np.full(3, np.nan)
    return grid, fit, up, sigma_b


def shared_snapshots(
    runs: Sequence[RunParticles],
) -> tuple[np.ndarray, list[tuple[np.ndarray, np.ndarray]]]:
    """The particles used at every Δt of runs that share their first frames.

    With a shared frame a, a particle has the same measured X(t) in every run, so the
    runs' used links are joined on X(t) (bit for bit), snapshot by snapshot.

    Parameters
    ----------
    runs : sequence of K RunParticles
        Runs whose snapshot m shares frame a.

    Returns
    -------
    (ndarray of int (S,), list of S (ndarray (P, 3), ndarray (P, K, 3)))
        The snapshots kept in every run, and per snapshot X(t), m, and ΔX at each Δt, m.
    """
    per_run = [
        dict(zip(run.snapshot_ids.tolist(), run.snapshot_arrays(), strict=True)) for run in runs
    ]
    common = sorted(set.intersection(*(set(d) for d in per_run)))
    out = []
    for m in common:
        arrays = [d[m] for d in per_run]
        index = [{row.tobytes(): i for i, row in enumerate(x)} for x, _ in arrays]
        keys = [key for key in index[0] if all(key in ix for ix in index[1:])]
        rows = [[ix[key] for key in keys] for ix in index]
        x = arrays[0][0][rows[0]].reshape(-1, 3)
        d = np.stack([a[1][r].reshape(-1, 3) for a, r in zip(arrays, rows, strict=True)], axis=1)
        out.append((x, d))
    return np.array(common, dtype=np.int64), out


def _consistent(joined, dt: np.ndarray, settings: PipelineSettings):
    """The joined particles whose trajectory residual is not an outlier.

    Parameters
    ----------
    joined : list of (ndarray (P, 3), ndarray (P, K, 3))
        X(t) and ΔX at every Δt per snapshot (:func:`shared_snapshots`), m.
    dt : ndarray, shape (K,)
        s.
    settings : PipelineSettings
        ``trajectory_threshold``: the limit in multiples of the median residual.

    Returns
    -------
    list of (ndarray, ndarray)
        The same snapshots without the particles above the limit.
    """
    residuals = [trajectory_residuals(dt, d) for _, d in joined]
    limit = settings.trajectory_threshold * np.median(np.concatenate(residuals))
    kept = [(x[r <= limit], d[r <= limit]) for (x, d), r in zip(joined, residuals, strict=True)]
    dropped = sum(len(x) for x, _ in joined) - sum(len(x) for x, _ in kept)
    log.info(
        "%d particle(s) dropped: trajectory residual above %.3g µm (%g × the median)",
        dropped,
        limit * 1e6,
        settings.trajectory_threshold,
    )
    return kept


def compute_statistics(
    runs: Sequence[RunParticles],
    settings: PipelineSettings,
    *,
    shared_first_frame: bool = False,
) -> PtvStatistics:
    """Multi-Δt statistics of the links in the analysis volume.

    Parameters
    ----------
    runs : sequence of RunParticles
        One per Δt (runs without links are dropped with a warning).
    settings : PipelineSettings
        Bins, plateau range, C2, bootstrap, Eulerian cells.
    shared_first_frame : bool
        The runs share their first frames (:attr:`ptv.dataset.Dataset.shared_first_frame`):
        S2 then uses the particles linked at every Δt, with snapshots resampled jointly
        over all Δt (:func:`shared_snapshots`, :func:`ptv.stats.structure.time_resolved_sums`);
        otherwise every run's links, each run resampled on its own.

    Returns
    -------
    PtvStatistics

    Raises
    ------
    ValueError
        Fewer than two Δt with links in the analysis volume.
    """
    usable = []
    for run in runs:
        n = int(np.count_nonzero(run.used))
        if n < 2:
            log.warning(
                "Δt_%d = %.4g s dropped from the statistics: %d link(s) in the analysis volume",
                run.k,
                run.dt,
                n,
            )
        else:
            usable.append(run)
    if len(usable) < 2:
        raise ValueError(
            f"only {len(usable)} Δt value(s) with particle links in the analysis volume "
            f"{settings.analysis_volume} m: the multi-Δt method needs at least two "
            "(are the frames empty, or the calibration, volume or max speed wrong?)"
        )
    dt = np.array([r.dt for r in usable])
    bins = settings.bins
    if shared_first_frame:
        ids, joined = shared_snapshots(usable)
        if not joined:
            raise ValueError("no snapshot has particles linked at every Δt")
        linked = sum(len(x) for x, _ in joined)
        log.info(
            "shared first frame: %d particles linked at every Δt in %d snapshots",
            linked,
            len(joined),
        )
        if settings.trajectory_threshold is not None and len(usable) >= 4:
            joined = _consistent(joined, dt, settings)
        sums = time_resolved_sums(joined, bins)
        n_snap = np.full(len(usable), len(joined), dtype=np.int64)
        mean_displacement = _mean_displacement_joined(joined, dt)
        population = S2Population(
            snapshot_ids=ids,
            positions=tuple(x for x, _ in joined),
            displacements=tuple(d for _, d in joined),
            trajectory_outliers=linked - sum(len(x) for x, _ in joined),
        )
    else:
        per_run = [r.snapshot_arrays() for r in usable]
        sums = double_frame_sums(per_run, bins)
        n_snap = np.array([len(p) for p in per_run], dtype=np.int64)
        mean_displacement = population = None
    if mean_displacement is None:
        if shared_first_frame:
            log.warning(
                "mean displacement: too few snapshots (%d) for the covariance of the %d "
                "shared means; each Δt's links are averaged on their own",
                len(joined),
                len(usable),
            )
        mean_displacement = _mean_displacement(usable)
    errors = "bootstrap"
    if n_snap.min() < 2:
        log.warning(
            "a Δt has a single snapshot: S2 errors from the pair count (they underestimate)"
        )
        errors = "pairs"

    def fit(use=None) -> StructureFunction:
        return structure_function(
            sums, dt, errors=errors, n_boot=settings.n_boot, use=use, rng=settings.seed
        )

    def profile_of(sf: StructureFunction) -> DissipationProfile:
        return dissipation_profile(
            np.where(np.isfinite(sf.r), sf.r, bins.centres),
            sf.s2,
            se_s2=sf.se_s2,
            s2_boot=sf.s2_boot,
            kolmogorov_c2=settings.kolmogorov_c2,
        )

    structure = fit()
    profile = profile_of(structure)
    plateau = _plateau(profile, settings, "all Δt")
    subsets = {}
    k = dt.size
    for name, idx, needed in (
        ("3 largest dt", lambda: largest_dt(dt, 3), 4),
        ("smallest and largest dt", lambda: smallest_and_largest_dt(dt), 3),
    ):
        if k < needed:
            continue
        use = np.zeros(k, dtype=bool)
        use[idx()] = True
        sf = fit(use)
        prof = profile_of(sf)
        subsets[name] = Subset(name, use, sf, prof, _plateau(prof, settings, name))
    grid, eul, up, sigma_b = _eulerian(usable, dt, settings)
    return PtvStatistics(
        dt_index=np.array([r.k for r in usable], dtype=np.int64),
        dt=dt,
        bins=bins,
        structure=structure,
        profile=profile,
        plateau=plateau,
        subsets=subsets,
        mean_displacement=mean_displacement,
        grid=grid,
        eulerian=eul,
        u_prime=up,
        position_noise=sigma_b,
        errors=errors,
        n_snapshots=n_snap,
        population=population,
    )


# ----------------------------------------------------------------------------- pipeline


@dataclass(frozen=True, eq=False)
class PtvResult:
    """Everything :func:`run_pipeline` measured.

    Attributes
    ----------
    dataset : Dataset
        The folder processed.
    cameras : tuple of str
        Camera order of the count arrays.
    settings : PipelineSettings
        Options used.
    runs : list of RunParticles
        Particles per Δt (all Δt of the dataset).
    statistics : PtvStatistics
        The statistics.
    """

    dataset: Dataset
    cameras: tuple[str, ...]
    settings: PipelineSettings
    runs: list[RunParticles]
    statistics: PtvStatistics


def run_pipeline(
    dataset: Dataset,
    calibrations: Mapping[str, CameraModel],
    settings: PipelineSettings | None = None,
    *,
    progress: Progress | None = None,
) -> PtvResult:
    """Images → particles → links → S2(r), ε, u′ for a whole dataset.

    Parameters
    ----------
    dataset : Dataset
        From :func:`ptv.dataset.open_dataset`.
    calibrations : mapping of camera name to CameraModel
        E.g. :func:`ptv.calibration.io.load_calibrations`; must name exactly the
        dataset's cameras.
    settings : PipelineSettings, optional
        Options (defaults: the paper's volumes and ranges).
    progress : callable(done, total), optional
        Called after each snapshot and after the statistics.

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
    cameras = cameras_in_order(dataset, calibrations)
    counts = [
        dataset.frames[k]
        if settings.snapshots is None
        else min(settings.snapshots, dataset.frames[k])
        for k in range(dataset.n_dt)
    ]
    total = sum(counts) + 1
    done = [0]

    def tick() -> None:
        done[0] += 1
        if progress is not None:
            progress(done[0], total)

    first_frames = SharedFirstFrames() if dataset.shared_first_frame else None
    runs = [
        measure_run(dataset, k, cameras, settings, tick=tick, first_frames=first_frames)
        for k in range(dataset.n_dt)
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
    statistics = compute_statistics(runs, settings, shared_first_frame=dataset.shared_first_frame)
    tick()
    return PtvResult(
        dataset=dataset,
        cameras=dataset.cameras,
        settings=settings,
        runs=runs,
        statistics=statistics,
    )
