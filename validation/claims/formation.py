"""The simulator's images are what their scenario says they are (docs/claims.md #37–#41).

Measured from the rendered images of both cases alone (:mod:`validation.claims.
formation_scores`): the particle images' size and brightness, the background's level
and noise, the saturated pixels, and the defocus blur at the sheet's edges. Each is
compared with the specification: the spot sizes and photo-electrons that the rig's
optics and the case's lighting give by the documented formulas, measured by the same fit
on spots that the specification's sensor draws (so the fitter's own bias cancels); the
exact distribution of a background reading; each pixel's chance to saturate. The
tolerances are the measurements' standard errors at the claims' false-alarm rate.
"""

import numpy as np
from scipy.stats import norm

from validation.claims.base import Claim, ClaimResult, result
from validation.claims.context import ClaimContext
from validation.claims.formation_scores import FormationScores
from validation.claims.image_stack import FALSE_ALARM

#: A median's standard error per robust standard deviation, times √n (normal law).
MEDIAN_EFFICIENCY = 1.2533
#: Gaussian σ per median absolute deviation.
MAD_TO_SIGMA = 1.4826
#: n × the variance of a median-absolute-deviation σ over σ², normal samples.
MAD_VARIANCE = 1.3605
#: Differences the detector's noise estimate samples per image (its documented lattice).
ESTIMATOR_SAMPLES = 2**17


def _median_and_error(values: np.ndarray) -> tuple[float, float]:
    """The median and its standard error, from the median absolute deviation."""
    median = float(np.median(values))
    spread = MAD_TO_SIGMA * float(np.median(np.abs(values - median)))
    return median, MEDIAN_EFFICIENCY * spread / np.sqrt(len(values))


def _medians(rendered: np.ndarray, reference: np.ndarray) -> tuple[float, float, float]:
    """Rendered and reference medians and the standard error of their difference."""
    (a, a_error), (b, b_error) = _median_and_error(rendered), _median_and_error(reference)
    return a, b, float(np.hypot(a_error, b_error))


def _limit(tests: int) -> float:
    """Two-sided normal limit of ``tests`` comparisons at the claims' false-alarm rate."""
    return float(norm.isf(FALSE_ALARM / (2 * tests)))


def _cases(ctx: ClaimContext) -> dict[str, FormationScores]:
    return {"paper": ctx.formation, "slow": ctx.slow_formation}


def _spot_ratio(claim: Claim, ctx: ClaimContext, names: tuple[str, ...], what: str):
    cases = _cases(ctx)
    k = _limit(len(cases) * len(names))
    worst, parts = 0.0, []
    for case, scores in cases.items():
        for name in names:
            measured, reference, error = _medians(
                getattr(scores.rendered, name), getattr(scores.reference, name)
            )
            worst = max(worst, abs(measured - reference) / error)
            parts.append(f"{case} {name.removesuffix('_ratio')} {measured:.4f} vs {reference:.4f}")
    spots = ", ".join(f"{len(s.rendered.sigma_ratio)}" for s in cases.values())
    return result(
        claim,
        worst,
        f"medians of {what} of the rendered spots ({spots} isolated spots) and of the same "
        f"spots drawn by the specification within {k:.2f} SE ({'; '.join(parts)})",
        worst <= k,
        limit=k,
    )


def _spot_diameter(claim: Claim, ctx: ClaimContext) -> ClaimResult:
    return _spot_ratio(claim, ctx, ("sigma_ratio",), "fitted σ / specified σ (d_τ/4)")


def _spot_brightness(claim: Claim, ctx: ClaimContext) -> ClaimResult:
    return _spot_ratio(
        claim,
        ctx,
        ("amount_ratio", "peak_ratio"),
        "fitted total and brightest pixel / gain × specified photo-electrons",
    )


def _moments(histogram: np.ndarray) -> tuple[float, float, float, float, int]:
    """Mean, standard deviation and their standard errors of readings counted per DN."""
    levels = np.arange(len(histogram), dtype=np.float64)
    n = int(histogram.sum())
    mean = float(histogram @ levels) / n
    variance = float(histogram @ (levels - mean) ** 2) / n
    kurtosis = float(histogram @ (levels - mean) ** 4) / n / variance**2
    sd = np.sqrt(variance)
    return mean, sd, sd / np.sqrt(n), sd * np.sqrt((kurtosis - 1) / (4 * n)), n


def _background(claim: Claim, ctx: ClaimContext) -> ClaimResult:
    cases = _cases(ctx)
    k = _limit(2 * len(cases))
    worst, parts = 0.0, []
    for case, scores in cases.items():
        mean, sd, mean_error, sd_error, n = _moments(scores.background_histogram)
        spec_mean, spec_sd = scores.background_specified
        worst = max(worst, abs(mean - spec_mean) / mean_error, abs(sd - spec_sd) / sd_error)
        parts.append(
            f"{case}: {mean:.4f} ± {sd:.4f} DN vs {spec_mean:.4f} ± {spec_sd:.4f} over "
            f"{n / 1e6:.0f} M pixels"
        )
    return result(
        claim,
        worst,
        f"mean and standard deviation of the pixels no particle's light reaches within "
        f"{k:.2f} SE of the sensor's exact reading distribution ({'; '.join(parts)})",
        worst <= k,
        limit=k,
    )


