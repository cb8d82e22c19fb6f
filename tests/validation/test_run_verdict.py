"""The checks of ``synptv run`` on every calibration rung and the run's verdict: inputs
built so that which check fails, and on which rung, is known from the construction."""

import pytest

from validation.run.run_report import _checks_section
from validation.run.verdict import (
    BASELINE,
    UNDER_TEST,
    calibration_check,
    run_checks,
    rung_checks,
    summary_lines,
    verdict,
    verdict_line,
)

TABLE1 = {
    "model-free": {"nominal": {"d_um": 8.0}},
    "tsai": {"nominal": {"d_um": 50.0}},
}


def comparison(*, c1=0.01, epsilon=0.01, negative_bins=0, raw_s2=3.0, statistic=5.0):
    """A rung's comparison with the truth (the fields the checks read), every check
    passing with the defaults."""
    return {
        "c1": {
            "r_range_m": [2e-3, 20e-3],
            "max_abs_deviation": c1,
            "tolerance": 0.05,
            "z": 4.4,
            "passed": c1 <= 0.05,
        },
        "epsilon": {
            "relative_to_exact_d_ll": epsilon,
            "relative_to_exact_rung": epsilon,
            "method_tolerance": 0.01,
            "z": 3.56,
            "paired": True,
            "tolerance": 0.02,
            "passed": abs(epsilon) <= 0.02,
        },
        "c2": {
            "negative_bins": negative_bins,
            "significantly_negative_bins": negative_bins,
            "z": 4.4,
            "passed": negative_bins == 0,
        },
        "raw_s2": {"ratio_smallest_dt": raw_s2, "minimum": 2.0, "passed": raw_s2 > 2.0},
        "mean_linear": {
            "statistic": statistic,
            "limit": 13.8,
            "false_alarm_rate": 0.001,
            "passed": statistic < 13.8,
        },
        "subsets": {
            "3 largest dt": {
                "change": -0.01,
                "tolerance": 0.10,
                "z": 3.56,
                "allowed": 0.11,
                "passed": True,
            },
            "smallest and largest dt": {
                "change": 0.01,
                "tolerance": 0.05,
                "z": 3.56,
                "allowed": 0.06,
                "passed": True,
            },
        },
    }


def matching(yield_=0.95, ghosts=0.02):
    return {"yield": yield_, "ghost_fraction": ghosts}


def detection(rms=0.07, amplitude=0.002):
    return {
        "rms_error_px": [[rms, 0.05], [0.05, 0.05]],
        "peak_locking": {"cam0": {"amplitude_px": [amplitude, 0.0]}},
    }


DETECTED = {
    "c2": {"consistent": True, "consistent_range": [0.93, 1.05], "median_over_prediction": 0.98}
}


def failed(checks):
    return [c["id"] for c in checks if not c["passed"]]


def test_every_check_of_a_good_rung_passes():
    checks = rung_checks(comparison(), matching())
    assert failed(checks) == []
    assert [c["id"] for c in checks] == [
        "matching.yield",
        "matching.ghost_fraction",
        "stats.c1_matches_truth",
        "stats.epsilon_recovered",
        "stats.c2_positive",
        "stats.raw_s2_biased",
        "stats.mean_linear_in_dt",
        "stats.dt_subsets: 3 largest dt",
        "stats.dt_subsets: smallest and largest dt",
    ]


@pytest.mark.parametrize(
    ("rung", "fails"),
    [
        ((comparison(), matching(ghosts=0.10)), ["matching.ghost_fraction"]),
        ((comparison(), matching(yield_=0.87)), ["matching.yield"]),
        ((comparison(c1=0.061), matching()), ["stats.c1_matches_truth"]),
        ((comparison(negative_bins=2), matching()), ["stats.c2_positive"]),
        ((comparison(raw_s2=1.5), matching()), ["stats.raw_s2_biased"]),
        ((comparison(statistic=20.0), matching()), ["stats.mean_linear_in_dt"]),
    ],
)
def test_a_rung_fails_the_check_it_was_built_to_fail(rung, fails):
    assert failed(rung_checks(*rung)) == fails


