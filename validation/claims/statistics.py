"""The flow and statistics claims (docs/claims.md #1, #5–#15, #23).

Every estimate is compared with a reference it shares no code with
(:mod:`validation.truth.independent`): the brute-force S2 of the exact velocities over
a subsample of each snapshot (S2_ref), the injected noise 4σ², and the input ε times
the estimator's plateau deficit from an independent quadrature of the spectrum.
"""

from dataclasses import replace

import numpy as np
from scipy.stats import chi2 as chi2_distribution

from ptv.stats.dissipation import (
    dissipation_profile,
    epsilon_estimate,
    epsilon_paper_caption,
    plateau_epsilon,
    turbulence_scales,
)
from ptv.stats.mean_displacement import OFFSET_FALSE_ALARM, mean_displacement
from ptv.stats.multidt import wls_line
from ptv.stats.structure import StructureFunction
from simulator.presets import FLOW_PRESETS
from validation.claims.base import Claim, ClaimResult, result
from validation.claims.context import CORRELATION_LENGTH, PLATEAU_RANGE, ClaimContext
from validation.run.checks import NORMAL_Z
from validation.score.tolerances import false_alarm_z
from validation.studies.multi_dt_experiment import Measurement
from validation.truth.dt3_bias import dt3_gamma
from validation.truth.independent import (
    REFERENCE_C2,
    BruteForceS2,
    intercept_standard_error,
)

#: Table 3 as printed: η (µm), τ_η (ms), R_λ.
_TABLE3 = {"lem-8hz": (56, 3.2, 291), "lem-10hz": (49, 2.4, 339), "lem-12hz": (42, 1.7, 388)}
#: Position noise of the statistics runs per component, m, and its noise term N = 4σ².
NOISE = Measurement().noise[0]
NOISE_TERM = 4 * NOISE**2
#: The method error of c₁ allowed per bin: the KS fit's own bias reaches −1.5 % near
#: 2 mm (sweeping of the smallest modes within Δt), −0.5 % at 0.2 L_int.
C1_METHOD_ERROR = 0.03
#: c₁'s bias in the plateau range (≈ −1 % at 2–5 mm), in ε as 1.5 times that.
C1_PLATEAU_BIAS = 0.01
#: Bins from this fraction of L_int on enter the pooled c₁/S2_ref, where the KS fit's
#: own bias is below 0.5 %: a 3 % error common to all bins shows there.
POOLED_FROM = 0.2
#: An offset of this many standard errors of β₀ must be detected and recovered (#5).
OFFSET_IN_SE = 5.0


def _table3(claim: Claim, ctx: ClaimContext) -> ClaimResult:
    """η, τ_η, R_λ from u′, ε by the stack's ``turbulence_scales`` and by the presets."""
    worst = 0.0
    for name, (eta, tau, r_lambda) in _TABLE3.items():
        p = FLOW_PRESETS[name].parameters
        stack = turbulence_scales(p.u_rms, p.epsilon, nu=p.nu)
        scales = (p.eta, p.tau_eta, p.R_lambda), (stack.eta, stack.tau_eta, stack.re_lambda)
        for derived in scales:
            worst = max(
                worst,
                abs(derived[0] * 1e6 / eta - 1) / 0.05,
                abs(derived[1] * 1e3 / tau - 1) / 0.05,
                abs(derived[2] / r_lambda - 1) / 0.01,
            )
    return result(
        claim,
        worst,
        "η, τ_η within 5 %, R_λ within 1 % of the printed table, by ptv.stats.dissipation."
        "turbulence_scales and by the presets (worst / tolerance ≤ 1)",
        worst <= 1,
    )


