"""The checks of ``synptv run`` on the run and on every calibration rung, and its verdict.

Two kinds of checks (tolerances here, in :mod:`validation.run.checks` and in
docs/claims.md §4):

- checks of the run, one value each: Table 1 of the model-free calibration against
  classic Tsai (where claim #16 applies), the detection error and its peak locking, c2
  of the truth-paired detections against their measured noise;
- checks of a calibration rung (the PTV stack with one method of ``[ptv] methods``),
  the same on every rung: matching yield and ghosts in the analysis volume, c1, ε,
  c2 > 0, c1 and ε against references that share no code with the stack (where the
  truth file has them), the raw S2 at the smallest Δt, the mean displacement linear in
  Δt, the ε of the Δt subsets.

The rule of the verdict: the checks of the run and those of the method under test,
the first of ``[ptv] methods`` (model-free in every preset), must hold; ``synptv run``
exits with status 1 when one of them fails. Every other method is a baseline (classic
Tsai in ``default``): its checks run the same and are reported PASS or FAIL, and a FAIL
there is a finding about that calibration (Tsai on Scheimpflug cameras behind oblique
windows loses particles and adds ghosts: claim #16), not a failure of the run.
"""

import numpy as np

from validation.run.checks import EPSILON_TOLERANCE
from validation.run.derived_ptv import PLATEAU_MIN_ETA
from validation.score.tolerances import FALSE_ALARM

#: Matching in the analysis volume: the least yield and the most ghosts.
YIELD_MIN = 0.90
GHOST_MAX = 0.05
#: Detection: the largest rms error and peak-locking amplitude, px. Flat histogram: the
#: sinusoidal bias amplitude is a tenth of the 0.1 px error budget or less (density
#: within 1 ± 2π·0.01 ≈ ±6 %).
DETECTION_RMS_MAX_PX = 0.1
PEAK_LOCKING_MAX_PX = 0.01
#: Table 1 d of classic Tsai over the model-free calibration's, at least (claim #16).
TSAI_OVER_MODEL_FREE_MIN = 3.0

#: IPR, as the LPT Challenge's best codes do at a density (particles per pixel) up to
#: the first number: the least found fraction, the most ghosts and the largest projected
#: position error, px (None: not asked at that density).
IPR_TARGETS = ((0.05, 0.99, 0.01, 0.1), (0.12, 0.97, 0.03, None))

UNDER_TEST = "method under test"
BASELINE = "baseline"
RULE = (
    "Must hold: the checks of the run and every check of the method under test (the "
    "first of [ptv] methods); synptv run exits with status 1 when one fails. The other "
    "methods are baselines: their checks run the same and are reported, and a FAIL "
    "there is a finding about that calibration, not a failure of the run."
)
IPR_RULE = (
    "Must hold: the checks of the run and every check of the method under test (IPR "
    "through the first of [ipr] methods); synptv run exits with status 1 when one fails. "
    "The detect-and-match rungs of [ptv] methods are baselines: their checks run the same "
    "and are reported, and a FAIL there is a finding about detecting and matching dense "
    "images, not a failure of the run."
)


#: Checks whose value is a relative deviation, printed in % like their tolerance.
PERCENT_CHECKS = frozenset(
    {
        "stats.c1_matches_truth",
        "stats.epsilon_recovered",
        "stats.u_prime_recovered",
        "stats.c1_matches_independent_truth",
        "stats.epsilon_matches_input_deficit",
        "stats.dt_subsets",
        "stats.sample_off_ensemble",
        "ipr.found",
        "ipr.ghosts",
    }
)
#: How a check's false-alarm rate is written beside its tolerance.
RATE = f"{100 * FALSE_ALARM:g} % false alarms"


def _row(check_id: str, value, tolerance: str, passed, informative: str | None = None) -> dict:
    """A check; ``informative`` (why it is not required) only where the configuration
    makes it a property of the rig rather than of the code."""
    row = {"id": check_id, "value": value, "tolerance": tolerance, "passed": bool(passed)}
    if informative is not None:
        row["informative"] = informative
    return row


