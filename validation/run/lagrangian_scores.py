"""The Lagrangian statistics of a run's tracks beside the flow's exact values.

The noise is removed over several steps (:mod:`ptv.stats.lagrangian`); the exact values
are those of the recording's true particles (:mod:`validation.truth.lagrangian`,
written apart). Beside each, the same estimator on the true positions of the same track
points, without noise: what the estimator gives on this flow at this frame rate, so
that the error the noise leaves and the estimator's own bias (the truncation of its
expansion in the step) are told apart.

What can be required (docs/run.md §9, measured on the tr recording):

- S2ᴸ(τ) at τ ≥ :data:`CHECKED_TAU_ETA` τ_η: within 3 % of exact. At smaller lags the
  noise term of the one-frame step is 40–220 times S2ᴸ, and a noise variance known to
  its sampling error (0.3 %) leaves 4–20 %: reported, not required.
- ⟨|a|²⟩: its noise removed to within 3 % of the noise-free estimator on the same points.
  Against the exact value the estimator is 11 % low on kinematic simulation at a frame
  every τ_η/10 even without noise (the acceleration decorrelates within τ_η/3 as the
  frozen small scales are swept past the particle; 1.8 % at τ_η/20, 0.2 % at τ_η/40):
  reported beside.
"""

import numpy as np

from ptv.stats.lagrangian import LAGS, acceleration_pdf, lagrangian_statistics
from ptv.tracking.fitting import FittedTracks
from validation.score.trajectories import TrackPoints, TrueTrajectories
from validation.truth.lagrangian import exact_lagrangian

#: Shortest lag of the S2ᴸ check, Kolmogorov times.
CHECKED_TAU_ETA = 0.5
#: Bootstrap replicates of every statistic.
RESAMPLES = 200


def _statistics(tracks: TrackPoints, position: np.ndarray, frame_rate: float, lags, seed):
    """⟨a²⟩, S2ᴸ, ⟨|u|²⟩ and ρ of tracks with the given positions."""
    found = lagrangian_statistics(
        tracks.track, tracks.frame, position, frame_rate, lags=lags, resamples=RESAMPLES, rng=seed
    )
    return found.acceleration, found.structure, found.velocity, found.autocorrelation


def _number(value) -> float | None:
    return float(value) if np.isfinite(value) else None


def lagrangian_scores(
    tracks: TrackPoints,
    truth: TrueTrajectories,
    row: np.ndarray,
    frame_rate: float,
    tau_eta: float,
    *,
    frames: int,
    seed: int,
) -> tuple[dict, np.ndarray]:
    """The statistics of ``tracks`` against the truth (module docstring).

    Parameters
    ----------
    tracks : TrackPoints
        In the world frame.
    truth : TrueTrajectories
    row : ndarray of int, shape (M,)
        The truth row each track point is paired with, −1 for a ghost point.
    frame_rate : float
        Hz.
    tau_eta : float
        The flow's Kolmogorov time, s.
    frames : int
        Frames per recording (lags beyond a third of it are left out).
    seed : int
        Seeds the bootstrap.

    Returns
    -------
    (dict, ndarray)
        The JSON-able comparison, and σ_c, the noise per component, m (3,).
    """
    lags = np.array([lag for lag in LAGS if lag <= frames // 3])
    measured = _statistics(tracks, tracks.position, frame_rate, lags, seed)
    acceleration, structure, variance, correlation = measured
    # The noise-free estimator: the true positions of the tracks' paired points.
    paired = row >= 0
    clean_tracks = TrackPoints(tracks.track[paired], tracks.frame[paired], tracks.position[paired])
    clean = _statistics(clean_tracks, truth.position[row[paired]], frame_rate, lags, seed)
    observed = truth.observed
    exact = exact_lagrangian(
        truth.particle[observed],
        truth.frame[observed],
        truth.velocity[observed],
        truth.acceleration[observed],
        lags,
    )
    tau = lags / frame_rate
    exact_correlation = 1 - exact.structure / (2 * exact.velocity_variance)
    s2 = [
        {
            "lag": int(lag),
            "tau_s": float(t),
            "tau_over_tau_eta": float(t / tau_eta),
            "measured": _number(structure.value[j]),
            "se": _number(structure.se[j]),
            "raw": _number(structure.raw[j]),
            "noise_free": _number(clean[1].value[j]),
            "exact": _number(exact.structure[j]),
            "ratio": _number(structure.value[j] / exact.structure[j]),
            "ratio_se": _number(structure.se[j] / exact.structure[j]),
            "checked": bool(t >= CHECKED_TAU_ETA * tau_eta),
        }
        for j, (lag, t) in enumerate(zip(lags, tau, strict=True))
    ]
    noise_free = clean[0].total
    return {
        "acceleration_variance": {
            "measured": acceleration.total,
            "se": acceleration.total_se,
            "raw": acceleration.raw,
            "noise_free": noise_free,
            "exact": exact.acceleration_total,
            "ratio": acceleration.total / noise_free,
            "ratio_se": acceleration.total_se / noise_free,
            "ratio_to_exact": acceleration.total / exact.acceleration_total,
            "noise_free_to_exact": noise_free / exact.acceleration_total,
            "steps": acceleration.steps.tolist(),
            "noise_variance_m2": acceleration.noise_variance.tolist(),
            "noise_fraction": acceleration.noise_fraction.tolist(),
        },
        "s2": s2,
        "checked_from_tau_eta": CHECKED_TAU_ETA,
        "velocity_variance": {
            "measured": variance.total,
            "se": variance.total_se,
            "raw": variance.raw,
            "exact": exact.velocity_variance,
        },
        "autocorrelation": {
            "tau_s": tau.tolist(),
            "measured": [_number(v) for v in correlation.value],
            "se": [_number(v) for v in correlation.se],
            "exact": [_number(v) for v in exact_correlation],
        },
        "tau_eta_s": tau_eta,
    }, np.sqrt(np.maximum(acceleration.noise_variance, 0.0))


def pdf_comparison(fitted: FittedTracks, truth: TrueTrajectories, row: np.ndarray) -> dict:
    """The PDF of the fitted accelerations' components over their rms, and that of the
    true accelerations of the same points on the same bins."""
    measured = acceleration_pdf(fitted)
    paired = (row >= 0) & np.isfinite(fitted.acceleration).all(axis=1)
    a = truth.acceleration[row[paired]]
    scaled = (a / np.sqrt(np.mean(a**2, axis=0))).ravel()
    density, _ = np.histogram(scaled, bins=measured.edges, density=True)
    return {
        "edges": measured.edges.tolist(),
        "measured": measured.density.tolist(),
        "true": density.tolist(),
        "measured_rms": measured.rms.tolist(),
        "true_rms": np.sqrt(np.mean(a**2, axis=0)).tolist(),
        "samples": measured.samples,
    }