def _c1_against_reference(
    fit: StructureFunction, reference: BruteForceS2, l_int: float
) -> tuple[float, str]:
    """c₁ against S2_ref: per bin, and pooled over r ≥ POOLED_FROM·L_int.

    Returns the worst deviation over its allowance (≤ 1 passes) and the tolerance in
    words. Per bin |c₁/S2_ref − 1| ≤ max(3 %, zσ), σ² the sum of c₁'s bootstrap
    variance and S2_ref's subsampling variance, z the normal quantile of 0.1 % false
    alarms shared over the bins. Pooled: the mean of c₁/S2_ref within 3.29σ (0.1 %), σ
    from c₁'s bootstrap replicates of that mean and S2_ref's subsampling error (the
    bootstrap includes the sampling of the flow, which c₁ and S2_ref share, so this
    overstates the error of their ratio).
    """
    s2_ref, se_ref = reference.s2, reference.se_s2()
    ok = fit.fitted & np.isfinite(s2_ref) & (s2_ref > 0)
    ratio = fit.s2 / s2_ref
    z_bins = false_alarm_z(None, tests=max(int(ok.sum()), 1))
    allowed = np.maximum(C1_METHOD_ERROR, z_bins * np.hypot(fit.se_s2, se_ref) / s2_ref)
    per_bin = float(np.max(np.abs(ratio[ok] - 1) / allowed[ok]))
    far = ok & (reference.r >= POOLED_FROM * l_int)
    pooled = float(np.mean(ratio[far]))
    boot = np.std(np.mean(fit.s2_boot[:, far] / s2_ref[far], axis=1), ddof=1)
    _, se_sub = reference.pooled(np.where(far, fit.s2 / s2_ref**2, 0.0) / far.sum())
    tolerance = NORMAL_Z * float(np.hypot(boot, se_sub))
    value = max(per_bin, abs(pooled - 1) / tolerance)
    groups, size = reference.count.shape[1], int(reference.group_size.max())
    text = (
        f"every bin |c₁/S2_ref − 1| ≤ max(3 %, {z_bins:.3g}σ) (worst {per_bin:.2f} of "
        f"allowed); r ≥ {POOLED_FROM:g} L_int: mean c₁/S2_ref {pooled:.4f} within "
        f"{NORMAL_Z:.3g}σ = {tolerance:.2%} (0.1 % false alarms each) "
        f"(S2_ref: brute force, {groups} groups of ≤ {size} particles "
        f"per snapshot, subsampling σ {se_sub:.2%})"
    )
    return value, text


def _c1_truth(claim: Claim, ctx: ClaimContext) -> ClaimResult:
    l_int = ctx.preset.parameters.L_int
    value, text = _c1_against_reference(ctx.multi_dt.fit, ctx.reference, l_int)
    return result(claim, value, text, value <= 1)


def _correlated(claim: Claim, ctx: ClaimContext) -> ClaimResult:
    r = ctx.multi_dt_correlated
    value, text = _c1_against_reference(r.fit, ctx.reference, ctx.preset.parameters.L_int)
    sel = r.fit.fitted
    rho = np.exp(-(r.fit.r[sel] ** 2) / (2 * CORRELATION_LENGTH**2))
    noise = np.median(r.fit.noise[sel] / (NOISE_TERM * (1 - rho)))
    return result(
        claim,
        value,
        f"as #8: {text}; c₂/4σ²(1 − ρ(r)) median {noise:.3f} within 5 %",
        value <= 1 and abs(noise - 1) <= 0.05,
    )


def _c2(claim: Claim, ctx: ClaimContext) -> ClaimResult:
    r = ctx.multi_dt
    sel = r.fit.fitted
    value = float(np.median(r.fit.noise[sel]) / NOISE_TERM)
    positive = bool(np.all(r.fit.noise[sel] > 0))
    return result(
        claim,
        value,
        "c₂ > 0 in every bin and median c₂/4σ² within 5 %",
        positive and abs(value - 1) <= 0.05,
    )


def _chi2(claim: Claim, ctx: ClaimContext) -> ClaimResult:
    """χ² of the reported line c₁Δt² + c₂ through the ⟨q⟩_k, with their bootstrap σ."""
    f = ctx.multi_dt.fit
    residual = (f.raw_s2 - f.s2[:, None] - f.noise[:, None] / f.dt**2) / f.se_raw_s2
    chi2 = np.sum(residual[:, f.used] ** 2, axis=1) / (np.count_nonzero(f.used) - 2)
    value = float(np.median(chi2[f.fitted]))
    return result(
        claim,
        value,
        "median χ²/dof < 2, χ² of the reported c₁, c₂ against ⟨q⟩_k (a right line gives ≈ 1)",
        value < 2,
    )