def calibration_check(table1: dict, rig: dict) -> dict | None:
    """Model-free against classic Tsai on the Table 1 metric (nominal dots), checked
    where the paper's claim applies: both calibrated, every camera on a Scheimpflug
    mount behind an oblique window (docs/claims.md #16: d_Tsai/d_new ≥ 3).

    Parameters
    ----------
    table1 : dict
        ``table1.json``'s ``table1``: per method and reference, the Table 1 errors.
    rig : dict
        The rig's spec.

    Returns
    -------
    dict or None
        The check (``id``, ``value``, ``tolerance``, ``passed``); None where the claim
        does not apply.
    """
    oblique = all(
        c.get("scheimpflug") and c.get("window", {}).get("obliquity_deg", 0.0) > 0
        for c in rig["cameras"]
    )
    if not (oblique and {"model-free", "tsai"} <= set(table1)):
        return None
    ratio = table1["tsai"]["nominal"]["d_um"] / table1["model-free"]["nominal"]["d_um"]
    return _row(
        "calibration.tsai_over_model_free_d",
        ratio,
        f"≥ {TSAI_OVER_MODEL_FREE_MIN:g} (Table 1 d; the paper: 4.5)",
        ratio >= TSAI_OVER_MODEL_FREE_MIN,
    )


def run_checks(detection: dict, detected: dict, calibration: dict | None) -> list[dict]:
    """The checks of the run, one value each (module docstring).

    Parameters
    ----------
    detection : dict
        ``detection.json`` of the detection rung.
    detected : dict
        The detection rung's comparison with the truth
        (:func:`validation.run.checks.compare_variant`).
    calibration : dict, optional
        :func:`calibration_check`.

    Returns
    -------
    list of dict
        ``id``, ``value``, ``tolerance``, ``passed``.
    """
    rms = float(np.max(detection["rms_error_px"]))
    amplitude = float(
        np.max(np.abs([v["amplitude_px"] for v in detection["peak_locking"].values()]))
    )
    rows = [] if calibration is None else [calibration]
    rows += [
        _row(
            "detection.rms_error_px",
            rms,
            f"≤ {DETECTION_RMS_MAX_PX:g} px",
            rms <= DETECTION_RMS_MAX_PX,
        ),
        _row(
            "detection.peak_locking_amplitude_px",
            amplitude,
            f"|a| ≤ {PEAK_LOCKING_MAX_PX:g} px (a tenth of the error budget)",
            amplitude <= PEAK_LOCKING_MAX_PX,
        ),
    ]
    # c2 against the position noise where that noise is known for every particle of S2:
    # the truth-paired detections (the PTV runs add ghosts and mislinks, whose errors
    # the truth cannot attribute; their ratio is in the report's noise section).
    c2 = detected["c2"]
    if "consistent" in c2:
        lo, hi = c2["consistent_range"]
        rows.append(
            _row(
                "stats.c2_matches_noise (detection)",
                c2["median_over_prediction"],
                f"median (c2 − exact positions' c2) / noise prediction in [{lo:.2f}, {hi:.2f}]",
                c2["consistent"],
            )
        )
    return rows


def failed_rung_checks(failure: dict) -> list[dict]:
    """The one check of a baseline whose calibration failed: which camera, and why.

    Parameters
    ----------
    failure : dict
        ``table1.json``'s ``failed`` entry of the method: ``camera`` and ``reason``.
    """
    return [
        _row(
            "calibration.fitted",
            None,
            f"fits every camera; failed on {failure['camera']}: {failure['reason']}",
            False,
        )
    ]


