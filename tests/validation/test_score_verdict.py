"""synptv score prints a verdict beside each statistic, and says when too few snapshots
leave a failed check within the sampling scatter."""

from validation.commands.score import SCATTER_SE, _statistics_lines


def _statistics(deviation: float, in_se: float, eps: float = 0.01) -> dict:
    return {
        "c1": {
            "max_abs_deviation": deviation,
            "max_deviation_in_se": in_se,
            "tolerance": 0.05,
            "passed": deviation <= 0.05,
        },
        "epsilon": {"relative_to_exact_d_ll": eps, "tolerance": 0.05, "passed": abs(eps) <= 0.05},
    }


def test_a_pass_is_a_pass_with_its_tolerance():
    lines = _statistics_lines(_statistics(0.02, 0.5), snapshots=40)
    assert lines[0] == "c1 within 2 % of the sample truth over the check range (≤ 5 %): PASS"
    assert lines[1].endswith("(≤ 5 %): PASS")
    assert len(lines) == 2


def test_a_failure_within_the_scatter_says_too_few_snapshots():
    lines = _statistics_lines(_statistics(0.111, SCATTER_SE - 0.5), snapshots=2)
    assert lines[0].endswith("FAIL")
    assert lines[2].startswith("too few snapshots (2 per dt)")


def test_a_failure_beyond_the_scatter_is_only_a_failure():
    lines = _statistics_lines(_statistics(0.111, SCATTER_SE + 1, eps=-0.08), snapshots=40)
    assert lines[0].endswith("FAIL") and lines[1].endswith("FAIL")
    assert len(lines) == 2