def _saturation(claim: Claim, ctx: ClaimContext) -> ClaimResult:
    cases = _cases(ctx).values()
    saturated = sum(s.saturated for s in cases)
    expected = sum(s.saturated_expected for s in cases)
    allowed = _limit(1) * np.sqrt(sum(s.saturated_variance for s in cases)) + 0.5
    bands = sorted({s.saturation_band for s in cases})
    band = ", ".join(f"{lo}–{hi}" for lo, hi in bands)
    return result(
        claim,
        saturated - expected,
        f"pixels reading a full well ({band} DN, ± 5 read-noise σ), on the cases' frames and "
        f"a bright exposure of each: {saturated}, expected {expected:.1f} ± {allowed:.1f} from "
        "each pixel's specified light",
        abs(saturated - expected) <= allowed,
        limit=float(np.copysign(allowed, saturated - expected)),
    )


def _defocus(claim: Claim, ctx: ClaimContext) -> ClaimResult:
    scores = ctx.slow_formation
    edge, reference_edge = scores.rendered.edge, scores.reference.edge
    measured, reference, error = _medians(
        scores.rendered.sigma_ratio[edge], scores.reference.sigma_ratio[reference_edge]
    )
    z = abs(measured - reference) / error
    sharp = np.hypot(scores.geometric[edge], scores.diffraction[edge])
    widening = float(np.median(np.hypot(sharp, scores.blur[edge]) / sharp)) - 1
    k = _limit(1)
    tolerance = k * error
    return result(
        claim,
        z,
        f"median fitted / specified σ of {int(edge.sum())} spots at the sheet's edges "
        f"(slow case, box-4cam) {measured:.4f} vs {reference:.4f} drawn: within {k:.2f} SE "
        f"({tolerance:.2%}); the specified blur ({np.median(scores.blur[edge]):.2f} px) "
        f"widens them by {widening:.1%}, which must exceed that tolerance",
        z <= k and widening > tolerance,
        limit=k,
    )


def _contaminated_range(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The relative range of a median-|d| σ when a fraction p of the differences may lie
    anywhere: the clean half-normal's quantiles (½ − p)/(1 − p) and ½/(1 − p) over its
    median."""
    quartile = norm.ppf(0.75)
    low = norm.ppf((1 + (0.5 - p) / (1 - p)) / 2) / quartile - 1
    high = norm.ppf((1 + 0.5 / (1 - p)) / 2) / quartile - 1
    return low, high


def _noise_estimate(claim: Claim, ctx: ClaimContext) -> ClaimResult:
    cases = _cases(ctx)
    n = sum(len(s.noise_estimates) for s in cases.values())
    k = _limit(n)
    error = np.sqrt(MAD_VARIANCE / ESTIMATOR_SAMPLES)
    worst, parts = -np.inf, []
    for case, scores in cases.items():
        ratio = scores.noise_estimates / scores.background_mad_sigma - 1
        low, high = _contaminated_range(scores.contamination)
        worst = max(worst, float(np.max(np.maximum(low - ratio, ratio - high) / error)))
        parts.append(
            f"{case}: {np.min(ratio):+.2%} to {np.max(ratio):+.2%}, allowed from "
            f"{np.min(low):+.2%} to {np.max(high):+.2%} ({np.max(scores.contamination):.1%} "
            "of the differences touched)"
        )
    return result(
        claim,
        worst,
        f"the detector's background noise of each of {n} images against the same median "
        f"estimate on the exact reading distribution ({cases['paper'].background_mad_sigma:.3f}"
        f" DN): inside the range the touched differences allow, give or take {k:.2f} SE "
        f"(√({MAD_VARIANCE}/n), n = {ESTIMATOR_SAMPLES} samples); {'; '.join(parts)}",
        worst <= k,
        limit=k,
    )


FORMATION_CLAIMS: tuple[Claim, ...] = (
    Claim(
        "image.spot_diameter",
        "§2 (particle images; docs/imaging.md §1)",
        "the particle images have the diameter d_τ the scenario's optics specify",
        _spot_diameter,
    ),
    Claim(
        "image.spot_brightness",
        "§2 (particle images; docs/imaging.md §2)",
        "the particle images carry the light the scenario's sheet and tracers specify",
        _spot_brightness,
    ),
    Claim(
        "image.background",
        "docs/imaging.md §4",
        "the background reads the sensor's offset and noise",
        _background,
    ),
    Claim(
        "image.saturation",
        "docs/imaging.md §4",
        "pixels saturate where, and only where, the specified light fills the well",
        _saturation,
    ),
    Claim(
        "image.defocus_at_edges",
        "§2 (Scheimpflug mounts; docs/imaging.md §1)",
        "particle images at the sheet's edges carry the optics' defocus blur",
        _defocus,
    ),
    Claim(
        "image.noise_estimate",
        "docs/ptv.md (detection: background and noise)",
        "the detector's background noise estimate is the sensor's noise",
        _noise_estimate,
    ),
)