def rung_checks(comparison: dict, matching: dict) -> list[dict]:
    """The checks of one calibration rung (module docstring), the same on every rung.

    Parameters
    ----------
    comparison : dict
        The rung's comparison with the truth (:func:`validation.run.checks.compare_variant`).
    matching : dict
        The rung's ``matching.json``: ``yield`` and ``ghost_fraction`` in the analysis
        volume.

    Returns
    -------
    list of dict
        ``id`` (without the rung's name), ``value``, ``tolerance``, ``passed``.
    """
    c = comparison
    c1_range = c["c1"]["r_range_m"]
    used = c["c1"].get("r_used_m")
    c1_where = (
        f"over the {c['c1']['bins']} fitted bins at {used[0] * 1e3:.2g}–{used[1] * 1e3:.3g} mm "
        f"(of {c1_range[0] * 1e3:.2g}–{c1_range[1] * 1e3:.3g} mm asked)"
        if used
        else f"no fitted bin in {c1_range[0] * 1e3:.2g}–{c1_range[1] * 1e3:.3g} mm"
    )
    eps = c["epsilon"]
    rows = [
        _row(
            "matching.yield",
            matching["yield"],
            f"≥ {YIELD_MIN:.2f}",
            matching["yield"] >= YIELD_MIN,
        ),
        _row(
            "matching.ghost_fraction",
            matching["ghost_fraction"],
            f"≤ {GHOST_MAX:.2f}",
            matching["ghost_fraction"] <= GHOST_MAX,
        ),
        *_linking_rows(c),
        _row(
            "stats.c1_matches_truth",
            c["c1"]["max_abs_deviation"],
            f"≤ {c['c1']['tolerance']:.0%} + {c['c1']['z']:.3g}σ per bin {c1_where}; {RATE}",
            c["c1"]["passed"],
        ),
        _epsilon_row(eps),
    ]
    if "u_prime" in c:
        up = c["u_prime"]
        rows.append(
            _row(
                "stats.u_prime_recovered",
                up["relative_to_exact_rung"],
                f"within ±{up['tolerance']:.3g} ({up['method_tolerance']:.0%} + "
                f"{up['z']:.3g}σ, {'paired' if up['paired'] else 'unpaired'}) of the exact "
                f"trajectories' u′; {RATE}",
                up["passed"],
            )
        )
    rows.append(
        _row(
            "stats.c2_positive",
            c["c2"]["significantly_negative_bins"],
            f"0 bins with c2 below −{c['c2']['z']:.3g}σ; {RATE}",
            c["c2"]["passed"],
        )
    )
    if "c1_independent" in c:
        ind, eps_ind = c["c1_independent"], c["epsilon_independent"]
        rows += [
            _row(
                "stats.c1_matches_independent_truth",
                ind["max_abs_deviation"],
                f"≤ {ind['tolerance']}; sample truth / reference "
                f"{ind['sample_over_reference']:.4f} within {ind['z_sample_over_reference']:.3g}σ "
                f"({ind['se_sample_over_reference']:.2%}); {RATE}",
                ind["passed"],
            ),
            _row(
                "stats.epsilon_matches_input_deficit",
                eps_ind["relative_to_reference"],
                f"within ±{eps_ind['tolerance']:.3g} ({EPSILON_TOLERANCE:.0%} + "
                f"{eps_ind['z']:.3g}σ of the sample) of ε_input × (1 "
                f"{eps_ind['plateau_deficit']:+.1%}), the deficit by an independent "
                f"quadrature; {RATE}",
                eps_ind["passed"],
            ),
        ]
    if "raw_s2" in c:
        raw = c["raw_s2"]
        rows.append(
            _row(
                "stats.raw_s2_biased",
                raw["ratio_smallest_dt"],
                f"median > {raw['minimum']:g} over 5η–20η",
                raw["passed"],
                raw.get("informative"),
            )
        )
    linear = c["mean_linear"]
    rows.append(
        _row(
            "stats.mean_linear_in_dt",
            linear["statistic"],
            f"β0ᵀC⁻¹β0 < {linear['limit']:.3g} ({100 * linear['false_alarm_rate']:g} % false "
            "alarms)",
            linear["passed"],
        )
    )
    for name, sub in c["subsets"].items():
        rows.append(
            _row(
                f"stats.dt_subsets: {name}",
                sub["change"],
                f"|Δε| < {sub['tolerance']:.0%} + {sub['z']:.3g}σ ({sub['allowed']:.3g}); {RATE}",
                sub["passed"],
            )
        )
    return rows


