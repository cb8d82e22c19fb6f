"""Track fitting: position, velocity and acceleration of every track point by local
polynomial least squares, and the fit window chosen from the noise and the flow.

Fit (:func:`fit_tracks`). Each point is given the least-squares polynomial of degree p
(3 by default) through the W points of its track nearest to it in the track's order:
(W − 1)/2 before and after it where the track allows, the window shifted inwards at the
track's ends, so that every fit uses W points. Times are the actual frame numbers over
the frame rate, taken relative to the point's own time, so a track that skips frames is
fitted across its gap with the right spacing. The polynomial's value and first two
derivatives at the point are its position, velocity and acceleration. Each is a linear
combination Σ_j w_kj X_j of the window's positions, with weights w = k!·(VᵀV)⁻¹Vᵀ of the
window's Vandermonde matrix V; for white noise of σ per component the standard errors
are σ·sqrt(Σ_j w_kj²) = σ·sqrt(k!²·[(VᵀV)⁻¹]_kk), the same for each component. The
weights depend only on the pattern of the window's time offsets, and a recording has
few patterns (one in a track's interior without gaps, W − 1 at its ends, a few more per
gap), so they are computed once per pattern and all points are fitted at once.
A track shorter than W but of at least p + 2 points (one more than the parameters, so
that the fit smooths) is fitted over all its points; a shorter track is left NaN.

Window (:func:`choose_window`). A larger window averages the noise down but smooths
the acceleration. With the centred fit's acceleration weights w_i (times t_i = i τ,
|i| ≤ (W − 1)/2) the mean-square error of the acceleration is, per component,

    E²(W) = σ² Σ w_i² + β(W)² ⟨x⁽⁴⁾²⟩,     β(W) = Σ w_i t_i⁴ / 4!,

- noise: the estimate is linear in the positions, so white noise contributes exactly
  σ²Σw_i²;
- bias: applied to the Taylor series of the trajectory about the centre, the weights
  give Σ_k x⁽ᵏ⁾ Σ_i w_i t_i^k / k!. They reproduce polynomials of degree ≤ p exactly
  (Σ w_i t_i^k = 2 for k = 2, 0 for the other k ≤ p), and a centred window's
  acceleration weights are even in t, so every odd power cancels too: for p = 3 the
  first term the fit does not reproduce is t⁴, hence β·x⁽⁴⁾, with β exact from the
  weights. Higher terms (t⁶, …) grow faster with W, so the formula is the small-window
  limit of the bias, and underestimates it once Wτ approaches the time scale of x⁽⁴⁾;
- ⟨|x⁽⁴⁾|²⟩ from the tracks themselves: the centred degree-5 fit's fourth-derivative
  weights v_i over W₄ consecutive frames give x⁽⁴⁾ plus a bias of order (W₄τ)² x⁽⁶⁾
  (t⁵ cancels by symmetry) plus noise of variance σ²Σv_i² per component, which is
  subtracted from the mean square. The noise falls fast with W₄ (∝ W₄⁻⁹) while the
  smoothing bias grows, so W₄ is the smallest window at which the estimate stands
  :data:`SIGNIFICANCE` standard errors above zero; the standard error comes from the
  per-track sums (tracks are independent, the points of a track are not). The
  optimal W varies as (σ²/⟨x⁽⁴⁾²⟩)^(1/9) for p = 3, so even a 30 % error in the
  estimate moves it by only 3 %. When no W₄ resolves ⟨x⁽⁴⁾²⟩ (too much noise, too few
  or too short tracks), the bias cannot be predicted: the result says so and the
  largest candidate window is taken, as noise then dominates at every window.

The candidate windows run from the smallest odd W ≥ p + 2 to the largest odd W not
beyond the track length of the median point (so that the centred fit describes most
points), unless given.
"""

from dataclasses import dataclass
from math import factorial

import numpy as np

__all__ = [
    "MIN_FIT_POINTS",
    "OUTLIER_CHI2",
    "SIGNIFICANCE",
    "FittedTracks",
    "WindowChoice",
    "centred_weights",
    "choose_window",
    "fit_tracks",
    "track_outliers",
]

