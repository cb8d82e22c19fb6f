"""Claims: JSON form, and claims fail when what they guard is broken."""

import copy
import dataclasses
import json

import numpy as np
import pytest

import ptv.calibration.model_free as model_free
import ptv.matching.stereo as match
import ptv.stats.pairs as pairs
import validation.claims.rendered_case as rendered_case
from simulator.presets import flow_preset
from simulator.spectra import C_KOLMOGOROV
from validation.claims import CLAIMS, ClaimContext, run_claims
from validation.truth.dt3_bias import dt3_gamma

CALIBRATION = [c.id for c in CLAIMS if c.id.startswith("calib.")]


def test_claim_ids_required_by_the_validation_suite_exist():
    ids = {c.id for c in CLAIMS}
    assert {
        "calib.model_free_beats_tsai_scheimpflug",
        "calib.similar_conventional",
        "calib.planes_7_vs_13",
        "calib.planes_3_vs_13",
        "calib.noise_limited",
        "calib.model_error",
        "calib.sub_pixel",
        "calib.plane_fit_residual",
        "stats.c1_matches_truth",
        "stats.c2_positive",
        "stats.epsilon_recovered",
        "stats.mean_linear_in_dt",
        "stats.raw_s2_biased",
        "stats.dt_subsets",
        "stats.calibration_bias_not_removed",
        "stats.two_thirds_scaling",
        "stats.dt3_negligible",
    } <= ids


def test_json_lists_id_source_value_tolerance_passed(capsys):
    # Only the cheap claims through the public entry point: the full quick run is CI's.
    results = run_claims(
        ClaimContext("quick"), ids=["table3.arithmetic", "stats.epsilon_convention"]
    )
    assert [r.passed for r in results] == [True, True]
    record = results[0].as_dict()
    assert set(record) == {"id", "source", "statement", "value", "tolerance", "passed", "limit"}
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


def test_the_calibration_claims_pass_and_state_where_their_limits_come_from():
    results = run_claims(ClaimContext("quick"), ids=CALIBRATION)
    assert [r.id for r in results if not r.passed] == []
    by_id = {r.id: r for r in results}
    assert "d_noise" in by_id["calib.noise_limited"].tolerance
    assert "σ√(2(1 − p/N))" in by_id["calib.plane_fit_residual"].tolerance


def test_quadratic_plane_maps_break_the_noise_derived_calibration_claims(monkeypatch):
    # The mutation: model-free d 7.5 → 11 µm passed every relative claim.
    monkeypatch.setitem(model_free.calibrate_model_free.__kwdefaults__, "degree", 2)
    failed = {r.id for r in run_claims(ClaimContext("quick"), ids=CALIBRATION) if not r.passed}
    assert {"calib.noise_limited", "calib.model_error", "calib.plane_fit_residual"} <= failed


@pytest.mark.slow
def test_a_three_percent_error_in_the_shared_pair_sums_breaks_the_c1_and_epsilon_claims(
    monkeypatch,
):
    # The estimate and the stack's sample truth share ptv.stats.pairs; the brute-force
    # reference and the ε deficit do not, so the error cannot cancel.
    kernel = pairs._pair_sums

    def biased(*args):
        count, sum_q, sum_q2, sum_r = kernel(*args)
        return count, 1.03 * sum_q, 1.03**2 * sum_q2, sum_r

    monkeypatch.setattr(pairs, "_pair_sums", biased)
    ids = ["stats.c1_matches_truth", "stats.epsilon_recovered", "stats.raw_s2_biased"]
    assert not any(r.passed for r in run_claims(ClaimContext("quick"), ids=ids))


@pytest.fixture(scope="module")
def quick() -> ClaimContext:
    """A quick context whose band-limited run (the costly part) the tests below share."""
    return ClaimContext("quick")


def test_two_thirds_scaling_and_dt3_claims_pass_at_quick_size(quick):
    results = run_claims(quick, ids=["stats.two_thirds_scaling", "stats.dt3_negligible"])
    assert [r.passed for r in results] == [True, True]


def test_the_dissipation_matched_band_has_no_two_thirds_range():
    # Cut at k_N·η = 0.544 (SPECTRA's "k41-band") D_LL is still steep at 20η: slope ≈ 0.79.
    dissipation_matched = (2 / (3 * C_KOLMOGOROV)) ** 0.75
    (result,) = run_claims(
        ClaimContext("quick", band_cutoff=dissipation_matched), ids=["stats.two_thirds_scaling"]
    )
    assert not result.passed and result.value > 2 / 3 + 0.07


def test_a_ten_times_larger_dt3_term_is_not_negligible(quick):
    broken = copy.copy(quick)  # shares the simulated runs already computed
    broken.dt3_coefficient = 10 * quick.dt3_coefficient
    broken.__dict__.pop("dt3_fits", None)  # refit with the larger β (a cached_property)
    (result,) = run_claims(broken, ids=["stats.dt3_negligible"])
    assert not result.passed and result.value > 10  # max |bias| in %, ≈ 15


@pytest.mark.parametrize(
    ("preset", "gamma_over_tau_eta"), [("lem-8hz", 0.155), ("lem-10hz", 0.218), ("lem-12hz", 0.243)]
)
def test_dt3_gamma_of_the_table4_sets_is_that_of_physics_4(preset, gamma_over_tau_eta):
    p = flow_preset(preset)
    assert dt3_gamma(p.dt) / p.parameters.tau_eta == pytest.approx(gamma_over_tau_eta, abs=6e-4)


IMAGE = [c.id for c in CLAIMS if c.id.startswith("image.")]


@pytest.mark.slow
def test_centres_rounded_to_whole_pixels_break_the_detection_claims(monkeypatch):
    # The mutation: rounding every centre changed no claim before the image stack
    # was reached.
    detect = rendered_case.detect_particles

    def rounded(*args, **kwargs):
        found = detect(*args, **kwargs)
        return dataclasses.replace(found, xy=np.round(found.xy))

    monkeypatch.setattr(rendered_case, "detect_particles", rounded)
    failed = {r.id for r in run_claims(ClaimContext("quick"), ids=IMAGE) if not r.passed}
    assert {"image.detection_rms", "image.peak_locking"} <= failed


@pytest.mark.slow
def test_a_ten_micron_bias_of_the_matched_points_breaks_the_matching_claims(monkeypatch):
    candidates = match._pair_candidates

    def shifted(*args):
        i, j, distance, midpoint = candidates(*args)
        return i, j, distance, midpoint + np.array([10e-6, 0.0, 0.0])

    monkeypatch.setattr(match, "_pair_candidates", shifted)
    failed = {r.id for r in run_claims(ClaimContext("quick"), ids=IMAGE) if not r.passed}
    assert failed == {"image.matching_reference", "image.position_bias"}
