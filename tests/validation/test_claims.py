"""Claims: JSON form, and claims fail when what they guard is broken."""

import json

from validation.claims import CLAIMS, ClaimContext, run_claims


def test_claim_ids_required_by_the_validation_suite_exist():
    ids = {c.id for c in CLAIMS}
    assert {
        "calib.model_free_beats_tsai_scheimpflug",
        "calib.similar_conventional",
        "calib.planes_7_vs_13",
        "calib.planes_3_vs_13",
        "stats.c1_matches_truth",
        "stats.c2_positive",
        "stats.epsilon_recovered",
        "stats.mean_linear_in_dt",
        "stats.raw_s2_biased",
        "stats.dt_subsets",
        "stats.calibration_bias_not_removed",
    } <= ids


def test_json_lists_id_source_value_tolerance_passed(capsys):
    # Only the cheap claims through the public entry point: the full quick run is CI's.
    results = run_claims(
        ClaimContext("quick"), ids=["table3.arithmetic", "stats.epsilon_convention"]
    )
    assert [r.passed for r in results] == [True, True]
    record = results[0].as_dict()
    assert set(record) == {"id", "source", "statement", "value", "tolerance", "passed"}
    json.dumps(record, allow_nan=False)


def test_a_wrong_c2_breaks_the_estimator_convention_claim():
    (result,) = run_claims(
        ClaimContext("quick", kolmogorov_c2=2.1), ids=["stats.epsilon_convention"]
    )
    assert not result.passed


def test_switching_refraction_off_breaks_the_scheimpflug_claim():
    # Without windows a Scheimpflug pinhole is nearly what Tsai models: the gap closes.
    (result,) = run_claims(
        ClaimContext("quick", refraction=False), ids=["calib.model_free_beats_tsai_scheimpflug"]
    )
    assert not result.passed and result.value < 3
