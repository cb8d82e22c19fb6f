"""What the claims on tracks measure on the recorded case, against its exact values.

- **Track fits** (:func:`track_fit_scores`): the tracks are fitted as ``synptv ptv
  --tracks`` fits them (:func:`ptv.pipeline.track_fit.fit_recording`: the noise measured
  from the tracks, the points the fit does not explain taken out, the window chosen).
  For the window the stack chose, :func:`validation.truth.fit_floor.fit_floor` gives,
  apart from the stack, the least-squares fit d_ref of the exact positions at every
  point and the variance σ²Σw² the injected noise takes through its weights. The fit is
  linear in the positions, so the fitted derivative d̂ is d_ref plus the noise through
  the weights, exactly, and three ratios have expectation 1: the gain
  Σ d̂·d_ref / Σ|d_ref|² (the noise is independent of the trajectories), the rms of
  d̂ − d_ref over the rms the noise gives (√(3σ²Σw²)), and the rms error against the
  exact derivative over its floor √(|d_ref − d|² + 3σ²Σw²) (the window's smoothing bias
  and the noise), each summed over the same points.
- **Lagrangian statistics** (:func:`lagrangian_scores`): ⟨|u|²⟩, ⟨|a|²⟩ and S2ᴸ at the
  default lags with the noise removed (:func:`ptv.stats.lagrangian.lagrangian_statistics`
  on the noisy tracks) beside the same estimator on the exact positions of the same
  tracks, with the same bootstrap draws of the tracks, so that the standard error of
  their difference is that of the noise alone (the flow's own sampling cancels). The
  exact values (:func:`validation.truth.lagrangian.exact_lagrangian`) are reported
  beside.

Standard errors come from a bootstrap over tracks: the noise is independent between
tracks, the points of a track share theirs through the fits and differences.
"""

from dataclasses import dataclass

import numpy as np

from ptv.pipeline.track_fit import fit_recording
from ptv.stats.lagrangian import lagrangian_statistics
from validation.claims.recorded_case import RecordedCase
from validation.truth.fit_floor import fit_floor
from validation.truth.lagrangian import exact_lagrangian

#: Bootstrap replicates of the tracks.
RESAMPLES = 1000


@dataclass(frozen=True)
class FitComparison:
    """A fitted derivative against the least-squares fit of the exact positions and the
    exact derivative, over the points of the tracks covered (module docstring).

    Attributes
    ----------
    gain, gain_se : float
        Σ d̂·d_ref / Σ|d_ref|² and its standard error.
    scatter, scatter_se : float
        √(Σ|d̂ − d_ref|² / Σ 3σ²Σw²) and its standard error.
    ratio, ratio_se : float
        √(Σ|d̂ − d|² / Σ floor²), floor² = |d_ref − d|² + 3σ²Σw², and its standard error.
    error_rms, floor_rms, bias_rms, noise_rms, exact_rms : float
        rms length of the error d̂ − d, of the floor, of its bias and noise parts, and of
        the exact derivative, m/s^k for the k-th derivative.
    points, tracks : int
        Points and tracks compared.

    Notes
    -----
    Standard errors from :data:`RESAMPLES` bootstrap replicates of the tracks (whole
    tracks drawn with replacement; the noise is independent between tracks).
    """

    gain: float
    gain_se: float
    scatter: float
    scatter_se: float
    ratio: float
    ratio_se: float
    error_rms: float
    floor_rms: float
    bias_rms: float
    noise_rms: float
    exact_rms: float
    points: int
    tracks: int


@dataclass(frozen=True)
class TrackFitScores:
    """The recorded case's tracks fitted by the stack, against their floors.

    Attributes
    ----------
    window : int
        The window the stack chose.
    noise : ndarray, shape (3,)
        σ_c the stack measured, m.
    outliers : int
        Points it took out.
    velocity, acceleration : FitComparison
    """

    window: int
    noise: np.ndarray
    outliers: int
    velocity: FitComparison
    acceleration: FitComparison


def _ratio_of_sums(
    which: np.ndarray, top: np.ndarray, bottom: np.ndarray, draws: np.ndarray, *, root: bool
) -> tuple[float, float]:
    """Σ top / Σ bottom (its square root if ``root``) and its standard error over the
    bootstrap ``draws`` (R, T) of the tracks, ``which`` (n,) the track index 0 … T − 1 of
    each term."""
    tracks = draws.shape[1]
    per_top = np.bincount(which, weights=top, minlength=tracks)
    per_bottom = np.bincount(which, weights=bottom, minlength=tracks)
    value, replicates = per_top.sum() / per_bottom.sum(), (draws @ per_top) / (draws @ per_bottom)
    if root:
        value, replicates = np.sqrt(value), np.sqrt(replicates)
    return float(value), float(replicates.std(ddof=1))


