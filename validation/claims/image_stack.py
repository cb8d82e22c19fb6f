"""The image-stack claims (docs/claims.md #29–#36): detection, matching and linking on
small rendered cases, against the simulator's truth.

The cases (:mod:`validation.claims.rendered_case`) are the default scenario's rig, flow,
tracer density and brightness at its largest Δt (#29–#34), and the slow-4cam scenario's
(#35, #36: a default that does not follow the flow fails there); the stack runs on their
images with its default settings and the true cameras. The references
(:mod:`validation.claims.image_scores`) share no code with the stack.
"""

import numpy as np
from scipy.stats import chi2, poisson

from validation.claims.base import Claim, ClaimResult, result
from validation.claims.context import ClaimContext
from validation.claims.formation_scores import sensor_spec
from validation.claims.image_scores import (
    detection_scores,
    harmonic_bias,
    linking_scores,
    matching_differences,
    position_errors,
)
from validation.score.tolerances import false_alarm_z
from validation.truth.localisation_bound import least_squares_errors
from validation.truth.noise_floor import object_pixel

#: A least-squares Gaussian fit reaches at most 16/9 of the Cramér–Rao variance
#: (photon-limited; less where read noise dominates): RMS / bound ≤ 4/3, per axis.
LSQ_EFFICIENCY = 4.0 / 3.0
#: Spots drawn for the least-squares reference of #29, in all (at least one per isolated
#: spot): the relative standard error of its rms is then about 0.5 % per axis.
REFERENCE_DRAWS = 100_000
#: Peak-locking bias allowed, px: the 3-point Gaussian's largest bias on
#: pixel-integrated spots of σ = 0.5 px (docs/imaging.md §6); the case's spots have
#: σ = 0.60–0.66 px, where a Gaussian estimator's bias is smaller still.
GAUSSIAN_BIAS_PX = 0.005
#: False-alarm rate of the statistical limits.
FALSE_ALARM = 1e-3
#: Fewest bright isolated particles found, as a fraction (the noise model misses fewer
#: than 1e-4 of them; the rest is room for spots deformed by a neighbour beyond 4 px).
BRIGHT_FOUND = 0.999
#: The link speed measured on the slow case against the one of its true velocities: the
#: position noise inflates each σ_i by √(1 + 2σ_b²/(σ_i Δt)²) < 0.1 % at σ_b = 10 µm,
#: the stack measures on the first snapshots' links where the reference takes every
#: particle (the median absolute deviation of 4500 Gaussian values has a relative error
#: of 1.7 %, 5 % at 3 SE), and the largest component's may differ between them.
SPEED_TOLERANCE = 0.05
#: The detector's documented threshold, in noise σ (docs/imaging.md §5): the bright spots
#: of #31 are those whose brightest pixel expects twice it, whatever the settings say.
THRESHOLD_SIGMAS = 6.0
#: The matching tolerance's documented floor, in object-side pixels (docs/ptv.md §3),
#: which decides on the cases' true cameras (6 median ray distances are tens of µm).
PIXEL_FLOOR = 1.5
#: The tolerance used against the floor computed apart from the stack: the two
#: object-side pixels agree within 1e-5 on every rig (rays straight over one pixel).
FLOOR_AGREEMENT = 1e-3
#: Matched points differing from the brute-force matcher's, at most, as a fraction
#: (only floating-point ties at the tolerance or the box's edge may differ).
MATCH_DIFFERENCE = 1e-3


def _detection(ctx: ClaimContext):
    return detection_scores(ctx.rendered_case, THRESHOLD_SIGMAS)


