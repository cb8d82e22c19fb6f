"""The checks of a run judge the method against its own sample: ε and u′ against the
exact trajectories of the same snapshots with the paired error, every tolerance at a
stated false-alarm rate."""

import numpy as np
import pytest
from scipy.stats import norm, t

from validation.run.checks import EPSILON_METHOD, U_PRIME_METHOD, compare_variant
from validation.score.tolerances import false_alarm_z, paired_ratio, pairs_with, snapshot_dof

R = 400
EPS = 0.13


def _summary(eps_reps: np.ndarray, *, up=0.187, up_reps=None, ids=range(40), effective=40.0):
    """A rung's summary.json with the fields the ε and u′ checks read."""
    up_reps = np.full(R, up) if up_reps is None else up_reps
    bins = 4
    return {
        "epsilon": {
            "plateau": {"epsilon": float(np.mean(eps_reps)), "se_epsilon": float(np.std(eps_reps))}
        },
        "u_prime": {"value": up, "se": 1e-4, "se_snapshots": float(np.std(up_reps))},
        "bootstrap": {
            "replicates": R,
            "seed": 0,
            "block": 1,
            "snapshot_ids": [list(ids)],
            "correlation": {"effective_snapshots": effective},
            "epsilon_plateau": list(eps_reps),
            "u_prime": list(up_reps),
        },
        "structure_function": {
            "r": [3e-3, 6e-3, 1.2e-2, 2.4e-2],
            "s2": [0.05, 0.08, 0.12, 0.19],
            "se_s2": [0.001] * bins,
            "noise": [1e-9] * bins,
            "se_noise": [1e-10] * bins,
            "fitted": [True] * bins,
            "raw_s2": [[0.06, 0.09, 0.13, 0.2]] * 2,
        },
        "statistics_dt": [1e-4, 2e-4],
        "mean_displacement": {
            "offset": [0.0] * 3,
            "se_offset_scaled": [1e-6] * 3,
            "velocity": [0.0] * 3,
            "offset_test": {"statistic": 1.0, "limit": 16.0},
        },
        "subsets": {},
    }


TRUTH = {
    "s2_sample": [0.05, 0.08, 0.12, 0.19],
    "epsilon_exact_d_ll": EPS * 1.03,  # the sample 3 % off the ensemble
    "epsilon_sample_truth": EPS,
    "epsilon_input": 0.17,
    "u_rms_sample": 0.1875,
    "parameters": {"eta": 5e-5},
}


def _compare(summary, exact):
    return compare_variant(summary, TRUTH, check_range=(2e-3, 3e-2), noise=None, exact=exact)


def _sample(rng, scatter=0.013):
    """Bootstrap replicates of the exact rung's plateau ε: 1.3 % from the sample."""
    return EPS * (1 + scatter * rng.standard_normal(R))


def test_a_right_method_on_a_sample_off_the_ensemble_passes_and_says_so():
    """The exact trajectories' ε is 3 % (2.3 of its standard errors) below the
    ensemble's; the PTV adds 0.2 % ± 0.3 % to it: ε passes, the sample is reported."""
    rng = np.random.default_rng(0)
    sampled = _sample(rng)
    ptv = sampled * (1.002 + 0.003 * rng.standard_normal(R))
    got = _compare(_summary(ptv), _summary(sampled))["epsilon"]
    assert got["paired"] and got["passed"]
    assert got["relative_to_exact_rung"] == pytest.approx(np.mean(ptv) / np.mean(sampled) - 1)
    assert got["se_relative"] == pytest.approx(0.003, rel=0.15)
    off = got["sample_off_ensemble"]
    assert off["relative"] == pytest.approx(1 / 1.03 - 1, abs=2e-3)
    assert -3 < off["in_se"] < -2


def test_a_three_percent_bias_fails_where_the_ensemble_comparison_would_pass_it():
    rng = np.random.default_rng(1)
    sampled = _sample(rng)
    biased = sampled * (1.03 + 0.003 * rng.standard_normal(R))
    got = _compare(_summary(biased), _summary(sampled))
    assert not got["epsilon"]["passed"]
    assert got["epsilon"]["tolerance"] == pytest.approx(
        EPSILON_METHOD + got["epsilon"]["z"] * got["epsilon"]["se_relative"]
    )
    # Against the ensemble, with the sample's own 1.3 % error, the same bias hides.
    assert abs(got["epsilon"]["relative_to_exact_d_ll"]) < 0.05


def test_unpaired_snapshots_fall_back_to_both_errors_in_quadrature():
    rng = np.random.default_rng(2)
    sampled = _sample(rng)
    ptv = sampled * 1.002
    other = _summary(ptv, ids=range(1, 41))  # another set of snapshots
    got = _compare(other, _summary(sampled))["epsilon"]
    assert not got["paired"]
    assert got["se_relative"] == pytest.approx(np.hypot(0.013, 0.013), rel=0.15)


def test_u_prime_is_judged_against_the_exact_trajectories_paired():
    rng = np.random.default_rng(3)
    base = 0.187 * (1 + 0.01 * rng.standard_normal(R))
    exact = _summary(_sample(rng), up=float(np.mean(base)), up_reps=base)
    good = _summary(_sample(rng), up=float(np.mean(base)) * 1.004, up_reps=base * 1.004)
    bad = _summary(_sample(rng), up=float(np.mean(base)) * 1.03, up_reps=base * 1.03)
    assert _compare(good, exact)["u_prime"]["passed"]
    got = _compare(bad, exact)["u_prime"]
    assert not got["passed"] and got["method_tolerance"] == U_PRIME_METHOD
    assert got["se_relative"] < 1e-9  # perfectly paired


def test_without_the_exact_rung_epsilon_is_judged_against_the_ensemble_with_the_sample_error():
    rng = np.random.default_rng(4)
    got = _compare(_summary(_sample(rng)), None)["epsilon"]
    assert got["against"] == "the estimator on the exact D_LL"
    assert got["passed"]  # 3 % off, within 5 % + 3.56 × 1.3 %


def test_the_false_alarm_quantile_is_students_with_the_effective_snapshots():
    assert false_alarm_z(None) == pytest.approx(norm.ppf(1 - 0.0005))
    assert false_alarm_z(39.0) == pytest.approx(t.ppf(1 - 0.0005, 39))
    # Ten bins that must all hold share the rate: each at 0.01 %.
    assert false_alarm_z(None, tests=10) == pytest.approx(norm.ppf(1 - 0.00005))
    # Four snapshots: an error from them is worth three degrees of freedom.
    assert false_alarm_z(3.0) == pytest.approx(12.92, rel=1e-3)


def test_the_degrees_of_freedom_are_the_fewest_effective_snapshots_less_one():
    a, b = _summary(np.ones(R), effective=40.0), _summary(np.ones(R), effective=8.7)
    assert snapshot_dof(a, b) == pytest.approx(7.7)
    assert snapshot_dof(None) is None
    assert pairs_with(a, b) and not pairs_with(a, _summary(np.ones(R), ids=range(3)))


def test_a_paired_ratio_without_replicates_adds_the_errors_in_quadrature():
    ratio, se, paired = paired_ratio(1.02, 0.01, None, 1.0, 0.01, None)
    assert ratio == pytest.approx(0.02) and not paired
    assert se == pytest.approx(1.02 * np.hypot(0.01 / 1.02, 0.01))