def _compare(case, rows, fitted, exact, order, window, rng) -> FitComparison:
    """The fitted ``order``-th derivative (len(rows), 3) of the points ``rows`` against
    the least-squares fit of their exact positions and their exact derivative."""
    floor = fit_floor(
        case.track[rows],
        case.frame[rows],
        case.position[rows],
        exact[rows],
        case.frame_rate,
        window=window,
        noise=case.noise,
        order=order,
    )
    use = floor.covered & np.all(np.isfinite(fitted), axis=1)
    d_hat, d_ref, d = fitted[use], floor.reference[use], exact[rows][use]
    noise = 3.0 * floor.noise_variance[use]
    _, which = np.unique(case.track[rows][use], return_inverse=True)
    tracks = int(which.max()) + 1
    draws = rng.multinomial(tracks, np.full(tracks, 1.0 / tracks), size=RESAMPLES)
    gain = _ratio_of_sums(
        which, np.sum(d_hat * d_ref, axis=1), np.sum(d_ref**2, axis=1), draws, root=False
    )
    scatter = _ratio_of_sums(which, np.sum((d_hat - d_ref) ** 2, axis=1), noise, draws, root=True)
    error = np.sum((d_hat - d) ** 2, axis=1)
    ratio = _ratio_of_sums(which, error, floor.mean_square[use], draws, root=True)
    return FitComparison(
        gain=gain[0],
        gain_se=gain[1],
        scatter=scatter[0],
        scatter_se=scatter[1],
        ratio=ratio[0],
        ratio_se=ratio[1],
        error_rms=float(np.sqrt(error.mean())),
        floor_rms=float(np.sqrt(floor.mean_square[use].mean())),
        bias_rms=float(np.sqrt(np.sum(floor.bias[use] ** 2, axis=1).mean())),
        noise_rms=float(np.sqrt(noise.mean())),
        exact_rms=float(np.sqrt(np.sum(d**2, axis=1).mean())),
        points=int(use.sum()),
        tracks=tracks,
    )


def track_fit_scores(case: RecordedCase, *, seed: int) -> TrackFitScores:
    """:class:`TrackFitScores` of the case (module docstring); ``seed`` seeds the stack's
    bootstraps and the floor's."""
    fitted = fit_recording(case.track, case.frame, case.measured, case.frame_rate, seed=seed)
    rows = np.flatnonzero(fitted.kept)
    rng = np.random.default_rng(seed)
    window = fitted.fitted.window
    return TrackFitScores(
        window=window,
        noise=fitted.noise,
        outliers=fitted.outliers,
        velocity=_compare(case, rows, fitted.fitted.velocity, case.velocity, 1, window, rng),
        acceleration=_compare(
            case, rows, fitted.fitted.acceleration, case.acceleration, 2, window, rng
        ),
    )


@dataclass(frozen=True)
class LagrangianScores:
    """Noise-removed statistics beside the same estimator on the exact positions.

    Attributes
    ----------
    names : tuple of str
        ``"<|u|^2>"``, ``"<|a|^2>"`` and ``"S2L(L)"`` per lag L (frames).
    measured, noise_free : ndarray, shape (K,)
        The estimate on the noisy tracks and on the exact positions, m²/s² or m²/s⁴.
    standard_error : ndarray, shape (K,)
        Of their difference, from the shared bootstrap replicates of the tracks.
    raw : ndarray, shape (K,)
        The noisy estimate without its noise removed (one-frame steps).
    exact : ndarray, shape (K,)
        The exact value over every particle-frame (or pair) of the tracks.
    lags : ndarray of int, shape (J,)
        Lags of S2ᴸ, frames.
    tracks : int
        Tracks of the sample.
    """

    names: tuple[str, ...]
    measured: np.ndarray
    noise_free: np.ndarray
    standard_error: np.ndarray
    raw: np.ndarray
    exact: np.ndarray
    lags: np.ndarray
    tracks: int


def lagrangian_scores(case: RecordedCase, *, seed: int) -> LagrangianScores:
    """:class:`LagrangianScores` of the case (module docstring); ``seed`` seeds the
    bootstrap draws both estimates share."""
    noisy = lagrangian_statistics(case.track, case.frame, case.measured, case.frame_rate, rng=seed)
    clean = lagrangian_statistics(case.track, case.frame, case.position, case.frame_rate, rng=seed)
    lags = noisy.structure.lags
    exact = exact_lagrangian(case.track, case.frame, case.velocity, case.acceleration, lags)

    def parts(found):
        return (
            np.r_[found.velocity.total, found.acceleration.total, found.structure.value],
            np.column_stack(
                [
                    found.velocity.boot,
                    found.acceleration.per_component_boot.sum(axis=1),
                    found.structure.boot,
                ]
            ),
        )

    measured, measured_boot = parts(noisy)
    noise_free, noise_free_boot = parts(clean)
    return LagrangianScores(
        names=("<|u|^2>", "<|a|^2>", *(f"S2L({lag})" for lag in lags)),
        measured=measured,
        noise_free=noise_free,
        standard_error=(measured_boot - noise_free_boot).std(axis=0, ddof=1),
        raw=np.r_[noisy.velocity.raw, noisy.acceleration.raw, noisy.structure.raw],
        exact=np.r_[exact.velocity_variance, exact.acceleration_total, exact.structure],
        lags=lags,
        tracks=case.tracks,
    )