def _rms_ratio(errors: np.ndarray, reference: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per axis, the rms of ``errors`` over that of ``reference`` and its standard error.

    Parameters
    ----------
    errors : ndarray, shape (N, 2)
        Errors of the stack, px.
    reference : ndarray, shape (M, 2)
        Errors of the reference, drawn independently, px.

    Returns
    -------
    ratio, standard_error : ndarray, shape (2,)
        The delta method on the two mean squares: the relative variance of an rms is a
        quarter of its mean square's, Var(e²)/(n⟨e²⟩²), and the two samples add.
    """
    square, square_ref = errors**2, reference**2
    mean, mean_ref = square.mean(axis=0), square_ref.mean(axis=0)
    relative = square.var(axis=0) / (len(square) * mean**2) + square_ref.var(axis=0) / (
        len(square_ref) * mean_ref**2
    )
    ratio = np.sqrt(mean / mean_ref)
    return ratio, 0.5 * ratio * np.sqrt(relative)


def _detection_rms(claim: Claim, ctx: ClaimContext) -> ClaimResult:
    scores = _detection(ctx)
    # The error an unweighted least-squares Gaussian reaches on these very spots (σ,
    # photo-electrons, sub-pixel centre), drawn and fitted apart from the stack.
    draws = max(1, round(REFERENCE_DRAWS / len(scores.errors)))
    reference = least_squares_errors(
        scores.sigma,
        scores.electrons,
        scores.fraction,
        sensor_spec(ctx.rendered_case),
        np.random.default_rng(ctx.seed + 15),
        draws=draws,
    )
    ratio, standard_error = _rms_ratio(scores.errors, reference)
    # One-sided (a fit better than least squares is no fault), 0.1 % over both axes.
    k = false_alarm_z(None, tests=2, rate=2 * FALSE_ALARM)
    limit = 1.0 + k * standard_error
    bound = np.sqrt(np.mean(scores.bound**2, axis=0))
    to_bound = np.sqrt(np.mean(scores.errors**2, axis=0)) / bound
    reference_to_bound = np.sqrt(np.mean(reference**2, axis=0)) / bound
    pooled = float(np.sqrt(np.mean(scores.errors**2) / np.mean(scores.bound**2)))
    worst = int(np.argmax(ratio - limit))
    passed = bool(np.all(ratio <= limit) and np.all(reference_to_bound <= LSQ_EFFICIENCY))
    return result(
        claim,
        float(ratio[worst]),
        f"per axis, RMS / RMS of an unweighted least-squares Gaussian on the same spots "
        f"(x {ratio[0]:.3f}, y {ratio[1]:.3f}) ≤ 1 + {k:.2f} SE (x ≤ {limit[0]:.3f}, "
        f"y ≤ {limit[1]:.3f}; one-sided, 0.1 % false alarms over both axes), that fit "
        f"within 4/3 of the Cramér–Rao bound (x {reference_to_bound[0]:.3f}, y "
        f"{reference_to_bound[1]:.3f}; Mortensen et al.); RMS / bound x {to_bound[0]:.3f}, "
        f"y {to_bound[1]:.3f}, pooled {pooled:.3f} over {len(scores.errors)} isolated spots",
        passed,
        limit=float(limit[worst]),
    )


def _peak_locking(claim: Claim, ctx: ClaimContext) -> ClaimResult:
    scores = _detection(ctx)
    amplitude, standard_error = harmonic_bias(scores.errors, scores.fraction)
    # Two axes, two harmonic coefficients each: χ²₂ at half the false-alarm rate per axis.
    k = float(np.sqrt(chi2.isf(FALSE_ALARM / 2, 2)))
    limit = GAUSSIAN_BIAS_PX + k * standard_error
    return result(
        claim,
        float(amplitude.max()),
        f"first-harmonic bias vs fractional position ≤ {GAUSSIAN_BIAS_PX} px + {k:.2f} SE "
        f"(x {limit[0]:.4f}, y {limit[1]:.4f} px)",
        bool(np.all(amplitude <= limit)),
        limit=float(limit[np.argmax(amplitude)]),
    )


def _detection_found(claim: Claim, ctx: ClaimContext) -> ClaimResult:
    scores = _detection(ctx)
    fraction = scores.bright_found / scores.bright
    return result(
        claim,
        fraction,
        f"≥ {BRIGHT_FOUND} of the {scores.bright} isolated spots whose brightest pixel "
        f"expects 2× the documented {THRESHOLD_SIGMAS:g}σ threshold",
        fraction >= BRIGHT_FOUND,
        limit=BRIGHT_FOUND,
    )


def _matching_reference(claim: Claim, ctx: ClaimContext) -> ClaimResult:
    differ, total = matching_differences(ctx.rendered_case)
    fraction = differ / total
    return result(
        claim,
        fraction,
        f"≤ {MATCH_DIFFERENCE} of the {total} points differ from the brute-force matcher's",
        fraction <= MATCH_DIFFERENCE,
        limit=MATCH_DIFFERENCE,
    )


def _matching_tolerance(claim: Claim, ctx: ClaimContext) -> ClaimResult:
    worst, parts = 0.0, []
    for case in (ctx.rendered_case, ctx.slow_case):
        lower, upper = (np.asarray(v) for v in case.settings.volume)
        floor = PIXEL_FLOOR * object_pixel(case.rig.cameras, 0.5 * (lower + upper))
        worst = max(worst, abs(case.settings.tolerance / floor - 1))
        parts.append(f"{case.spec.rig} {case.settings.tolerance * 1e6:.1f} vs {floor * 1e6:.1f} µm")
    return result(
        claim,
        worst,
        f"|tolerance / (1.5 object-side pixels) − 1| ≤ {FLOOR_AGREEMENT} on both cases, the "
        f"pixel from the true projection's Jacobian ({'; '.join(parts)})",
        worst <= FLOOR_AGREEMENT,
        limit=FLOOR_AGREEMENT,
    )


def _position_bias(claim: Claim, ctx: ClaimContext) -> ClaimResult:
    errors = position_errors(ctx.rendered_case)
    standard_error = errors.std(axis=0) / np.sqrt(len(errors))
    t = np.abs(errors.mean(axis=0)) / standard_error
    # Three components: a two-sided normal limit at a third of the false-alarm rate each.
    k = float(np.sqrt(chi2.isf(FALSE_ALARM / 3, 1)))
    mean_um = errors.mean(axis=0) * 1e6
    return result(
        claim,
        float(t.max()),
        f"|mean error| ≤ {k:.2f} SE per component (mean X, Y, Z = "
        f"{mean_um[0]:+.2f}, {mean_um[1]:+.2f}, {mean_um[2]:+.2f} µm over {len(errors)} points)",
        bool(np.all(t <= k)),
        limit=k,
    )


def _linking(claim: Claim, ctx: ClaimContext, *, slow: bool = False) -> ClaimResult:
    scores = linking_scores(ctx.slow_case if slow else ctx.rendered_case)
    allowed = int(poisson.isf(FALSE_ALARM, scores.expected))
    return result(
        claim,
        scores.failed / scores.linkable,
        f"failed links ≤ {allowed} of {scores.linkable} (99.9 % point of Poisson with the "
        f"{scores.expected:.1f} expected from competitors nearer than the displacement); "
        f"{scores.failed} failed",
        scores.failed <= allowed,
        limit=allowed / scores.linkable,
    )


def _slow_link_speed(claim: Claim, ctx: ClaimContext) -> ClaimResult:
    case = ctx.slow_case
    # The reference: |U| + 5 max_i σ_i of the particles' true velocities over the frame
    # pair, (X_b − X_a)/Δt of the true positions, the rms per component from its median
    # absolute deviation as the stack states it, written here apart from the stack.
    velocity = (case.positions[:, 1] - case.positions[:, 0]).reshape(-1, 3) / case.dt
    mean = np.median(velocity, axis=0)
    rms = 1.4826 * np.median(np.abs(velocity - mean), axis=0)
    reference = float(np.linalg.norm(mean) + 5.0 * rms.max())
    ratio = case.settings.max_speed / reference
    return result(
        claim,
        ratio,
        f"max_speed used / |U| + 5 max σ_i of the true velocities within 1 ± {SPEED_TOLERANCE} "
        f"({case.settings.max_speed:.3g} against {reference:.3g} m/s; u′ = "
        f"{case.spec.parameters.u_rms:g} m/s)",
        abs(ratio - 1) <= SPEED_TOLERANCE,
        limit=1 + np.copysign(SPEED_TOLERANCE, ratio - 1),
    )


IMAGE_CLAIMS: tuple[Claim, ...] = (
    Claim(
        "image.detection_rms",
        "§2 (detection)",
        "isolated particle images are located, in x and in y alike, as well as a "
        "least-squares Gaussian locates them: within 4/3 of the Cramér–Rao bound",
        _detection_rms,
    ),
    Claim(
        "image.peak_locking",
        "§2 (detection)",
        "no peak locking beyond a Gaussian estimator's own",
        _peak_locking,
    ),
    Claim(
        "image.detection_found",
        "§2 (detection)",
        "every bright isolated particle is found",
        _detection_found,
    ),
    Claim(
        "image.matching_reference",
        "§2 (matching)",
        "stereo matching finds the minimum-cost one-to-one pairing",
        _matching_reference,
    ),
    Claim(
        "image.matching_tolerance",
        "§2 (matching)",
        "the matching tolerance is the documented 1.5 object-side pixels where the "
        "calibration is exact",
        _matching_tolerance,
    ),
    Claim(
        "image.position_bias",
        "§2 (triangulation)",
        "matched positions are unbiased through the refracting windows",
        _position_bias,
    ),
    Claim(
        "image.linking",
        "§3 (linking)",
        "frame a links to frame b unless a nearer competitor exists",
        _linking,
    ),
    Claim(
        "image.slow_link_speed",
        "§3 (linking), a slow lab flow",
        "the link radius follows the flow: max_speed is measured, |U| + 5σ of the velocities",
        _slow_link_speed,
    ),
    Claim(
        "image.slow_linking",
        "§3 (linking), a slow lab flow",
        "on four cameras and a flow ten times slower, frame a links to frame b unless a "
        "nearer competitor exists",
        lambda claim, ctx: _linking(claim, ctx, slow=True),
    ),
)
