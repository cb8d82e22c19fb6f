"""The tracers' flux check of a DNS run (dns.tracer_flux): its pass/fail logic on
synthetic inputs, and the whole check on tracers of a linear flow."""

from types import SimpleNamespace

import numpy as np
import pytest
from scipy.linalg import expm

from validation.run import dns_checks
from validation.run.verdict import dns_rows
from validation.score.tolerances import false_alarm_z

EPSILON = 1e-5
#: The honest flux at 10η on dns-ci, m²/s³.
FLUX = -1.2 * EPSILON


def _series(rng, m=20, bins=5, noise=0.05 * EPSILON, offset=0.0, rho=0.0):
    """Per-snapshot field values and tracer values = field + noise (AR(1) of lag-one
    correlation rho) + offset, shape (m, bins) each, m²/s³."""
    field = FLUX + rng.normal(0, 0.1 * EPSILON, (m, bins))
    white = rng.normal(0, noise, (m, bins))
    error = np.empty_like(white)
    error[0] = white[0]
    for i in range(1, m):
        error[i] = rho * error[i - 1] + np.sqrt(1 - rho**2) * white[i]
    return field + error + offset, field


def _compare(tracers, field, *, truncation=0.0, interpolation=0.0, seed=0):
    return dns_checks.flux_comparison(
        tracers,
        field,
        du2=np.full(tracers.shape, 1e-5),
        truncation_rms=truncation,
        interpolation_rms=interpolation,
        epsilon=EPSILON,
        seed=seed,
    )


def test_an_honest_sample_passes_and_a_null_field_fails():
    rng = np.random.default_rng(0)
    tracers, field = _series(rng)
    honest = _compare(tracers, field)
    assert honest["passed"]
    assert honest["field"] == pytest.approx(0.6, abs=0.02)
    broken = _compare(tracers, np.zeros_like(field))  # the transposed gradient's field
    assert not broken["passed"]
    assert broken["difference_over_2eps"] == pytest.approx(-0.6, abs=0.05)


def test_the_tolerance_is_the_allowance_plus_the_false_alarm_quantile_times_the_error():
    rng = np.random.default_rng(1)
    tracers, field = _series(rng)
    out = _compare(tracers, field, truncation=1e-5, interpolation=2e-5)
    assert out["z"] == pytest.approx(false_alarm_z(out["dof"]))
    assert out["dof"] == pytest.approx(out["correlation"]["effective_snapshots"] - 1)
    per_error = 2 * np.sqrt(3) * np.sqrt(1e-5)
    assert out["allowance"]["truncation"] == pytest.approx(per_error * 1e-5)
    assert out["allowance"]["interpolation"] == pytest.approx(per_error * 2e-5)
    assert out["allowance"]["directions"] == pytest.approx(0.02 * abs(np.mean(field[:, 2])))
    total = sum(out["allowance"].values()) + out["z"] * out["se"]
    assert out["tolerance"] == pytest.approx(total)
    # the standard error is that of a mean of 20 independent differences
    assert out["se"] == pytest.approx(
        np.std(tracers[:, 2] - field[:, 2], ddof=1) / np.sqrt(20), rel=0.2
    )
    # an offset just inside the tolerance passes, just outside fails
    shift = out["tolerance"] - out["difference"]
    inside = _compare(tracers + 0.9 * shift, field, truncation=1e-5, interpolation=2e-5)
    outside = _compare(tracers + 1.1 * shift, field, truncation=1e-5, interpolation=2e-5)
    assert inside["passed"] and not outside["passed"]


def test_correlated_snapshots_count_as_fewer():
    rng = np.random.default_rng(2)
    tracers, field = _series(rng, m=40, rho=0.8)
    out = _compare(tracers, field)
    assert out["correlation"]["effective_snapshots"] < 20
    assert out["block"] > 1


def test_honest_samples_fail_rarely():
    """At 0.1 % false alarms 200 honest samples should all pass (a few failures would
    mean the bootstrap or the quantile is off)."""
    rng = np.random.default_rng(3)
    failures = 0
    for trial in range(200):
        tracers, field = _series(rng)
        failures += not _compare(tracers, field, seed=trial)["passed"]
    assert failures <= 2


def test_non_finite_values_fail():
    rng = np.random.default_rng(4)
    tracers, field = _series(rng)
    tracers[3, 2] = np.nan
    assert not _compare(tracers, field)["passed"]


def _linear_flow(m=3, n=3000, seed=5):
    """Tracers of the steady linear flow u = Gx (X(t) = e^{Gt}x0, a = G²x) over dns-ci's
    Δt set: times (T,), positions (m, T, n, 3), velocity (m, n, 3), and the exact
    ⟨δu·δa⟩(r) = r² tr(GᵀG²)/3 of isotropically oriented pairs."""
    rng = np.random.default_rng(seed)
    g = rng.normal(0, 1.0, (3, 3))
    g -= np.trace(g) / 3 * np.eye(3)
    times = np.array([0.0, 0.04, 0.08, 0.12, 0.17, 0.21])
    x0 = rng.uniform(0, 0.02, (m, n, 3))
    positions = np.stack([x0 @ expm(g * t).T for t in times], axis=1)
    velocity = x0 @ g.T
    coefficient = np.trace(g.T @ g @ g) / 3
    return times, positions, velocity, coefficient


def test_the_whole_check_on_tracers_of_a_linear_flow():
    times, positions, velocity, coefficient = _linear_flow()
    eta = 2e-4  # 10η = 2 mm inside the 20 mm cube
    r = np.geomspace(1e-4, 1e-2, 24)
    exact = np.tile(coefficient * r**2, (3, 1))
    field = {"r": r, "du_da": exact, "dul_dal": exact, "epsilon": EPSILON, "nu": 1e-6}
    honest = dns_checks.tracer_flux(field, times, positions, velocity, eta=eta, seed=0)
    assert honest["r_over_eta"] == pytest.approx(10, rel=0.05)  # pairs ∝ r² in the bin
    assert honest["acceleration_fit"]["relative"] < 1e-3
    assert abs(honest["difference"]) < 0.03 * abs(honest["field"]) * 2 * EPSILON
    assert honest["passed"]
    broken = dns_checks.tracer_flux(
        {**field, "du_da": 0 * exact}, times, positions, velocity, eta=eta, seed=0
    )
    assert not broken["passed"]
    with pytest.raises(ValueError, match="snapshots"):
        dns_checks.tracer_flux(field, times, positions[:2], velocity[:2], eta=eta, seed=0)


def test_no_check_without_a_shared_first_frame_and_the_verdict_row():
    truth = SimpleNamespace(shared_first_frame=False, dt=np.arange(1, 6) * 0.01)
    assert dns_checks.tracer_flux_check({}, truth, eta=1e-3, seed=0) is None
    rng = np.random.default_rng(6)
    flux = {**_compare(*_series(rng)), "r_over_eta": 10.3}
    dns = {
        "energy_budget": {"dissipation_over_injection": 1.0, "tolerance": 0.02, "passed": True},
        "karman_howarth": {"max_residual_in_se": 1.0, "tolerance_se": 3.0, "passed": True},
        "dt3_bias": None,
        "tracer_flux": flux,
    }
    rows = {row["id"]: row for row in dns_rows(dns)}
    assert rows["dns.tracer_flux"]["passed"] == flux["passed"]
    assert "informative" not in rows["dns.tracer_flux"]
    assert rows["dns.tracer_flux"]["value"] == flux["difference_over_2eps"]