def _epsilon(claim: Claim, ctx: ClaimContext) -> ClaimResult:
    """Plateau ε against ε_input × the estimator's deficit (independent quadrature, C₂ = 2)."""
    r = ctx.multi_dt
    value = r.epsilon_fit / ctx.epsilon_reference
    s2, radius = r.fit.s2[r.inertial], r.fit.r[r.inertial]
    boot = np.nanmax(r.fit.s2_boot[:, r.inertial] ** 1.5 / radius, axis=1)
    relative_se = float(np.std(boot, ddof=1) / np.nanmax(s2**1.5 / radius))
    tolerance = NORMAL_Z * relative_se + 1.5 * C1_PLATEAU_BIAS
    deficit = ctx.epsilon_reference / ctx.preset.parameters.epsilon - 1
    return result(
        claim,
        value,
        f"ε / (ε_input × (1 {deficit:+.1%})) within ±{tolerance:.1%} (the deficit of "
        f"max (D_LL/{REFERENCE_C2:g})^{{3/2}}/r over {PLATEAU_RANGE[0] * 1e3:g}–"
        f"{PLATEAU_RANGE[1] * 1e3:g} mm by an independent quadrature; {NORMAL_Z:.3g}σ of the "
        f"plateau's bootstrap (0.1 % false alarms) + 1.5 × c₁'s {C1_PLATEAU_BIAS:.0%} bias "
        "there)",
        abs(value - 1) <= tolerance,
    )


def _mean_linear(claim: Claim, ctx: ClaimContext) -> ClaimResult:
    """The stack's β₀ test on the runs, and on the runs with an offset added to ΔX.

    The offset is 5σ of β₀ with σ from the scatter of the snapshot means, computed apart
    from the stack (:func:`validation.truth.independent.intercept_standard_error`): an
    error the stack makes in its own σ moves its test statistic against it.
    """
    r = ctx.multi_dt
    statistic, limit = r.mean_displacement.offset_test()
    means = [
        np.array([d.mean(axis=0) for _, d in run.snapshot_arrays() if len(d)]) for run in r.links
    ]
    offset = OFFSET_IN_SE * intercept_standard_error(r.mean_displacement.dt, means)
    shifted = mean_displacement(
        [replace(run, displacements=run.displacements + offset) for run in r.links]
    )
    detected, _ = shifted.offset_test()
    recovered = (shifted.fit.c2 - r.mean_displacement.fit.c2) / offset
    return result(
        claim,
        statistic,
        f"Σ(β₀/σ)² < {limit:.3g} (χ²₃, {100 * OFFSET_FALSE_ALARM:g} % false alarms, the "
        "stack's test); a frame offset of "
        f"{OFFSET_IN_SE:g}σ per component (σ of β₀ from the snapshot means' scatter, apart "
        f"from the stack) detected ({detected:.3g}) and recovered "
        f"(β₀ shift / offset {recovered.min():.3f}–{recovered.max():.3f}, within 1 %)",
        statistic < limit and detected > limit and bool(np.all(np.abs(recovered - 1) <= 0.01)),
    )


def _raw_biased(claim: Claim, ctx: ClaimContext) -> ClaimResult:
    """Raw S2 at Δt₁ against S2_ref + 4σ²/Δt₁², and over S2_ref near 10η."""
    f, reference = ctx.multi_dt.fit, ctx.reference
    s2_ref, se_ref = reference.s2, reference.se_s2()
    k = int(np.argmin(f.dt))
    expected = s2_ref + NOISE_TERM / f.dt[k] ** 2
    ok = f.fitted & np.isfinite(s2_ref)
    pull = (f.raw_s2[ok, k] - expected[ok]) / np.hypot(f.se_raw_s2[ok, k], se_ref[ok])
    chi2 = float(np.sum(pull**2))
    limit = float(chi2_distribution.ppf(0.999, ok.sum()))
    near = ok & (reference.r <= 20 * ctx.preset.parameters.eta)
    value = float(np.median(f.raw_s2[near, k] / s2_ref[near]))
    return result(
        claim,
        value,
        f"raw S2(Δt₁)/S2_ref median over 10η–20η > 2; raw S2(Δt₁) = S2_ref + 4σ²/Δt₁²: "
        f"χ² {chi2:.3g} over {ok.sum()} bins < {limit:.3g} (0.1 % false alarms)",
        value > 2 and chi2 < limit,
    )


def _subsets(claim: Claim, ctx: ClaimContext) -> ClaimResult:
    r = ctx.multi_dt
    three = r.epsilon_subsets["3 largest dt"] / r.epsilon_fit - 1
    two = r.epsilon_subsets["smallest and largest dt"] / r.epsilon_fit - 1
    return result(
        claim,
        max(abs(three) / 0.10, abs(two) / 0.05),
        f"|Δε| < 10 % (3 largest: {100 * three:+.1f} %), < 5 % (min + max: {100 * two:+.1f} %)",
        abs(three) < 0.10 and abs(two) < 0.05,
    )