def ipr_rows(reconstruction: dict) -> list[dict]:
    """The checks of an IPR rung's reconstruction against the LPT Challenge's targets at
    its density (:data:`IPR_TARGETS`; above the densest, informative rows).

    Parameters
    ----------
    reconstruction : dict
        The rung's ``reconstruction.json`` (:mod:`validation.truth.reconstruction`):
        ``ppp``, ``found``, ``ghosts``, ``rms_px``.

    Returns
    -------
    list of dict
        ``id``, ``value``, ``tolerance``, ``passed`` (and ``informative``).
    """
    ppp = reconstruction["ppp"]
    target = next((t for t in IPR_TARGETS if ppp <= t[0]), None)
    found, ghosts, rms = (reconstruction[k] for k in ("found", "ghosts", "rms_px"))
    if target is None:
        note = f"{ppp:.3g} particles per pixel: beyond {IPR_TARGETS[-1][0]:g}, no target is set"
        return [
            _row("ipr.found", found, "reported", True, note),
            _row("ipr.ghosts", ghosts, "reported", True, note),
            _row("ipr.position_error_px", rms, "reported", True, note),
        ]
    up_to, found_min, ghosts_max, error_max = target
    where = f"at {ppp:.3g} ≤ {up_to:g} particles per pixel (the LPT Challenge's best codes)"
    rows = [
        _row("ipr.found", found, f"≥ {found_min:g} {where}", found >= found_min),
        _row("ipr.ghosts", ghosts, f"≤ {ghosts_max:g} {where}", ghosts <= ghosts_max),
    ]
    if error_max is not None:
        rows.append(
            _row(
                "ipr.position_error_px",
                rms,
                f"≤ {error_max:g} px rms, projected, {where}",
                rms is not None and rms <= error_max,
            )
        )
    return rows


def _linking_rows(comparison: dict) -> list[dict]:
    """The ambiguity of the links (none where they were not made by distance)."""
    linking = comparison.get("linking")
    if linking is None:
        return []
    return [
        _row(
            "linking.ambiguity",
            linking["worst"],
            f"≤ {linking['limit']:g} of the links with a second candidate at every Δt "
            f"(worst at {linking['worst_dt'] * 1e3:.3g} ms)",
            linking["passed"],
        )
    ]


def _epsilon_row(eps: dict) -> dict:
    """The ε check's row: against the exact trajectories of the same snapshots where the
    run has them (paired), else against the estimator on the exact D_LL."""
    if "relative_to_exact_rung" in eps:
        return _row(
            "stats.epsilon_recovered",
            eps["relative_to_exact_rung"],
            f"within ±{eps['tolerance']:.3g} ({eps['method_tolerance']:.0%} + {eps['z']:.3g}σ, "
            f"{'paired' if eps['paired'] else 'unpaired'}) of the exact trajectories' ε; {RATE}",
            eps["passed"],
        )
    tolerance = "n/a" if eps["tolerance"] is None else f"±{eps['tolerance']:.3g}"
    return _row(
        "stats.epsilon_recovered",
        eps["relative_to_exact_d_ll"],
        f"within {tolerance} of the estimator on the exact D_LL; {RATE}",
        eps["passed"],
    )


def sample_row(comparison: dict) -> dict | None:
    """An informative row: how far the exact trajectories' ε lies from the ensemble's.

    Parameters
    ----------
    comparison : dict
        A rung's comparison (:func:`validation.run.checks.compare_variant`), whose
        ``epsilon.sample_off_ensemble`` (:func:`validation.run.checks.sample_off_ensemble`)
        is read.

    Returns
    -------
    dict or None
        The row, in the exact trajectories' standard errors (a statement about the
        sample, not a verdict on the code); None where the run has no exact rung.
    """
    off = comparison["epsilon"].get("sample_off_ensemble")
    if off is None:
        return None
    effective = off["effective_snapshots"]
    snapshots = "" if effective is None else f" ({effective:.3g} effective snapshots)"
    return _row(
        "stats.sample_off_ensemble",
        off["relative"],
        f"the exact trajectories' ε against the estimator on the exact D_LL: "
        f"{off['in_se']:+.2g} standard errors{snapshots}",
        True,
        "a statement about the sample (which eddies its snapshots caught), not about the code",
    )


