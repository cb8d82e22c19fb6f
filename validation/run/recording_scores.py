"""The tracks of a rendered run's recordings against their truth: scores, fits, statistics.

For the tracks of one variant (the true cameras or a calibration) over every recording:

1. the points are brought onto the truth (:mod:`validation.score.recorded_tracks`) and
   the recordings joined;
2. the tracks are fitted as ``synptv ptv --tracks`` fits them
   (:func:`ptv.pipeline.track_fit.fit_recording`): those of five points or more
   (shorter ones, mostly ghost matches that no later frame continues, are left as
   unlinked points), the points their fit does not explain taken out (a false point a
   track took where its particle was missed spoils the fits of its neighbours), the
   noise from their second differences, the window chosen from it (or the scenario's
   ``fit_window``);
3. the points kept are the run's tracks;
4. the tracks are scored (:func:`validation.score.trajectories.trajectory_scores`,
   pairs within one object pixel, as ``synptv score`` pairs; a particle is observed
   where as many cameras image it as a match needs), with the fitted velocity and
   acceleration;
5. the fitted acceleration's error is put beside its floor: the same fit, at the same
   window, on the true positions of the same track points plus white noise of the σ_c
   measured where each point is in the sheet's depth (:func:`noise_by_depth`,
   :func:`acceleration_floor`), and both are measured over a range of windows for the
   figure;
6. the Lagrangian statistics, noise removed, beside the exact ones of the same
   population (:mod:`validation.truth.lagrangian`).
"""

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ptv.pipeline.track_fit import fit_recording
from ptv.settings import TrackFitSettings
from ptv.stats.lagrangian import acceleration_variance
from ptv.stats.track_sample import track_sample
from ptv.tracking.fitting import choose_window, fit_tracks
from validation.report.png import save_figure
from validation.report.track_score_figures import (
    fit_window_figure,
    lagrangian_figure,
    track_lengths_figure,
)
from validation.run.experiment import object_pixel
from validation.run.lagrangian_scores import lagrangian_scores, pdf_comparison
from validation.score.recorded_tracks import (
    align_tracks,
    alignment_dict,
    join_sequences,
    true_trajectories,
)
from validation.score.trajectories import (
    TrackPoints,
    TrueTrajectories,
    pair_points,
    trajectory_scores,
)
from validation.truth.recording_truth import RecordingTruth

#: Cameras that must image a particle for it to count as observed, where the matching's
#: fewest cameras are not known.
MIN_CAMERAS = 2
#: Bins of depth in the sheet in which the noise of the floor is measured.
DEPTH_BINS = 4
#: Windows measured for the figure of acceleration error against the window.
FIGURE_WINDOWS = (5, 7, 9, 11, 13, 15, 19, 23, 27, 31)


def long_tracks(tracks: TrackPoints, fewest: int) -> TrackPoints:
    """The tracks of at least ``fewest`` points."""
    _, index = np.unique(tracks.track, return_inverse=True)
    keep = np.bincount(index)[index] >= fewest
    return TrackPoints(tracks.track[keep], tracks.frame[keep], tracks.position[keep])


def _rms(error: np.ndarray) -> float:
    """rms length of the error vectors (N, 3) that are finite."""
    good = np.isfinite(error).all(axis=1)
    return float(np.sqrt(np.mean(np.sum(error[good] ** 2, axis=1))))


def noise_by_depth(tracks: TrackPoints, frame_rate: float, sheet, seed: int):
    """The position noise σ_c where each point is in the sheet's depth, m, (M, 3).

    A particle near the sheet's edge is lit less and found less precisely (on the tr
    recording σ grows from 2 µm at the centre plane to 5–8 µm at the edge), and a
    particle enters and leaves the sheet through its edges, so the ends of the tracks,
    where a fit is most sensitive, are the noisiest points. The points are cut into
    :data:`DEPTH_BINS` equal-count bins of their distance from the sheet's centre plane
    and σ_c is measured in each as for the whole
    (:func:`ptv.stats.lagrangian.acceleration_variance`). Returns the per-point σ_c and
    the table (bin edges, m, and σ_c per bin, µm)."""
    axis = int(np.argmin(sheet.size))
    depth = np.abs(tracks.position[:, axis] - sheet.centre[axis])
    edges = np.quantile(depth, np.linspace(0, 1, DEPTH_BINS + 1))
    which = np.clip(np.searchsorted(edges, depth, side="right") - 1, 0, DEPTH_BINS - 1)
    sigma = np.empty((DEPTH_BINS, 3))
    for b in range(DEPTH_BINS):
        m = which == b
        sample = track_sample(
            tracks.track[m], tracks.frame[m], tracks.position[m], frame_rate, rng=seed
        )
        sigma[b] = np.sqrt(np.maximum(acceleration_variance(sample).noise_variance, 0.0))
    table = {"depth_edges_m": edges.tolist(), "noise_um": (sigma * 1e6).tolist()}
    return sigma[which], table


def acceleration_floor(
    tracks: TrackPoints,
    truth: TrueTrajectories,
    row: np.ndarray,
    frame_rate: float,
    *,
    window: int,
    noise: np.ndarray,
    rng: np.random.Generator,
) -> float:
    """The rms acceleration error of the fit at ``window`` on the true positions of the
    track points paired with a particle (``row`` ≥ 0), each plus white noise of its
    σ_c = ``noise`` (M, 3), with the tracks' ids and frames; m/s²."""
    paired = row >= 0
    scale = noise[paired]
    noisy = truth.position[row[paired]] + rng.normal(size=(paired.sum(), 3)) * scale
    fit = fit_tracks(
        tracks.track[paired],
        tracks.frame[paired],
        noisy,
        frame_rate,
        window=window,
        noise=float(np.sqrt(np.mean(scale**2))),
    )
    return _rms(fit.acceleration - truth.acceleration[row[paired]])


