"""Tracks sorted and indexed for the Lagrangian statistics, with their bootstrap draws.

Tracks are independent; the points of one are not. :func:`track_sample` sorts the
points by track and frame and draws ``resamples`` bootstrap replicates of the tracks
once (whole tracks, with replacement); :meth:`TrackSample.means` keeps every mean as
per-track sums, so that each replicate of a mean is one contraction with the draws
(:mod:`ptv.stats.lagrangian`).
"""

from dataclasses import dataclass

import numpy as np

__all__ = ["TrackSample", "track_sample"]


@dataclass(frozen=True, eq=False)
class TrackSample:
    """Tracks sorted and indexed for the statistics, with their bootstrap draws.

    Attributes
    ----------
    track : ndarray of int, shape (M,)
        Track index 0 … T − 1 (in the order of the given ids); rows sorted by track,
        then frame.
    frame : ndarray of int, shape (M,)
        Frame number.
    position : ndarray, shape (M, 3)
        m.
    frame_rate : float
        Hz.
    draws : ndarray of int, shape (R, T)
        Times each track is drawn in each bootstrap replicate.
    """

    track: np.ndarray
    frame: np.ndarray
    position: np.ndarray
    frame_rate: float
    draws: np.ndarray

    @property
    def tau(self) -> float:
        """Frame interval τ₀, s."""
        return 1.0 / self.frame_rate

    def rows(self, offset: int) -> np.ndarray:
        """Row of the same track at frame + ``offset`` for every row, −1 where none, (M,)."""
        stride = int(self.frame.max() - self.frame.min()) + 1
        key = self.track * stride + (self.frame - self.frame.min())
        found = np.searchsorted(key, key + offset)
        found = np.minimum(found, len(key) - 1)
        hit = (key[found] == key + offset) & (self.track[found] == self.track)
        return np.where(hit, found, -1)

    def means(self, rows: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Mean of ``values`` (n, Q) over ``rows`` (n,), and its bootstrap replicates.

        Returns
        -------
        mean : ndarray, shape (Q,)
        replicates : ndarray, shape (R, Q)
        """
        tracks = self.draws.shape[1]
        which = self.track[rows]
        sums = np.stack([np.bincount(which, weights=v, minlength=tracks) for v in values.T], axis=1)
        counts = np.bincount(which, minlength=tracks).astype(float)
        drawn = self.draws @ counts
        return sums.sum(axis=0) / counts.sum(), (self.draws @ sums) / drawn[:, None]


def track_sample(
    track: np.ndarray,
    frame: np.ndarray,
    position: np.ndarray,
    frame_rate: float,
    *,
    resamples: int = 200,
    rng: np.random.Generator | int | None = 0,
) -> TrackSample:
    """Sort and index tracks, and draw their bootstrap replicates.

    Parameters
    ----------
    track, frame : ndarray of int, shape (M,)
        Track id and frame number; (track, frame) unique.
    position : ndarray, shape (M, 3)
        Measured positions, m.
    frame_rate : float
        Hz.
    resamples : int
        Bootstrap replicates R ≥ 2.
    rng : numpy.random.Generator, int or None
        Randomness of the draws.

    Returns
    -------
    TrackSample
    """
    track, frame = np.asarray(track), np.asarray(frame)
    position = np.asarray(position, dtype=float)
    if track.ndim != 1 or frame.shape != track.shape or position.shape != (len(track), 3):
        raise ValueError(
            f"track, frame (M,) and position (M, 3) must align, got {track.shape}, "
            f"{frame.shape}, {position.shape}"
        )
    if len(track) == 0:
        raise ValueError("no track points")
    for name, a in (("track", track), ("frame", frame)):
        if not np.issubdtype(a.dtype, np.integer):
            raise ValueError(f"{name} must hold integers, got {a.dtype}")
    if not np.isfinite(position).all():
        raise ValueError("position holds non-finite values")
    if not (np.isfinite(frame_rate) and frame_rate > 0):
        raise ValueError(f"frame_rate must be finite and > 0 Hz, got {frame_rate!r}")
    if not isinstance(resamples, int) or resamples < 2:
        raise ValueError(f"resamples must be an integer >= 2, got {resamples!r}")
    ids, index = np.unique(track, return_inverse=True)
    order = np.lexsort((frame, index))
    index, frame = index[order].astype(np.int64), frame[order].astype(np.int64)
    if np.any((np.diff(frame) < 1) & (np.diff(index) == 0)):
        raise ValueError("a track holds the same frame twice")
    draws = np.random.default_rng(rng).multinomial(
        len(ids), np.full(len(ids), 1.0 / len(ids)), size=resamples
    )
    return TrackSample(index, frame, position[order], float(frame_rate), draws)