#: Standard errors above zero at which ⟨|x⁽⁴⁾|²⟩ counts as resolved.
SIGNIFICANCE = 3.0
#: Degree of the fit whose fourth derivative estimates x⁽⁴⁾.
FOURTH_DERIVATIVE_DEGREE = 5
#: Fewest points of a cubic fit that smooths (four parameters and one degree of freedom).
MIN_FIT_POINTS = 5
#: χ² (three degrees of freedom) of a point's residual beyond which it is an outlier:
#: exceeded by Gaussian noise with probability 10⁻⁶.
OUTLIER_CHI2 = 30.66
#: Most rounds of :func:`track_outliers` (one point per track per round).
OUTLIER_ROUNDS = 10


@dataclass(frozen=True, eq=False)
class FittedTracks:
    """Every track point's fitted position, velocity and acceleration.

    Attributes
    ----------
    track, frame : ndarray of int, shape (M,)
        As given, in the given order.
    position, velocity, acceleration : ndarray, shape (M, 3)
        The fit at the point, m, m/s, m/s²; NaN on tracks of fewer than degree + 2
        points.
    position_error, velocity_error, acceleration_error : ndarray, shape (M,)
        Standard errors per component from the position noise, m, m/s, m/s²; NaN where
        the fit is.
    window : int
        Points per fit (tracks shorter than it use all their points).
    degree : int
        Degree of the polynomial.
    frame_rate : float
        Hz.
    """

    track: np.ndarray
    frame: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    position_error: np.ndarray
    velocity_error: np.ndarray
    acceleration_error: np.ndarray
    window: int
    degree: int
    frame_rate: float


@dataclass(frozen=True, eq=False)
class WindowChoice:
    """The fit window of least predicted acceleration error.

    Attributes
    ----------
    window : int
        The chosen window.
    windows : ndarray of int, shape (K,)
        Candidate windows.
    noise_rms, bias_rms, total_rms : ndarray, shape (K,)
        Predicted rms of the acceleration error vector (three components) from the
        noise, from the bias, and both, m/s²; bias and total NaN when not resolved.
    fourth_derivative_mean_square : float
        Estimated ⟨|x⁽⁴⁾|²⟩ (sum of components), m²/s⁸.
    fourth_derivative_se : float
        Its standard error, m²/s⁸.
    fourth_derivative_window : int
        The window W₄ of the degree-5 fit that estimated it.
    resolved : bool
        Whether ⟨|x⁽⁴⁾|²⟩ is significantly positive; if not, the largest window was
        taken and the estimate is the one at the largest W₄ tried.
    degree : int
        Degree of the track fit.
    noise : float
        σ per component, m.
    """

    window: int
    windows: np.ndarray
    noise_rms: np.ndarray
    bias_rms: np.ndarray
    total_rms: np.ndarray
    fourth_derivative_mean_square: float
    fourth_derivative_se: float
    fourth_derivative_window: int
    resolved: bool
    degree: int
    noise: float


def _derivative_weights(offsets: np.ndarray, valid: np.ndarray, degree: int) -> np.ndarray:
    """Least-squares weights of the derivatives at offset 0, in frame units.

    Parameters
    ----------
    offsets : ndarray of int, shape (P, W)
        Frame offsets of each window's points from the fitted point.
    valid : ndarray of bool, shape (P, W)
        Which entries are points (a short track's window is padded).
    degree : int
        Polynomial degree p.

    Returns
    -------
    ndarray, shape (P, p + 1, W)
        Row k: the k-th derivative at 0 is Σ_j w_kj X_j, per frame^k; 0 at padding.
    """
    scale = np.maximum(np.max(np.abs(offsets) * valid, axis=1), 1).astype(float)  # conditioning
    t = offsets / scale[:, None]
    powers = np.arange(degree + 1)
    vandermonde = (t[..., None] ** powers) * valid[..., None]
    # The pseudo-inverse's columns of zero rows (padding) are zero.
    pinv = np.linalg.pinv(vandermonde)
    factor = np.array([factorial(k) for k in powers]) / scale[:, None] ** powers
    return pinv * factor[..., None]