def test_the_comparisons_with_independent_references_are_checked_when_the_truth_has_them():
    c = comparison()
    c["c1_independent"] = {
        "max_abs_deviation": 0.02,
        "tolerance": "5% + 4.4σ per bin",
        "sample_over_reference": 1.031,
        "se_sample_over_reference": 0.004,
        "z_sample_over_reference": 3.56,
        "passed": False,  # the sample truth 7.8σ off the brute force: a shared-code error
    }
    c["epsilon_independent"] = {
        "relative_to_reference": 0.01,
        "plateau_deficit": -0.2,
        "z": 3.56,
        "tolerance": 0.08,
        "passed": True,
    }
    checks = rung_checks(c, matching())
    assert failed(checks) == ["stats.c1_matches_independent_truth"]
    assert "stats.epsilon_matches_input_deficit" in [r["id"] for r in checks]
    row = next(r for r in checks if r["id"] == "stats.c1_matches_independent_truth")
    assert "1.0310 within 3.56σ" in row["tolerance"]


def test_a_rung_without_a_raw_s2_bin_has_no_raw_s2_check():
    c = comparison()
    del c["raw_s2"]
    assert "stats.raw_s2_biased" not in [r["id"] for r in rung_checks(c, matching())]


def test_a_baseline_with_ten_percent_ghosts_is_flagged_but_does_not_fail_the_run():
    rungs = {
        "model-free": rung_checks(comparison(), matching()),
        "tsai": rung_checks(comparison(c1=0.061), matching(yield_=0.87, ghosts=0.10)),
    }
    run = run_checks(detection(), DETECTED, None)
    checks, must_hold = verdict(run, rungs, ["model-free", "tsai"], TABLE1)
    assert checks["passed"] and all(c["passed"] for c in must_hold)
    assert checks["rungs"]["model-free"]["role"] == UNDER_TEST
    assert checks["rungs"]["tsai"]["role"] == BASELINE
    assert not checks["rungs"]["tsai"]["required"]
    assert checks["rungs"]["tsai"]["table1_d_um"] == 50.0
    assert failed(checks["rungs"]["tsai"]["checks"]) == [
        "matching.yield",
        "matching.ghost_fraction",
        "stats.c1_matches_truth",
    ]
    # What must hold: the run's checks and the method under test's, named by their rung.
    ids = [c["id"] for c in must_hold]
    assert ids[: len(run)] == [c["id"] for c in run]
    assert "matching.ghost_fraction (model-free)" in ids
    assert not any("tsai" in i for i in ids)
    line = verdict_line(checks)
    assert line.startswith("every required check passes")
    assert "tsai fails 3 of 9" in line and "matching.ghost_fraction" in line
    printed = summary_lines({"checks": checks, "must_hold": must_hold})
    assert any(p.startswith("FAIL  matching.ghost_fraction (tsai)") for p in printed)
    assert printed[-1] == f"verdict: {line}"


def test_the_method_under_test_with_ten_percent_ghosts_fails_the_run():
    rungs = {
        "tsai": rung_checks(comparison(), matching(ghosts=0.10)),
        "model-free": rung_checks(comparison(), matching()),
    }
    checks, must_hold = verdict(
        run_checks(detection(), DETECTED, None), rungs, ["tsai", "model-free"], TABLE1
    )
    assert not checks["passed"]
    assert failed(must_hold) == ["matching.ghost_fraction (tsai)"]
    assert verdict_line(checks) == "a required check fails"


def test_a_failed_check_of_the_run_fails_the_run():
    rungs = {"model-free": rung_checks(comparison(), matching())}
    run = run_checks(detection(rms=0.12), DETECTED, None)
    checks, must_hold = verdict(run, rungs, ["model-free"], TABLE1)
    assert failed(must_hold) == ["detection.rms_error_px"]
    assert not checks["passed"]


