"""synptv score prints a verdict beside each statistic, judged against the true
positions of the same snapshots, and says when the snapshots are too few for a verdict
with any power."""

from validation.commands.score import MIN_SNAPSHOTS_FOR_VERDICT, _statistics_lines


def _statistics(deviation: float, *, eps: float = 0.004, effective: float = 40.0) -> dict:
    return {
        "c1": {
            "max_abs_deviation": deviation,
            "tolerance": 0.05,
            "z": 4.4,
            "passed": deviation <= 0.05,
        },
        "epsilon": {
            "relative_to_exact_rung": eps,
            "tolerance": 0.02,
            "paired": True,
            "passed": abs(eps) <= 0.02,
        },
        "effective_snapshots": effective,
    }


def test_a_pass_is_a_pass_with_its_tolerance():
    lines = _statistics_lines(_statistics(0.02), snapshots=40)
    assert lines[0] == (
        "c1 within 2 % of the sample truth over the check range (≤ 5 % + 4.4σ per bin): PASS"
    )
    assert lines[1] == (
        "plateau epsilon +0.4 % from the true positions of the same snapshots (≤ 2 %, paired): PASS"
    )
    assert len(lines) == 2


def test_a_few_snapshots_say_that_they_cannot_judge():
    lines = _statistics_lines(_statistics(0.062, effective=4.0), snapshots=4)
    assert lines[-1].startswith("too few snapshots for a verdict with power: 4 per dt")
    assert f"at least {MIN_SNAPSHOTS_FOR_VERDICT}" in lines[-1]


def test_a_failure_with_enough_snapshots_is_only_a_failure():
    lines = _statistics_lines(_statistics(0.111, eps=-0.08), snapshots=40)
    assert lines[0].endswith("FAIL") and lines[1].endswith("FAIL")
    assert len(lines) == 2
