"""The status of a mutation's outcome, the kill table and the command line's refusals."""

import pytest

from validation.cli import main
from validation.mutations import mutation
from validation.mutations.report import kill_rate, kill_table
from validation.mutations.runner import Outcome

C2 = mutation("c2-1.5-in-estimator")  # expects stats.epsilon_recovered, stats.epsilon_convention
ROUNDED = mutation("detections-rounded")  # expects image.* claims
REGISTERED = ("stats.epsilon_recovered", "stats.epsilon_convention", "stats.c2_positive")


def outcome(chosen, killed_by):
    return Outcome(chosen, tuple(killed_by), REGISTERED, {}, 1.0)


@pytest.mark.parametrize(
    ("chosen", "killed_by", "status", "ok"),
    [
        (C2, ["stats.epsilon_recovered", "stats.epsilon_convention"], "killed", True),
        (
            C2,
            ["stats.epsilon_recovered", "stats.epsilon_convention", "stats.c2_positive"],
            "killed",
            True,
        ),
        (C2, ["stats.epsilon_recovered"], "partly killed", False),
        (C2, [], "survived", False),
        (ROUNDED, [], "awaiting claims", True),
        (ROUNDED, ["stats.c2_positive"], "killed", True),
    ],
)
def test_the_status_says_whether_the_expected_claims_caught_it(chosen, killed_by, status, ok):
    result = outcome(chosen, killed_by)
    assert (result.status, result.ok) == (status, ok)
    assert result.as_dict()["killed"] == bool(killed_by)


def test_the_kill_table_names_the_killers_and_the_rate():
    outcomes = [
        outcome(C2, ["stats.epsilon_recovered", "stats.epsilon_convention"]),
        outcome(ROUNDED, []),
    ]
    lines = kill_table(outcomes)
    assert kill_rate(outcomes) == (1, 2)
    assert "stats.epsilon_recovered, stats.epsilon_convention" in lines[1]
    assert "image.detection_rms (not registered)" in lines[4]
    assert lines[-1].startswith("1 of 2 mutations killed (50%); 1 waiting")


def test_an_unknown_mutation_is_refused_before_anything_runs(capsys):
    assert main(["claims", "--mutation", "no-such-mutation"]) == 2
    assert "unknown mutation 'no-such-mutation'" in capsys.readouterr().err