def _fit_errors(tracks, truth, row, frame_rate, window, noise, rng) -> tuple[float, float]:
    """The fitted acceleration's rms error on the tracks and its floor, at ``window``."""
    fit = fit_tracks(
        tracks.track,
        tracks.frame,
        tracks.position,
        frame_rate,
        window=window,
        noise=float(np.sqrt(np.mean(noise**2))),
    )
    paired = row >= 0
    error = _rms(fit.acceleration[paired] - truth.acceleration[row[paired]])
    floor = acceleration_floor(tracks, truth, row, frame_rate, window=window, noise=noise, rng=rng)
    return error, floor


def score_sequences(
    sequences: Sequence[tuple[object, RecordingTruth]],
    *,
    tau_eta: float,
    fit_window: int | None,
    seed: int,
    figures: Path,
    label: str,
) -> dict:
    """Everything the module docstring lists, for one variant's recordings.

    Parameters
    ----------
    sequences : sequence of (PtvResult, RecordingTruth)
        The result of :func:`ptv.pipeline.time_resolved.run_recording` on each recording,
        and its truth.
    tau_eta : float
        The flow's Kolmogorov time, s.
    fit_window : int or None
        Points per track fit (None: chosen).
    seed : int
        Seeds the floor's noise and the bootstrap.
    figures : Path
        Folder the figures are written to.
    label : str
        The figures' title.

    Returns
    -------
    dict
        JSON-able: ``alignment`` (per recording), ``scores``, ``noise_um``, ``fit``,
        ``lagrangian``.
    """
    parts, alignments = [], []
    cameras = sequences[0][0].settings.min_cameras or MIN_CAMERAS
    for result, truth in sequences:
        recording = result.recording
        tracks = TrackPoints(
            recording.tracks.track, recording.frame_number, recording.tracks.positions
        )
        moved, rotation, translation = align_tracks(tracks, truth)
        parts.append((moved, true_trajectories(truth, cameras)))
        alignments.append(alignment_dict(rotation, translation))
    first_truth = sequences[0][1]
    frame_rate, frames = first_truth.frame_rate, len(first_truth.times)
    joined, truth = join_sequences(parts, frames)
    radius = object_pixel(first_truth.rig)
    track_fit = fit_recording(
        joined.track,
        joined.frame,
        joined.position,
        frame_rate,
        TrackFitSettings(fit_window=fit_window),
        seed=seed,
    )
    kept = track_fit.kept
    tracks = TrackPoints(joined.track[kept], joined.frame[kept], joined.position[kept])
    row = pair_points(truth, tracks, radius)
    rng = np.random.default_rng(seed)
    lagrangian, noise = lagrangian_scores(
        tracks, truth, row, frame_rate, tau_eta, frames=frames, seed=seed
    )
    fitted, window = track_fit.fitted, track_fit.fitted.window
    sigma = float(np.sqrt(np.mean(track_fit.noise**2)))
    choice = track_fit.choice
    if choice is None:  # a window given: the prediction drawn beside it all the same
        choice = choose_window(tracks.track, tracks.frame, tracks.position, frame_rate, sigma)
    scored = TrackPoints(
        tracks.track, tracks.frame, tracks.position, fitted.velocity, fitted.acceleration
    )
    scores = trajectory_scores(truth, scored, radius)
    lagrangian["acceleration_pdf"] = pdf_comparison(fitted, truth, row)
    windows = [w for w in FIGURE_WINDOWS if w <= choice.windows.max()]
    local_noise, noise_table = noise_by_depth(tracks, frame_rate, first_truth.rig.sheet, seed)
    measured = [_fit_errors(tracks, truth, row, frame_rate, w, local_noise, rng) for w in windows]
    paired = row >= 0
    error = _rms(fitted.acceleration[paired] - truth.acceleration[row[paired]])
    floor = acceleration_floor(
        tracks, truth, row, frame_rate, window=window, noise=local_noise, rng=rng
    )
    fit = {
        "window": window,
        "chosen": fit_window is None,
        "degree": fitted.degree,
        "noise_um": sigma * 1e6,
        "noise_by_depth": noise_table,
        "acceleration_rms_error": error,
        "floor_acceleration_rms_error": floor,
        "floor_ratio": error / floor,
        "predicted": {
            "windows": choice.windows.tolist(),
            "noise_rms": choice.noise_rms.tolist(),
            "bias_rms": [None if not np.isfinite(v) else float(v) for v in choice.bias_rms],
            "total_rms": [None if not np.isfinite(v) else float(v) for v in choice.total_rms],
            "resolved": bool(choice.resolved),
        },
        "measured": {
            "windows": windows,
            "error": [m[0] for m in measured],
            "floor": [m[1] for m in measured],
        },
        "median_error_estimate": float(np.nanmedian(fitted.acceleration_error)),
    }
    save_figure(track_lengths_figure(scores, label), figures / "track_lengths.png")
    save_figure(fit_window_figure(fit, label), figures / "fit_window.png")
    save_figure(lagrangian_figure(lagrangian, label), figures / "lagrangian.png")
    return {
        "alignment": alignments,
        "track_fit": track_fit.as_dict(),
        "noise_um": (noise * 1e6).tolist(),
        "scores": scores,
        "fit": fit,
        "lagrangian": lagrangian,
    }
