"""The acceleration fitted to positions: exact on polynomials, within its truncation on
flows with known accelerations; the pairs' flux terms against hand-computed values."""

from math import factorial

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from validation.truth.acceleration_fit import (
    acceleration_from_positions,
    fit_derivatives,
    truncation_bound,
    truncation_gain,
)
from validation.truth.pair_flux import pair_flux

#: dns-ci's Δt set, in τ_η, behind the common start.
TIMES = np.array([0.0, 0.04, 0.08, 0.12, 0.17, 0.21])


def _polynomial(coefficients, times, x0):
    """X(τ) = x0 + Σ_n c_n τⁿ/n!, n = 1 …, for P tracers: (T, P, 3)."""
    return x0 + sum(
        c[None] * times[:, None, None] ** (n + 1) / factorial(n + 1)
        for n, c in enumerate(coefficients)
    )


def test_a_polynomial_of_the_fitted_degree_is_recovered_to_round_off():
    rng = np.random.default_rng(1)
    x0 = rng.uniform(-0.05, 0.05, (40, 3))
    v, a, jerk, snap = (rng.normal(0, s, (40, 3)) for s in (5e-3, 8e-3, 3e-2, 1e-1))
    positions = _polynomial([v, a, jerk, snap], TIMES, x0)
    derivatives = fit_derivatives(TIMES, positions, v, terms=3)
    assert derivatives.shape == (3, 40, 3)
    np.testing.assert_allclose(derivatives[0], a, rtol=0, atol=1e-9 * np.abs(a).max())
    np.testing.assert_allclose(derivatives[1], jerk, rtol=0, atol=1e-8 * np.abs(jerk).max())
    np.testing.assert_allclose(derivatives[2], snap, rtol=0, atol=1e-7 * np.abs(snap).max())


@pytest.mark.parametrize("terms", [1, 2, 3, 4])
def test_the_error_of_a_pure_next_order_term_is_the_truncation_gain_times_it(terms):
    """X = x0 + vτ + X⁽ᵖ⁺²⁾τᵖ⁺²/(p+2)!: the fit's a (exactly 0) reads g_p X⁽ᵖ⁺²⁾."""
    rng = np.random.default_rng(terms)
    x0, v, top = (rng.normal(0, 1, (5, 3)) for _ in range(3))
    positions = (
        x0
        + v * TIMES[:, None, None]
        + top * TIMES[:, None, None] ** (terms + 2) / (factorial(terms + 2))
    )
    fitted = acceleration_from_positions(TIMES, positions, v, terms=terms)
    # round-off: about 10³ (the fit's condition) × 10⁻¹⁶ × |X| ≈ 1 over τ_K² ≈ 0.04
    np.testing.assert_allclose(fitted, truncation_gain(TIMES, terms) * top, rtol=1e-6, atol=1e-11)


def test_shapes_with_snapshots_and_bad_input_refused():
    positions = np.zeros((4, len(TIMES), 7, 3))
    assert fit_derivatives(TIMES, positions, np.zeros((4, 7, 3)), terms=2).shape == (2, 4, 7, 3)
    with pytest.raises(ValueError, match="times must start at 0"):
        fit_derivatives(TIMES[1:], positions[:, 1:], np.zeros((4, 7, 3)))
    with pytest.raises(ValueError, match="terms must be in 1"):
        fit_derivatives(TIMES, positions, np.zeros((4, 7, 3)), terms=6)
    with pytest.raises(ValueError, match="velocity must have shape"):
        fit_derivatives(TIMES, positions, np.zeros((7, 3)))
    with pytest.raises(ValueError, match="it needs that many"):
        truncation_bound(TIMES, positions, np.zeros((4, 7, 3)), terms=5)