def dns_rows(dns: dict | None) -> list[dict]:
    """The checks of a DNS's ``dns`` section (:func:`validation.run.dns_checks.dns_section`;
    none for another flow): the energy budget and the Kármán–Howarth balance must hold
    (the truth is a solution of Navier–Stokes); the Δt³ bias against γβ/S2 is
    informative (the Δt⁴ terms and the bins' correlation make it a measurement, not a
    pass mark); the tracers' flux ⟨δu·δa⟩ at 10η against the field's must hold (the
    acceleration is the one the trajectories have)."""
    if dns is None:
        return []
    budget, balance = dns["energy_budget"], dns["karman_howarth"]
    rows = [
        _row(
            "dns.energy_budget",
            budget["dissipation_over_injection"],
            f"dissipation/injection within 1 ± {budget['tolerance']:g} over the window",
            budget["passed"],
        ),
        _row(
            "dns.karman_howarth",
            balance["max_residual_in_se"],
            f"≤ {balance['tolerance_se']:g} standard errors, 3Δx to a quarter box",
            balance["passed"],
        ),
    ]
    dt3 = dns["dt3_bias"]
    if dt3 is not None:
        rows.append(
            _row(
                "dns.dt3_bias_matches_field",
                dt3["chi2"],
                f"Σz² ≤ {dt3['chi2_limit']:g} over 10η, 20η, 40η (z: c1 bias − γβ/S2, paired SE)",
                dt3["passed"],
                "the Δt³ term measured against the field's β; the Δt⁴ terms grow with the Δt range",
            )
        )
    flux = dns.get("tracer_flux")
    if flux is not None:
        rows.append(
            _row(
                "dns.tracer_flux",
                flux["difference_over_2eps"],
                f"|tracers − field| ≤ {flux['tolerance_over_2eps']:.3g} (units of 2ε) at "
                f"{flux['r_over_eta']:.3g}η: ⟨δu·δa⟩ of the accelerations fitted to the "
                f"positions against the solver's, allowance + {flux['z']:.3g} SE "
                f"({flux['correlation']['effective_snapshots']:.3g} effective snapshots, "
                f"{100 * flux['false_alarm']:g} % false alarms)",
                flux["passed"],
            )
        )
    return rows


def verdict(
    run: list[dict], rungs: dict, methods, table1: dict, *, rule: str = RULE
) -> tuple[dict, list[dict]]:
    """The checks of the run and of every calibration rung, and which must hold.

    Parameters
    ----------
    run : list of dict
        :func:`run_checks`.
    rungs : dict
        ``{method: rung_checks(...)}`` for every method of ``[ptv] methods``.
    methods : sequence of str
        The rungs judged, the method under test first: ``[ptv] methods``, led by the
        IPR rungs of ``[ipr] methods`` where the scenario has them.
    table1 : dict
        ``table1.json``'s ``table1`` (the rungs' calibration errors, reported).
    rule : str
        What must hold, in words (:data:`RULE`, or :data:`IPR_RULE` where IPR rungs
        lead ``methods``).

    Returns
    -------
    (dict, list of dict)
        The checks (``rule``; ``run``; ``rungs``: per method its ``role``, whether its
        checks are ``required``, its Table 1 ``table1_d_um`` against the nominal dots
        and its ``checks``; ``passed``: whether every required check passed), and the
        list of the required checks (``must_hold``; a rung's checks named
        ``check (method)``).
    """
    per_rung = {}
    must_hold = [c for c in run if "informative" not in c]
    for i, method in enumerate(methods):
        required = i == 0
        d = table1.get(method, {}).get("nominal", {}).get("d_um")
        per_rung[method] = {
            "role": UNDER_TEST if required else BASELINE,
            "required": required,
            "table1_d_um": d,
            "checks": rungs[method],
        }
        if required:
            must_hold += [
                {**c, "id": f"{c['id']} ({method})"}
                for c in rungs[method]
                if "informative" not in c
            ]
    checks = {
        "rule": rule,
        "run": run,
        "rungs": per_rung,
        "passed": all(c["passed"] for c in must_hold),
    }
    return checks, must_hold


