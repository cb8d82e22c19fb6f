"""The error a least-squares polynomial fit along a track leaves, from the noise and the
window alone: the reference of :mod:`ptv.tracking.fitting`, written apart from it.

A track of consecutive frames τ₀ apart is measured as X_f = x(fτ₀) + n_f, n white with
variance σ² per component. The documented fit (docs/lagrangian.md §1) gives point k of a
track of L points the least-squares polynomial of degree p through the S = min(W, L)
points of the track nearest to it, (S − 1)/2 on either side where the track allows, the
window shifted inwards at the track's ends; its d-th derivative at the point is a linear
combination Σ_j w_j X_j. The weights here are SciPy's Savitzky–Golay coefficients
(:func:`scipy.signal.savgol_coeffs`, evaluated at the point's position in its window),
not the stack's. Being linear, the estimate splits into the same weights applied to the
exact positions, whose difference from the exact derivative is the window's smoothing
bias b, and to the noise, of variance σ²Σ_j w_j² per component; so its expected squared
error per component is exactly

    E(d̂ − d)² = b² + σ² Σ_j w_j²,

for whatever trajectories the tracks follow. :func:`fit_floor` gives both terms for
every point.
"""

from dataclasses import dataclass

import numpy as np
from scipy.signal import savgol_coeffs

__all__ = ["FitFloor", "fit_floor"]


@dataclass(frozen=True, eq=False)
class FitFloor:
    """The least-squares fit's bias and noise at every point of gap-free tracks.

    Attributes
    ----------
    reference : ndarray, shape (M, 3)
        The fit's d-th derivative computed from the exact positions, m/s^d (NaN where
        not covered).
    bias : ndarray, shape (M, 3)
        ``reference`` less the exact derivative, m/s^d.
    noise_variance : ndarray, shape (M,)
        σ²Σ_j w_j², the noise's variance per component, m²/s^2d.
    covered : ndarray of bool, shape (M,)
        Points of tracks of at least degree + 2 consecutive frames (others: NaN).
    """

    reference: np.ndarray
    bias: np.ndarray
    noise_variance: np.ndarray
    covered: np.ndarray

    @property
    def mean_square(self) -> np.ndarray:
        """b² + σ²Σw² summed over the three components, per point, (M,)."""
        return np.sum(self.bias**2, axis=1) + 3.0 * self.noise_variance


def fit_floor(
    track: np.ndarray,
    frame: np.ndarray,
    position: np.ndarray,
    derivative: np.ndarray,
    frame_rate: float,
    *,
    window: int,
    noise: float,
    order: int,
    degree: int = 3,
) -> FitFloor:
    """Bias and noise of the least-squares fit's ``order``-th derivative at every point.

    Parameters
    ----------
    track, frame : ndarray of int, shape (M,)
        Track id and frame number, rows sorted by track, then frame.
    position : ndarray, shape (M, 3)
        Exact positions, m.
    derivative : ndarray, shape (M, 3)
        The exact ``order``-th derivative of the trajectory at each point, m/s^order.
    frame_rate : float
        Hz.
    window : int
        Points per fit W (a track shorter than W is fitted over all its points).
    noise : float
        σ per component, m.
    order : int
        Derivative d, 0 ≤ d ≤ degree.
    degree : int
        Degree p of the polynomial.

    Returns
    -------
    FitFloor
        A track whose frames are not consecutive is not covered (its rows NaN).
    """
    track, frame = np.asarray(track), np.asarray(frame)
    position = np.asarray(position, dtype=float)
    derivative = np.asarray(derivative, dtype=float)
    m = len(track)
    if frame.shape != (m,) or position.shape != (m, 3) or derivative.shape != (m, 3):
        raise ValueError("track, frame (M,), position and derivative (M, 3) must align")
    if not 0 <= order <= degree:
        raise ValueError(f"order must lie in 0 … {degree}, got {order!r}")
    new_track = np.r_[True, track[1:] != track[:-1]]
    starts = np.flatnonzero(new_track)
    lengths = np.diff(np.r_[starts, m])
    first_row = np.repeat(starts, lengths)
    length = np.repeat(lengths, lengths)
    steps = np.diff(frame)
    gapped = np.zeros(len(starts), dtype=bool)
    inside = ~new_track[1:]
    which = np.cumsum(new_track)[1:] - 1
    np.logical_or.at(gapped, which[inside], steps[inside] != 1)
    index = np.arange(m) - first_row
    size = np.minimum(length, window)
    first = np.clip(index - (size - 1) // 2, 0, length - size)
    at = index - first
    covered = (length >= degree + 2) & ~np.repeat(gapped, lengths)
    reference = np.full((m, 3), np.nan)
    noise_variance = np.full(m, np.nan)
    for s, k in {(int(a), int(b)) for a, b in zip(size[covered], at[covered], strict=True)}:
        rows = np.flatnonzero(covered & (size == s) & (at == k))
        weights = savgol_coeffs(s, degree, deriv=order, delta=1.0 / frame_rate, pos=k, use="dot")
        start = first_row[rows] + first[rows]
        reference[rows] = sum(w * position[start + j] for j, w in enumerate(weights))
        noise_variance[rows] = noise**2 * float(np.sum(weights**2))
    return FitFloor(reference, reference - derivative, noise_variance, covered)