def _noisy_higher(claim: Claim, ctx: ClaimContext) -> ClaimResult:
    """ε of the raw S2 at each Δt over the fit's ε, against the injected noise's share."""
    r, reference = ctx.multi_dt, ctx.reference
    c2 = {} if ctx.kolmogorov_c2 is None else {"kolmogorov_c2": ctx.kolmogorov_c2}
    radius = r.fit.r[r.inertial]

    def plateau(s2: np.ndarray) -> float:
        profile = dissipation_profile(radius, s2[r.inertial], **c2)
        return plateau_epsilon(
            profile, r_min=PLATEAU_RANGE[0], r_max=PLATEAU_RANGE[1], method="max"
        ).epsilon

    measured = np.array([plateau(raw) for raw in r.fit.raw_s2.T]) / r.epsilon_fit
    inside = np.isfinite(reference.r)
    inside &= (reference.r >= PLATEAU_RANGE[0]) & (reference.r <= PLATEAU_RANGE[1])
    s2_ref, r_ref = reference.s2[inside], reference.r[inside]
    expected = np.array(
        [np.max((s2_ref + NOISE_TERM / dt**2) ** 1.5 / r_ref) for dt in r.fit.dt]
    ) / np.max(s2_ref**1.5 / r_ref)
    worst = float(np.max(np.abs(measured / expected - 1)))
    return result(
        claim,
        float(measured.min()),
        f"ε(raw S2 at Δt_k)/ε > 1 for every Δt ({measured.min():.3f}–{measured.max():.3g}), "
        f"each within 4.5 % of its value for S2_ref + 4σ²/Δt² (worst {worst:.1%}; 1.5 × the "
        "3 % of #8)",
        measured.min() > 1 and worst <= 1.5 * C1_METHOD_ERROR,
    )


def _two_thirds(claim: Claim, ctx: ClaimContext) -> ClaimResult:
    """Mean local slope d ln c₁/d ln r over 20η < r < 0.2L_int (L_int = u'³/ε).

    Measured on the band-limited K41 spectrum cut at k_N = 2π/η, whose exact D_LL has a
    local slope of 0.65–0.71 there (docs/flow.md §2.4; the Pope spectrum gives 0.69–1.0
    and the dissipation-matched band, cut at k_Nη = 0.544, 0.70–0.96). The slope is that
    of the weighted line through ln c₁ against ln r (σ of ln c₁ = σ(c₁)/c₁), since
    bin-to-bin slopes scatter by ±0.05 at quick size. It comes out ≈ 0.04 above that of
    the exact D_LL: on this spectrum c₁ is low at small r (−7 % at 23η), because its
    smallest modes turn over in τ_η/5 (it dissipates 26ε), so Δt_max = 0.21τ_η is not
    small against them.
    """
    fit, p = ctx.multi_dt_band.fit, ctx.preset.parameters
    sel = fit.fitted & (fit.r > 20 * p.eta) & (fit.r < 0.2 * p.L_int)
    line = wls_line(np.log(fit.r[sel]), np.log(fit.s2[sel]), fit.se_s2[sel] / fit.s2[sel])
    slope = float(line.c1[0])
    return result(
        claim,
        slope,
        f"0.667 ± 0.07 (line through {np.count_nonzero(sel)} bins, σ {line.se_c1[0]:.3f})",
        abs(slope - 2.0 / 3.0) <= 0.07,
    )


def _dt3_negligible(claim: Claim, ctx: ClaimContext) -> ClaimResult:
    """Bias of c₁ from a Δt³ term, against γβ/S2 (docs/statistics.md §4).

    KS has no energy flux (⟨δu·δa⟩ = 0, docs/flow.md §7), so the term ⟨δv_∥δa_∥⟩Δt³ of
    ⟨q⟩ = N + S2Δt² + ⟨δv_∥δa_∥⟩Δt³ is injected: β Δt_k³, with β = −(2/3)ε, is added to
    the q = (δΔX·e)² of every pair at Δt_k, so each ⟨q⟩_k and each bootstrap replicate
    moves by exactly βΔt_k³ (``add_dt3_term``; the fits with and without it share noise
    and bootstrap draws). The measured bias is (c₁^β − c₁)/S2 with S2 the exact D_LL of
    the spectrum; the prediction γβ/S2 takes γ of the unweighted fit (0.218 τ_η for the
    10 Hz set), while the weighted fit leans on the small Δt at large r, where the
    measured bias is up to 25 % smaller. The run is the band-limited one, whose
    S2 ≈ 1.8(εr)^{2/3} down to 10η, as the estimate of docs/statistics.md §4 (−1.1 to
    −1.8 % at 10η) assumes. On the Pope spectrum S2(10η) is about half that and the bias
    reaches −2.9 % at 11η and −2.1 % at 14η, but β = −(2/3)ε is an inertial-range value
    that does not hold in that dissipation range.
    """
    p = ctx.preset.parameters
    base, biased = ctx.dt3_fits
    sel = base.fitted & biased.fitted & (base.r >= 10 * p.eta)
    s2 = ctx.multi_dt_band.exact_dll[sel]
    bias = (biased.s2[sel] - base.s2[sel]) / s2
    beta = ctx.dt3_coefficient * p.epsilon
    ratio = bias / (dt3_gamma(ctx.preset.dt) * beta / s2)
    worst = float(np.max(np.abs(bias)))
    return result(
        claim,
        100 * worst,
        f"max |bias| < 2 % for r ≥ 10η; bias/(γβ/S2) in [{ratio.min():.2f}, {ratio.max():.2f}]"
        " within 1 ± 0.3",
        worst < 0.02 and bool(np.all(np.abs(ratio - 1) <= 0.3)),
    )