def verdict_line(checks: dict) -> str:
    """The verdict in one line: whether every required check passes, and which checks
    each baseline fails (``checks``: the first value of :func:`verdict`)."""
    line = "every required check passes" if checks["passed"] else "a required check fails"
    for method, rung in checks["rungs"].items():
        failed = [c["id"] for c in rung["checks"] if not c["passed"]]
        if failed and not rung["required"]:
            line += (
                f"; the {BASELINE} {method} fails {len(failed)} of {len(rung['checks'])} "
                f"(reported, not required): {', '.join(failed)}"
            )
    return line


def shown_value(check: dict) -> str:
    """A check's value as the terminal and the report show it: in per cent where its
    tolerance is one (a relative deviation), else to four digits; empty where it has none."""
    value = check["value"]
    if value is None:
        return ""
    if check["id"].split(" (")[0].split(":")[0] in PERCENT_CHECKS:
        return f"{100 * value:.3g} %"
    return f"{value:.4g}"


def summary_lines(results: dict) -> list[str]:
    """What ``synptv run`` prints of its checks: the required ones, then each baseline's,
    then the verdict (:func:`verdict_line`)."""

    def line(check: dict, name: str) -> str:
        mark = "PASS" if check["passed"] else "FAIL"
        return f"{mark}  {name:48s} {shown_value(check):>10s}   {check['tolerance']}"

    lines = [line(c, c["id"]) for c in results["must_hold"]]
    checks = results["checks"]
    informative = [(c, c["id"]) for c in checks["run"] if "informative" in c]
    for method, rung in checks["rungs"].items():
        if rung["required"]:
            informative += [
                (c, f"{c['id']} ({method})") for c in rung["checks"] if "informative" in c
            ]
    if informative:
        lines.append("informative here (a property of this configuration, not required):")
        lines += [f"{line(c, name)}  [{c['informative']}]" for c, name in informative]
    for method, rung in checks["rungs"].items():
        if not rung["required"]:
            lines.append(f"{method} ({BASELINE}: reported, not required):")
            lines += [line(c, f"{c['id']} ({method})") for c in rung["checks"]]
    for method, failure in results.get("calibration", {}).get("failed", {}).items():
        if method not in checks["rungs"]:  # a calibration baseline with no rung
            lines.append(
                f"{method} ({BASELINE}: reported, not required): could not calibrate camera "
                f"{failure['camera']}: {failure['reason']}"
            )
    lines.append(f"verdict: {verdict_line(checks)}")
    return lines


def plateau_row(plateau: tuple[float, float], eta: float) -> dict | None:
    """An informative row where the plateau starts below 40η (the derived plateau of a
    flow whose inertial range does not fit the analysis volume,
    :mod:`validation.run.derived_ptv`); None where it does not.

    Parameters
    ----------
    plateau : (float, float)
        The plateau's r range, m.
    eta : float
        The flow's Kolmogorov length, m.
    """
    start = plateau[0] / eta
    if start >= PLATEAU_MIN_ETA:
        return None
    return _row(
        "stats.plateau_below_40_eta",
        start,
        f"the plateau {plateau[0] * 1e3:.3g}–{plateau[1] * 1e3:.3g} mm starts at {start:.3g}η, "
        f"below {PLATEAU_MIN_ETA:g}η",
        True,
        "ε(r) there is not yet inertial; every ε check compares the same range of the "
        "exact trajectories or of the exact D_LL",
    )