@pytest.mark.parametrize("omega", [1.0, 3.0])
@pytest.mark.parametrize("terms", [1, 2, 3])
def test_solid_body_rotation_errs_by_its_truncation(omega, terms):
    """X rotates at Ω about z: a⁽ᵖ⁾ has rms Ωᵖ a_rms, so the fit errs by |g_p|Ωᵖ of a_rms
    to leading order; the next orders add a fraction O(Ωτ_K) of that (under 5 % at
    Ωτ_K = 0.63), and the bound measured from the data finds the same."""
    rng = np.random.default_rng(0)
    x0 = rng.normal(size=(50, 3))
    c, s = np.cos(omega * TIMES)[:, None], np.sin(omega * TIMES)[:, None]
    positions = np.stack(
        [
            c * x0[:, 0] - s * x0[:, 1],
            s * x0[:, 0] + c * x0[:, 1],
            np.broadcast_to(x0[:, 2], (len(TIMES), len(x0))),
        ],
        axis=-1,
    )
    velocity = omega * np.stack([-x0[:, 1], x0[:, 0], 0 * x0[:, 2]], axis=-1)
    exact = -(omega**2) * np.stack([x0[:, 0], x0[:, 1], 0 * x0[:, 2]], axis=-1)
    fitted = acceleration_from_positions(TIMES, positions, velocity, terms=terms)
    error = np.sqrt(np.mean((fitted - exact) ** 2) / np.mean(exact**2))
    predicted = abs(truncation_gain(TIMES, terms)) * omega**terms
    assert error == pytest.approx(predicted, rel=0.05)
    bound = truncation_bound(TIMES, positions, velocity, terms=terms)
    assert bound.relative == pytest.approx(predicted, rel=0.1)
    assert bound.next_order_rms / bound.acceleration_rms == pytest.approx(error, rel=0.1)


def _taylor_green(_, x):
    """The steady cellular flow u = (sin x cos y, −cos x sin y, 0) (m, s units): its
    Lagrangian acceleration is (u·∇)u = (½ sin 2x, ½ sin 2y, 0)."""
    x = x.reshape(-1, 3)
    u = np.stack([np.sin(x[:, 0]) * np.cos(x[:, 1]), -np.cos(x[:, 0]) * np.sin(x[:, 1])], -1)
    return np.column_stack([u, np.zeros(len(x))]).ravel()


@pytest.mark.parametrize("scale", [1.0, 2.5])
def test_a_steady_cellular_flow_is_within_the_measured_truncation_bound(scale):
    """Trajectories of a steady 2-D cell, integrated by DOP853 to 10⁻¹³, times τ_K of 0.21
    and 0.53 of the cell's turnover unit: the fitted a lies within the truncation the same
    data measure (|g_3|·rms(a⁽³⁾), to 25 %: the next orders), which is not vacuous (within
    a factor 2 of the error)."""
    rng = np.random.default_rng(2)
    x0 = rng.uniform(0, 2 * np.pi, (60, 3))
    times = TIMES * scale
    path = solve_ivp(
        _taylor_green,
        (0, times[-1]),
        x0.ravel(),
        method="DOP853",
        t_eval=times,
        rtol=1e-13,
        atol=1e-13,
    )
    positions = path.y.T.reshape(len(times), 60, 3)
    velocity = _taylor_green(0, x0).reshape(60, 3)
    exact = np.column_stack([0.5 * np.sin(2 * x0[:, 0]), 0.5 * np.sin(2 * x0[:, 1]), 0 * x0[:, 2]])
    fitted = acceleration_from_positions(times, positions, velocity)
    error = np.sqrt(np.mean((fitted - exact) ** 2))
    bound = truncation_bound(times, positions, velocity)
    assert error <= 1.25 * bound.error_rms
    assert bound.error_rms <= 2.0 * error
    assert bound.acceleration_rms == pytest.approx(np.sqrt(np.mean(exact**2)), rel=1e-3)


