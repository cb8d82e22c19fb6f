"""Claims on a time-resolved recording's tracks (docs/claims.md #51–#53): the fitted
velocity and acceleration, and the Lagrangian statistics with the noise removed.

The recorded case (:mod:`validation.claims.recorded_case`) follows the default flow's
tracers through the sheet at τ_η/10 per frame and measures their exact positions with
5 µm of white noise; no image is rendered and the tracks are the particles' own, so the
claims judge :mod:`ptv.tracking.fitting`, :mod:`ptv.pipeline.track_fit` and
:mod:`ptv.stats.lagrangian` alone (docs/lagrangian.md). The references
(:mod:`validation.claims.recorded_scores`) are the least-squares fit's floor computed
apart from the stack and the same estimator on the exact positions.
"""

import numpy as np

from validation.claims.base import Claim, ClaimResult, result
from validation.claims.context import ClaimContext
from validation.claims.recorded_scores import FitComparison
from validation.score.tolerances import FALSE_ALARM, false_alarm_z


def _fit(claim: Claim, ctx: ClaimContext, *, order: int) -> ClaimResult:
    scores = ctx.track_fits
    found: FitComparison = scores.velocity if order == 1 else scores.acceleration
    unit = "m/s" if order == 1 else "m/s²"
    # Three ratios of expectation 1 (recorded_scores), each two-sided: a fit that errs
    # less than the noise allows is as wrong as one that errs more.
    k = false_alarm_z(found.tracks - 1, tests=3)
    ratios = np.array([found.gain, found.scatter, found.ratio])
    room = k * np.array([found.gain_se, found.scatter_se, found.ratio_se])
    worst = int(np.argmax(np.abs(ratios - 1.0) / room))
    return result(
        claim,
        float(ratios[worst]),
        f"gain on the least-squares fit of the exact positions {found.gain:.4f}, rms "
        f"scatter about it / the noise through the fit's weights {found.scatter:.4f}, rms "
        f"error / its floor {found.ratio:.4f}: each within 1 ± {k:.2f} SE (± {room[0]:.4f}, "
        f"± {room[1]:.4f}, ± {room[2]:.4f}; two-sided, {FALSE_ALARM:.1%} false alarms over "
        f"the three; SE by a bootstrap over {found.tracks} tracks). Error {found.error_rms:.4g} "
        f"against a floor of {found.floor_rms:.4g} {unit} (window bias {found.bias_rms:.3g}, "
        f"noise {found.noise_rms:.3g}) at the {scores.window} points the stack chose; the "
        f"exact rms {found.exact_rms:.3g} {unit}; {found.points} points",
        bool(np.all(np.abs(ratios - 1.0) <= room)),
        limit=float(1.0 + np.copysign(room[worst], ratios[worst] - 1.0)),
    )


def _noise_removed(claim: Claim, ctx: ClaimContext) -> ClaimResult:
    s = ctx.lagrangian
    deviation = (s.measured - s.noise_free) / s.standard_error
    k = false_alarm_z(s.tracks - 1, tests=len(s.names))
    worst = int(np.argmax(np.abs(deviation)))
    listed = "; ".join(
        f"{name} {m / f:.4f} ({d:+.1f} SE)"
        for name, m, f, d in zip(s.names, s.measured, s.noise_free, deviation, strict=True)
    )
    return result(
        claim,
        float(np.abs(deviation[worst])),
        f"each noise-removed estimate / the same estimator on the exact positions within "
        f"1 ± {k:.2f} SE of their difference (two-sided, {FALSE_ALARM:.1%} false alarms over "
        f"the {len(s.names)} values; SE from the bootstrap over {s.tracks} tracks both "
        f"share): {listed}. Without noise removal ⟨|u|²⟩ {s.raw[0] / s.noise_free[0]:.3f}, "
        f"⟨|a|²⟩ {s.raw[1] / s.noise_free[1]:.2f}; the estimator on the exact positions "
        f"over the exact values: ⟨|u|²⟩ {s.noise_free[0] / s.exact[0]:.4f}, ⟨|a|²⟩ "
        f"{s.noise_free[1] / s.exact[1]:.3f} (kinematic simulation's decorrelating "
        f"acceleration), S2ᴸ({s.lags[-1]}) {s.noise_free[-1] / s.exact[-1]:.4f}",
        bool(np.all(np.abs(deviation) <= k)),
        limit=k,
    )


RECORDING_CLAIMS: tuple[Claim, ...] = (
    Claim(
        "tracks.fit_velocity",
        "docs/lagrangian.md §1–§2 (track fitting)",
        "the fitted track velocities err by what the position noise and the chosen window "
        "allow a least-squares cubic",
        lambda claim, ctx: _fit(claim, ctx, order=1),
    ),
    Claim(
        "tracks.fit_acceleration",
        "docs/lagrangian.md §1–§2 (track fitting)",
        "the fitted track accelerations err by what the position noise and the chosen "
        "window allow a least-squares cubic",
        lambda claim, ctx: _fit(claim, ctx, order=2),
    ),
    Claim(
        "lagrangian.noise_removed",
        "docs/lagrangian.md §4 (multi-step noise removal)",
        "⟨|u|²⟩, ⟨|a|²⟩ and S2ᴸ of noisy tracks, the noise removed over several steps, "
        "equal the same estimators on the exact positions",
        _noise_removed,
    ),
)