def centred_weights(window: int, *, degree: int = 3, frame_rate: float = 1.0) -> np.ndarray:
    """The centred fit's weights of the position and its derivatives at the centre.

    Parameters
    ----------
    window : int
        Odd number of consecutive frames W ≥ degree + 1.
    degree : int
        Polynomial degree p ≥ 0.
    frame_rate : float
        Hz (1 gives frame units).

    Returns
    -------
    ndarray, shape (p + 1, W)
        Row k: x⁽ᵏ⁾(0) = Σ_i w_ki X(t_i), t_i = i/frame_rate, i = −(W−1)/2 … (W−1)/2; units
        1/s^k.
    """
    if not isinstance(degree, int | np.integer) or degree < 0:
        raise ValueError(f"degree must be an integer >= 0, got {degree!r}")
    if not isinstance(window, int | np.integer) or window % 2 != 1 or window < degree + 1:
        raise ValueError(f"window must be an odd integer >= degree + 1, got {window!r}")
    _check_rate(frame_rate)
    half = window // 2
    offsets = np.arange(-half, half + 1)[None, :]
    w = _derivative_weights(offsets, np.ones_like(offsets, dtype=bool), int(degree))[0]
    return w * float(frame_rate) ** np.arange(degree + 1)[:, None]


def _check_rate(frame_rate) -> float:
    if not (np.isfinite(frame_rate) and frame_rate > 0):
        raise ValueError(f"frame_rate must be finite and > 0 Hz, got {frame_rate!r}")
    return float(frame_rate)


def _check_tracks(track, frame, position):
    """Validated arrays and the order that sorts them by track, then frame."""
    track = np.asarray(track)
    frame = np.asarray(frame)
    position = np.asarray(position, dtype=float)
    if track.ndim != 1 or frame.shape != track.shape or position.shape != (len(track), 3):
        raise ValueError(
            f"track, frame (M,) and position (M, 3) must align, got {track.shape}, "
            f"{frame.shape}, {position.shape}"
        )
    for name, a in (("track", track), ("frame", frame)):
        if len(a) and not np.issubdtype(a.dtype, np.integer):
            raise ValueError(f"{name} must hold integers, got {a.dtype}")
    if not np.isfinite(position).all():
        raise ValueError("position holds non-finite values")
    order = np.lexsort((frame, track))
    same = track[order][1:] == track[order][:-1]
    if np.any(np.diff(frame[order])[same] < 1):
        raise ValueError("a track holds the same frame twice")
    return track.astype(np.int64), frame.astype(np.int64), position, order