def test_pair_flux_of_three_tracers_by_hand():
    x = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 3.0, 0.0]])
    u = np.array([[0.0, 0.0, 0.0], [2.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    a = np.array([[0.0, 0.0, 0.0], [3.0, 5.0, 0.0], [1.0, 2.0, 7.0]])
    flux = pair_flux(
        x,
        u,
        a,
        np.array([0.5, 2.0, 3.5]),
        field_r=np.array([0.1, 10.0]),
        field_du_da=np.array([-1.0, -1.0]),
        field_dul_dal=np.array([0.0, 2.0 * np.log(100.0)]),
    )
    # bin 0: pair (0, 1), r = 1: δu = (2, 1, 0), δa = (3, 5, 0), e = x̂.
    # bin 1: pairs (0, 2) at r = 3 (e = ŷ) and (1, 2) at √10 ≈ 3.16 (e = (−1, 3, 0)/√10).
    np.testing.assert_array_equal(flux.count, [1, 2])
    np.testing.assert_allclose(flux.r, [1.0, (3.0 + np.sqrt(10.0)) / 2])
    d12 = np.array([-1.0, 3.0, 0.0]) / np.sqrt(10.0)
    du12, da12 = np.array([-2.0, -1.0, 1.0]), np.array([-2.0, -3.0, 7.0])
    np.testing.assert_allclose(flux.du_da, [11.0, (7.0 + du12 @ da12) / 2])
    np.testing.assert_allclose(flux.dul_dal, [6.0, (0.0 + (du12 @ d12) * (da12 @ d12)) / 2])
    np.testing.assert_allclose(flux.du2, [5.0, (1.0 + du12 @ du12) / 2])
    np.testing.assert_allclose(flux.field_du_da, [-1.0, -1.0])
    # linear in log r from 0 at 0.1 to 2 ln 100 at 10: the value is 2 ln(r/0.1) there
    expected = [2 * np.log(10.0), (2 * np.log(30.0) + 2 * np.log(10 * np.sqrt(10.0))) / 2]
    np.testing.assert_allclose(flux.field_dul_dal, expected)


def test_pair_flux_of_a_linear_field_is_its_isotropic_average():
    """u = Gx and a = Ax: δu·δa = dᵀGᵀAd, whose average over pair directions at r is
    r² tr(GᵀA)/3 (here over many random tracers, to 3 %)."""
    rng = np.random.default_rng(3)
    x = rng.uniform(0, 1, (4000, 3))
    g, acc = rng.normal(size=(3, 3)), rng.normal(size=(3, 3))
    flux = pair_flux(x, x @ g.T, x @ acc.T, np.array([0.05, 0.06]))
    r2 = np.mean(flux.r) ** 2
    assert flux.count[0] > 1000
    assert flux.du_da[0] == pytest.approx(r2 * np.trace(g.T @ acc) / 3, rel=0.03)
    assert np.isnan(flux.field_du_da).all()


def test_pair_flux_refuses_bad_input():
    x = np.zeros((3, 3))
    with pytest.raises(ValueError, match="share shape"):
        pair_flux(x, np.zeros((2, 3)), x, np.array([0.1, 0.2]))
    with pytest.raises(ValueError, match="edges"):
        pair_flux(x, x, x, np.array([0.2, 0.1]))


@pytest.mark.slow
def test_tracers_of_a_32_cubed_dns_accelerate_as_the_solver_says():
    """Tracers co-integrated with a stationary 32³ DNS over dns-ci's Δt set: the fit
    meets the solver's acceleration at the tracers (``truth_at``) within its truncation
    bound plus the spline's gradient floor (:func:`interpolation_error`, docs/dns.md §13);
    the solver's acceleration with the gradient transposed lies far outside."""
    import simulator.dns.tracers as tracers
    from simulator.dns.grid import dns_setup
    from simulator.dns.spinup import stationary_flow
    from validation.mutations import mutation
    from validation.run.dns_checks import interpolation_error

    nu, epsilon = 1e-6, 1e-5
    setup = dns_setup(nu, epsilon, 32)
    states = []
    solver, _ = stationary_flow(setup, snapshots=1, rng=0, on_snapshot=states.append)
    times = TIMES * np.sqrt(nu / epsilon)
    side = setup.grid.box_side
    x0 = np.random.default_rng(4).uniform(0, side, (1000, 3))
    truth, _ = tracers.follow_tracers(solver, states[0], x0, times)
    velocity = truth.velocity[0]
    fitted = acceleration_from_positions(times, truth.positions, velocity)
    bound = truncation_bound(times, truth.positions, velocity)
    u_rms = float(np.sqrt(np.mean(velocity**2)))
    allowed = bound.error_rms + interpolation_error(u_rms, epsilon, nu)
    error = float(np.sqrt(np.mean((fitted - truth.acceleration[0]) ** 2)))
    print(f"fit − solver {error:.3g}, allowed {allowed:.3g}, truncation {bound.error_rms:.3g} m/s²")
    assert error <= allowed
    assert bound.relative < 5e-3
    with mutation("dns-acceleration-gradient-transposed").applied():  # looked up when patched
        _, transposed = tracers.truth_at(solver, states[0], truth.positions[0])
    assert np.sqrt(np.mean((fitted - transposed) ** 2)) > 10 * allowed