def _scale_bias(claim: Claim, ctx: ClaimContext) -> ClaimResult:
    shift = ctx.multi_dt_scaled.epsilon_fit / ctx.multi_dt.epsilon_fit - 1
    return result(
        claim, 100 * shift, "+2.0 ± 0.5 % for a 1 % scale error", abs(shift - 0.02) <= 0.005
    )


def _convention(claim: Claim, ctx: ClaimContext) -> ClaimResult:
    s2, r = np.array([1e-3]), np.array([5e-3])
    c2 = {} if ctx.kolmogorov_c2 is None else {"kolmogorov_c2": ctx.kolmogorov_c2}
    value = float(epsilon_estimate(s2, r, **c2)[0] / epsilon_paper_caption(s2, r)[0])
    return result(claim, value, "1/2.83 ± 1 % (C₂ = 2)", abs(value * 2**1.5 - 1) <= 0.01)


FLOW_CLAIMS: tuple[Claim, ...] = (
    Claim(
        "table3.arithmetic", "Table 3", "η, τ_η, R_λ follow from u', ε (10 Hz: u' = 0.19)", _table3
    ),
)

STATISTICS_CLAIMS: tuple[Claim, ...] = (
    Claim("stats.c1_matches_truth", "eq. S2, Fig. 6a", "c₁ is the noise-free S2", _c1_truth),
    Claim("stats.c2_positive", "§3, Fig. 5b", "c₂ > 0 and equals 4σ² for white noise", _c2),
    Claim(
        "stats.correlated_noise_removed",
        "§3 (noise correlation C_b)",
        "spatially correlated white noise is removed too; c₂ = 4σ²(1 − ρ(r))",
        _correlated,
    ),
    Claim("stats.linear_in_dt2", "Fig. 5b", "q(Δt) is linear in Δt²", _chi2),
    Claim("stats.epsilon_recovered", "Fig. 6b, Table 3", "ε from the plateau of c₁", _epsilon),
    Claim(
        "stats.mean_linear_in_dt", "§3", "mean displacement ∝ Δt (zero-mean noise)", _mean_linear
    ),
    Claim("stats.raw_s2_biased", "Fig. 5a", "raw S2 of ΔX is strongly Δt-dependent", _raw_biased),
    Claim("stats.dt_subsets", "§3", "3 largest Δt: −5 %; min + max: +2 %", _subsets),
    Claim(
        "stats.noisy_estimates_higher",
        "§3",
        "u', ε slightly lower than noisy estimates",
        _noisy_higher,
    ),
    Claim(
        "stats.two_thirds_scaling",
        "Fig. 6a",
        "c₁ scales as r^{2/3} over about a decade (band-limited spectrum)",
        _two_thirds,
    ),
    Claim(
        "stats.dt3_negligible",
        "§3",
        "the Δt³ term is negligible for r ≫ η, Δt ≤ 0.2τ_η",
        _dt3_negligible,
    ),
    Claim(
        "stats.calibration_bias_not_removed",
        "docs/statistics.md §9",
        "a systematic scale error s shifts ε by 2s",
        _scale_bias,
    ),
    Claim(
        "stats.epsilon_convention",
        "Fig. 6b caption (docs/errata.md E5)",
        "ε = (S2/C₂)^{3/2}/r is C₂^{−3/2} × the caption's S2^{3/2}/r",
        _convention,
    ),
)
