"""A recording's tracks fitted as ``synptv ptv --tracks`` and ``synptv run`` fit them.

:func:`fit_recording` (docs/lagrangian.md §1–§3):

1. keeps the tracks of at least ``min_points`` points (a cubic and one degree of
   freedom);
2. measures the position noise σ_c per component from their second differences over
   steps of 1, 2 and 3 frames (:func:`ptv.stats.lagrangian.acceleration_variance`);
3. takes out the points their fit does not explain
   (:func:`ptv.tracking.fitting.track_outliers`, at the window chosen from that noise)
   and the tracks left shorter than ``min_points``;
4. measures σ_c again on what is left, chooses the window from it
   (:func:`ptv.tracking.fitting.choose_window`) unless one is given, and fits every
   point kept (:func:`ptv.tracking.fitting.fit_tracks`);
5. when asked, computes the Lagrangian statistics of the kept points with the noise
   removed (:func:`ptv.stats.lagrangian.lagrangian_statistics`).
"""

from dataclasses import dataclass

import numpy as np

from ptv.settings import TrackFitSettings
from ptv.stats.lagrangian import (
    LagrangianStatistics,
    acceleration_variance,
    lagrangian_statistics,
)
from ptv.stats.track_sample import track_sample
from ptv.tracking.fitting import (
    FittedTracks,
    WindowChoice,
    choose_window,
    fit_tracks,
    track_outliers,
)

__all__ = ["FittedRecording", "fit_recording"]


@dataclass(frozen=True, eq=False)
class FittedRecording:
    """What :func:`fit_recording` gives.

    Attributes
    ----------
    kept : ndarray of bool, shape (M,)
        The given points that are fitted: on tracks of ``min_points`` or more, not
        outliers.
    fitted : FittedTracks
        The fit of the kept points, in their given order.
    noise : ndarray, shape (3,)
        σ_c of the kept points, m.
    choice : WindowChoice or None
        The window choice (None when the window was given).
    outliers : int
        Points taken out as outliers.
    statistics : LagrangianStatistics or None
        ⟨a²⟩, S2ᴸ, ⟨|u|²⟩ and ρ of the kept points, the noise removed, when asked for.
    """

    kept: np.ndarray
    fitted: FittedTracks
    noise: np.ndarray
    choice: WindowChoice | None
    outliers: int
    statistics: LagrangianStatistics | None = None

    def as_dict(self) -> dict:
        """JSON-able summary, SI units."""
        return {
            "window": self.fitted.window,
            "window_chosen": self.choice is not None,
            "noise": self.noise.tolist(),
            "points": int(self.kept.sum()),
            "points_left_out": int((~self.kept).sum()),
            "outliers": self.outliers,
            "tracks": len(np.unique(self.fitted.track)),
            "lagrangian": None if self.statistics is None else self.statistics.as_dict(),
        }


def _long(track: np.ndarray, keep: np.ndarray, fewest: int) -> np.ndarray:
    """``keep`` less the points of tracks with fewer than ``fewest`` kept points."""
    _, index = np.unique(track, return_inverse=True)
    counts = np.bincount(index, weights=keep)
    return keep & (counts[index] >= fewest)


def _noise(track, frame, position, frame_rate, seed) -> np.ndarray:
    sample = track_sample(track, frame, position, frame_rate, rng=seed)
    return np.sqrt(np.maximum(acceleration_variance(sample).noise_variance, 0.0))


def fit_recording(
    track: np.ndarray,
    frame: np.ndarray,
    position: np.ndarray,
    frame_rate: float,
    settings: TrackFitSettings | None = None,
    *,
    seed: int = 0,
    statistics: bool = False,
) -> FittedRecording:
    """Fit a recording's tracks (module docstring).

    Parameters
    ----------
    track, frame : ndarray of int, shape (M,)
        Track id and frame number of every point.
    position : ndarray, shape (M, 3)
        m.
    frame_rate : float
        Hz.
    settings : TrackFitSettings, optional
    seed : int
        Seeds the bootstraps.
    statistics : bool
        Also compute the Lagrangian statistics of the kept points
        (:func:`ptv.stats.lagrangian.lagrangian_statistics`).

    Returns
    -------
    FittedRecording

    Raises
    ------
    ValueError
        No track long enough to fit.

    Examples
    --------
    Twenty tracks of 40 frames at 1 kHz, each at a constant acceleration, measured with
    2 µm of noise: the noise is measured on the tracks themselves, and the fitted
    accelerations are within a few of their standard errors of the true ones.

    >>> import numpy as np
    >>> import ptv
    >>> rng = np.random.default_rng(0)
    >>> rate = 1000.0  # Hz
    >>> t = np.arange(40)[:, None] / rate
    >>> x0, v, a = (rng.normal(0, scale, (20, 1, 3)) for scale in (5e-3, 0.1, 5.0))
    >>> paths = x0 + v * t + a / 2 * t**2  # (tracks, frames, 3), m
    >>> measured = paths + rng.normal(0, 2e-6, paths.shape)
    >>> track, frame = np.repeat(np.arange(20), 40), np.tile(np.arange(40), 20)
    >>> result = ptv.fit_recording(track, frame, measured.reshape(-1, 3), rate)
    >>> bool(np.all(np.abs(result.noise - 2e-6) < 0.2e-6))  # per component, m
    True
    >>> error = result.fitted.acceleration - np.repeat(a[:, 0], 40, axis=0)  # m/s²
    >>> bool(np.all(np.abs(error) < 5 * result.fitted.acceleration_error[:, None]))
    True
    """
    settings = TrackFitSettings() if settings is None else settings
    track, frame = np.asarray(track), np.asarray(frame)
    position = np.asarray(position, dtype=float)
    keep = _long(track, np.ones(len(track), dtype=bool), settings.min_points)
    if not keep.any():
        raise ValueError(f"no track of {settings.min_points} points or more to fit")
    rows = np.flatnonzero(keep)
    noise = _noise(track[rows], frame[rows], position[rows], frame_rate, seed)
    sigma = float(np.sqrt(np.mean(noise**2)))
    first = choose_window(track[rows], frame[rows], position[rows], frame_rate, sigma).window
    outlier = np.zeros(len(track), dtype=bool)
    outlier[rows] = track_outliers(
        track[rows], frame[rows], position[rows], frame_rate, window=first, noise=noise
    )
    keep = _long(track, keep & ~outlier, settings.min_points)
    rows = np.flatnonzero(keep)
    noise = _noise(track[rows], frame[rows], position[rows], frame_rate, seed)
    sigma = float(np.sqrt(np.mean(noise**2)))
    choice = None
    window = settings.fit_window
    if window is None:
        choice = choose_window(track[rows], frame[rows], position[rows], frame_rate, sigma)
        window = choice.window
    fitted = fit_tracks(
        track[rows], frame[rows], position[rows], frame_rate, window=window, noise=sigma
    )
    found = None
    if statistics:
        found = lagrangian_statistics(
            track[rows], frame[rows], position[rows], frame_rate, rng=seed
        )
    return FittedRecording(keep, fitted, noise, choice, int(outlier.sum()), found)