def _runs(track: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per point of a sorted track array: its track's first row and its track's length."""
    starts = np.flatnonzero(np.r_[True, track[1:] != track[:-1]])
    lengths = np.diff(np.r_[starts, len(track)])
    which = np.repeat(np.arange(len(starts)), lengths)
    return starts[which], lengths[which]


def _window_patterns(offsets: np.ndarray, valid: np.ndarray, lead: np.ndarray):
    """The distinct windows and each point's index among them.

    Parameters
    ----------
    offsets : ndarray of int, shape (N, W)
        Frame offsets of each point's window from the point (0 at padding).
    valid : ndarray of bool, shape (N, W)
        Which entries are points; each row's first ``size`` entries.
    lead : ndarray of int, shape (N,)
        Points of the window before the point.

    Returns
    -------
    patterns : ndarray of int, shape (P, W)
    in_window : ndarray of bool, shape (P, W)
    pattern : ndarray of int, shape (N,)

    Notes
    -----
    A window of consecutive frames is fixed by its size and ``lead``, so those rows are
    grouped by that pair (a 1-D sort); only windows across a gap are compared whole.
    """
    n, window = offsets.shape
    size = valid.sum(axis=1)
    last = offsets[np.arange(n), size - 1]
    regular = np.flatnonzero(last - offsets[:, 0] == size - 1)
    gapped = np.flatnonzero(last - offsets[:, 0] != size - 1)
    pattern = np.empty(n, dtype=np.int64)
    _, first, pattern[regular] = np.unique(
        size[regular] * window + lead[regular], return_index=True, return_inverse=True
    )
    keys = np.where(valid[gapped], offsets[gapped], np.iinfo(np.int64).min)
    if len(gapped):
        keys, inverse = np.unique(keys, axis=0, return_inverse=True)
        pattern[gapped] = len(first) + inverse.ravel()
    in_window = np.concatenate([valid[regular[first]], keys != np.iinfo(np.int64).min])
    patterns = np.where(in_window, np.concatenate([offsets[regular[first]], keys]), 0)
    return patterns, in_window, pattern


def fit_tracks(
    track: np.ndarray,
    frame: np.ndarray,
    position: np.ndarray,
    frame_rate: float,
    *,
    window: int,
    noise: float,
    degree: int = 3,
) -> FittedTracks:
    """Fit a polynomial of ``degree`` in time through the ``window`` points about each point.

    Parameters
    ----------
    track : ndarray of int, shape (M,)
        Track id.
    frame : ndarray of int, shape (M,)
        Frame number; distinct within a track, which may skip frames.
    position : ndarray, shape (M, 3)
        Measured positions, m.
    frame_rate : float
        Hz.
    window : int
        Points per fit, odd, ≥ degree + 2.
    noise : float
        Position noise σ per component, m, ≥ 0 (sets the standard errors only).
    degree : int
        Polynomial degree, ≥ 2.

    Returns
    -------
    FittedTracks
        Rows in the given order (module docstring).

    Examples
    --------
    One track of 9 points at 1 kHz under a constant acceleration of 20 m/s² along X:
    the cubic fit over 5 points is exact, and the standard errors for 1 µm of noise
    grow at the track's ends, where the window is shifted inwards.

    >>> import numpy as np
    >>> import ptv
    >>> rate = 1000.0  # Hz
    >>> t = np.arange(9) / rate
    >>> position = np.zeros((9, 3))
    >>> position[:, 0] = 0.1 * t + 10.0 * t**2  # m
    >>> fit = ptv.fit_tracks(np.zeros(9, dtype=int), np.arange(9), position, rate,
    ...                      window=5, noise=1e-6)
    >>> bool(np.allclose(fit.velocity[:, 0], 0.1 + 20.0 * t))  # m/s
    True
    >>> bool(np.allclose(fit.acceleration, [20.0, 0.0, 0.0]))  # m/s²
    True
    >>> fit.acceleration_error.round(3)  # m/s²
    array([3.207, 1.669, 0.535, 0.535, 0.535, 0.535, 0.535, 1.669, 3.207])
    """
    if not isinstance(degree, int | np.integer) or degree < 2:
        raise ValueError(f"degree must be an integer >= 2, got {degree!r}")
    if not isinstance(window, int | np.integer) or window % 2 != 1 or window < degree + 2:
        raise ValueError(f"window must be an odd integer >= degree + 2, got {window!r}")
    if not (np.isfinite(noise) and noise >= 0):
        raise ValueError(f"noise must be finite and >= 0 m, got {noise!r}")
    rate = _check_rate(frame_rate)
    track, frame, position, order = _check_tracks(track, frame, position)
    degree, window = int(degree), int(window)
    m = len(track)
    out = np.full((4, m, 3), np.nan)  # position, velocity, acceleration, errors
    tr, fr, x = track[order], frame[order], position[order]
    start, length = _runs(tr)
    fitted = np.flatnonzero(length >= degree + 2)
    if len(fitted):
        start, length = start[fitted], length[fitted]
        size = np.minimum(length, window)
        k = fitted - start
        first = start + np.clip(k - (size - 1) // 2, 0, length - size)
        j = np.arange(window)
        valid = j < size[:, None]
        rows = np.where(valid, first[:, None] + j, fitted[:, None])
        offsets = np.where(valid, fr[rows] - fr[fitted][:, None], 0)
        patterns, in_window, pattern = _window_patterns(offsets, valid, k - (first - start))
        w = _derivative_weights(patterns, in_window, degree)[:, :3]
        w *= (rate ** np.arange(3))[None, :, None]
        estimate = np.zeros((len(fitted), 3, 3))
        for c in range(window):
            estimate += w[pattern, :, c, None] * x[rows[:, c], None, :]
        error = noise * np.sqrt(np.sum(w**2, axis=2))  # (P, 3)
        out[:3, order[fitted]] = np.moveaxis(estimate, 1, 0)
        out[3, order[fitted]] = error[pattern]
    return FittedTracks(
        track=track,
        frame=frame,
        position=out[0],
        velocity=out[1],
        acceleration=out[2],
        position_error=out[3, :, 0],
        velocity_error=out[3, :, 1],
        acceleration_error=out[3, :, 2],
        window=window,
        degree=degree,
        frame_rate=rate,
    )


def _fourth_derivative(tr, fr, x, rate, noise, window):
    """⟨|x⁽⁴⁾|²⟩ from the centred degree-5 fit over ``window`` consecutive frames.

    Returns the noise-subtracted mean square and its standard error from the per-track
    sums, m²/s⁸ (NaN, NaN where no point has such a window).
    """
    v = centred_weights(window, degree=FOURTH_DERIVATIVE_DEGREE, frame_rate=rate)[4]
    half = window // 2
    centre = np.arange(half, len(tr) - half)
    ends = (centre - half, centre + half)
    full = (tr[ends[0]] == tr[ends[1]]) & (fr[ends[1]] - fr[ends[0]] == 2 * half)
    centre = centre[full]
    if len(centre) == 0:
        return np.nan, np.nan
    z = np.zeros((len(centre), 3))
    for j, weight in enumerate(v):
        z += weight * x[centre - half + j]
    square = np.sum(z**2, axis=1)
    mean = square.mean()
    _, which = np.unique(tr[centre], return_inverse=True)
    sums = np.bincount(which, weights=square)
    counts = np.bincount(which)
    tracks = len(sums)
    spread = np.sum((sums - mean * counts) ** 2) * tracks / max(tracks - 1, 1)
    return mean - 3 * noise**2 * np.sum(v**2), np.sqrt(spread) / len(centre)


def _fourth_derivative_windows(largest: int) -> np.ndarray:
    """Odd W₄ from the degree-5 fit's smallest, 7, to ``largest``, about 20 % apart."""
    smallest = FOURTH_DERIVATIVE_DEGREE + 2
    if largest < smallest:
        return np.empty(0, dtype=int)
    count = int(np.ceil(np.log(largest / smallest) / np.log(1.2))) + 1
    odd = 2 * np.round((np.geomspace(smallest, largest, count) - 1) / 2).astype(int) + 1
    return np.unique(odd)


def choose_window(
    track: np.ndarray,
    frame: np.ndarray,
    position: np.ndarray,
    frame_rate: float,
    noise: float,
    *,
    degree: int = 3,
    windows=None,
) -> WindowChoice:
    """The window of :func:`fit_tracks` of least predicted acceleration error.

    Parameters
    ----------
    track, frame : ndarray of int, shape (M,)
        Track id and frame number (as :func:`fit_tracks`).
    position : ndarray, shape (M, 3)
        Measured positions, m.
    frame_rate : float
        Hz.
    noise : float
        Position noise σ per component, m, ≥ 0.
    degree : int
        Degree of the track fit, 2 or 3 (for either the centred acceleration's first
        unreproduced term is t⁴; module docstring).
    windows : sequence of int, optional
        Candidate windows, odd, ≥ degree + 2 (default: module docstring).

    Returns
    -------
    WindowChoice
    """
    if degree not in (2, 3):
        raise ValueError(f"degree must be 2 or 3, got {degree!r}")
    if not (np.isfinite(noise) and noise >= 0):
        raise ValueError(f"noise must be finite and >= 0 m, got {noise!r}")
    rate = _check_rate(frame_rate)
    track, frame, position, order = _check_tracks(track, frame, position)
    tr, fr, x = track[order], frame[order], position[order]
    if len(tr) == 0:
        raise ValueError("no track points")
    _, length = _runs(tr)
    typical = int(np.median(length))
    largest = typical if typical % 2 else typical - 1
    smallest = degree + 2 + (degree + 1) % 2
    if windows is None:
        windows = np.arange(smallest, largest + 1, 2)
        if len(windows) == 0:
            raise ValueError(
                f"the median point's track has {typical} points, fewer than the "
                f"smallest window {smallest}"
            )
    windows = np.unique(np.asarray(windows, dtype=int))
    if len(windows) == 0 or np.any(windows % 2 != 1) or windows[0] < degree + 2:
        raise ValueError(f"windows must be odd integers >= degree + 2, got {windows!r}")
    mean_square, se, w4 = np.nan, np.nan, 0
    for w4 in _fourth_derivative_windows(largest):
        mean_square, se = _fourth_derivative(tr, fr, x, rate, noise, int(w4))
        if mean_square > SIGNIFICANCE * se:
            break
    resolved = bool(mean_square > SIGNIFICANCE * se)
    noise_rms, beta = np.empty(len(windows)), np.empty(len(windows))
    for i, w in enumerate(windows):
        weights = centred_weights(int(w), degree=degree, frame_rate=rate)[2]
        t = (np.arange(w) - w // 2) / rate
        noise_rms[i] = noise * np.sqrt(3 * np.sum(weights**2))
        beta[i] = np.sum(weights * t**4) / 24
    bias_rms = np.abs(beta) * np.sqrt(mean_square) if resolved else np.full(len(windows), np.nan)
    total_rms = np.hypot(noise_rms, bias_rms)
    chosen = windows[np.argmin(total_rms)] if resolved else windows[-1]
    return WindowChoice(
        window=int(chosen),
        windows=windows,
        noise_rms=noise_rms,
        bias_rms=bias_rms,
        total_rms=total_rms,
        fourth_derivative_mean_square=float(mean_square),
        fourth_derivative_se=float(se),
        fourth_derivative_window=int(w4),
        resolved=resolved,
        degree=degree,
        noise=float(noise),
    )


def track_outliers(
    track: np.ndarray,
    frame: np.ndarray,
    position: np.ndarray,
    frame_rate: float,
    *,
    window: int,
    noise: np.ndarray,
    degree: int = 3,
) -> np.ndarray:
    """The points of each track that its fit does not explain: false points a tracker
    took (a ghost match, a point displaced by an overlapping particle image).

    A point's residual from its fit, r = X − X̂, has variance σ_c²(1 − h) per component,
    h = Σ_j w_j² its own weight in the fit (the hat matrix's diagonal, the squared
    position error of :func:`fit_tracks` at unit noise). Its statistic
    q = Σ_c r_c² / (σ_c²(1 − h)) follows χ² with three degrees of freedom for Gaussian
    noise. Each round, the point of largest q of each track is an outlier when q
    exceeds :data:`OUTLIER_CHI2`, and the tracks are fitted again without it: one point
    per round, because a false point also pulls the residuals of its neighbours (by its
    error times their weight on it) and only the worst is surely false. At most
    :data:`OUTLIER_ROUNDS` rounds.

    Parameters
    ----------
    track, frame, position, frame_rate, window, degree :
        As :func:`fit_tracks`.
    noise : ndarray, shape (3,)
        Position noise σ_c per component, m, > 0.

    Returns
    -------
    ndarray of bool, shape (M,)
        True for an outlier.
    """
    noise = np.broadcast_to(np.asarray(noise, dtype=float), (3,))
    if not (np.isfinite(noise).all() and np.all(noise > 0)):
        raise ValueError(f"noise must be three finite values > 0 m, got {noise!r}")
    track, frame = np.asarray(track), np.asarray(frame)
    position = np.asarray(position, dtype=float)
    outlier = np.zeros(len(track), dtype=bool)
    for _ in range(OUTLIER_ROUNDS):
        kept = np.flatnonzero(~outlier)
        fit = fit_tracks(
            track[kept],
            frame[kept],
            position[kept],
            frame_rate,
            window=window,
            noise=1.0,
            degree=degree,
        )
        room = 1.0 - fit.position_error**2
        with np.errstate(invalid="ignore", divide="ignore"):
            q = np.sum(((position[kept] - fit.position) / noise) ** 2, axis=1) / room
        q = np.where(np.isfinite(q) & (room > 0), q, 0.0)
        order = np.lexsort((q, track[kept]))
        last = np.append(track[kept][order][1:] != track[kept][order][:-1], True)
        worst = order[last]
        worst = worst[q[worst] > OUTLIER_CHI2]
        if not len(worst):
            break
        outlier[kept[worst]] = True
    return outlier