def test_the_calibration_claim_is_checked_only_on_oblique_scheimpflug_rigs():
    oblique = {"cameras": [{"scheimpflug": True, "window": {"obliquity_deg": 30.0}}] * 2}
    straight = {"cameras": [{"scheimpflug": False}] * 2}
    assert calibration_check(TABLE1, straight) is None
    check = calibration_check(TABLE1, oblique)
    assert check["value"] == pytest.approx(50.0 / 8.0) and check["passed"]
    close = {**TABLE1, "tsai": {"nominal": {"d_um": 20.0}}}
    assert not calibration_check(close, oblique)["passed"]


def test_the_report_has_a_column_per_rung_with_each_verdict_and_value():
    rungs = {
        "model-free": rung_checks(comparison(), matching()),
        "tsai": rung_checks(comparison(), matching(ghosts=0.10)),
    }
    checks, _ = verdict(
        run_checks(detection(), DETECTED, None), rungs, ["model-free", "tsai"], TABLE1
    )
    page = "\n".join(_checks_section({"checks": checks}, None))
    assert "<th>model-free (method under test: must hold)</th>" in page
    assert "<th>tsai (baseline: reported)</th>" in page
    ghost_row = next(r for r in page.split("<tr>") if r.startswith("<td>matching.ghost_fraction"))
    assert '<td class="pass">PASS 0.02</td><td class="fail">FAIL 0.1</td>' in ghost_row
    table1_row = next(r for r in page.split("<tr>") if r.startswith("<td>calibration: Table 1 d"))
    assert "<td>8</td><td>50</td>" in table1_row
    assert 'class="pass">Verdict: every required check passes; the baseline tsai fails' in page


def test_a_relative_deviation_prints_in_percent_over_the_bins_actually_used():
    # the case: c1 off by 6.144 (614 %), asked over 7.1–62.5 mm, the
    # statistics stopping at 35 mm
    c = comparison(c1=6.144)
    c["c1"].update(r_range_m=[7.1e-3, 62.5e-3], r_used_m=[7.5e-3, 33.1e-3], bins=9)
    rungs = {"model-free": rung_checks(c, matching())}
    checks, must_hold = verdict(run_checks(detection(), DETECTED, None), rungs, ["model-free"], {})
    printed = summary_lines({"checks": checks, "must_hold": must_hold})
    line = next(p for p in printed if "c1_matches_truth" in p)
    assert "614 %" in line and "≤ 5% + 4.4σ per bin" in line
    assert "9 fitted bins at 7.5–33.1 mm" in line and "7.1–62.5 mm asked" in line
    # a ratio stays a ratio
    assert any("1.23" in p for p in summary_lines_with_raw(1.23))
    # and report.html shows the value as the terminal does, beside the same tolerance
    page = "\n".join(_checks_section({"checks": checks}, None))
    c1_row = next(r for r in page.split("<tr>") if r.startswith("<td>stats.c1_matches_truth"))
    assert '<td class="fail">FAIL 614 %</td>' in c1_row


def summary_lines_with_raw(raw: float) -> list[str]:
    rungs = {"model-free": rung_checks(comparison(raw_s2=raw), matching())}
    checks, must_hold = verdict(run_checks(detection(), DETECTED, None), rungs, ["model-free"], {})
    return summary_lines({"checks": checks, "must_hold": must_hold})


def test_the_epsilon_row_names_its_reference_and_its_false_alarm_rate():
    rows = rung_checks(comparison(epsilon=-0.006), matching())
    row = next(r for r in rows if r["id"] == "stats.epsilon_recovered")
    assert row["passed"] and row["value"] == -0.006
    assert "paired" in row["tolerance"] and "exact trajectories" in row["tolerance"]
    assert "0.1 % false alarms" in row["tolerance"]
    c = comparison(epsilon=0.03)  # a 3 % bias against a tolerance of 2 %
    assert "stats.epsilon_recovered" in failed(rung_checks(c, matching()))


def test_a_u_prime_check_is_required_where_the_comparison_has_one():
    c = comparison()
    c["u_prime"] = {
        "relative_to_exact_rung": 0.02,
        "tolerance": 0.013,
        "method_tolerance": 0.01,
        "z": 3.56,
        "paired": True,
        "passed": False,
    }
    assert failed(rung_checks(c, matching())) == ["stats.u_prime_recovered"]
