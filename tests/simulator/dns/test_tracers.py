"""Tracers co-integrated with the DNS, against trajectories of the exact Taylor–Green
solution integrated independently (scipy's adaptive Runge–Kutta on the closed form)."""

from math import pi

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from simulator.dns.grid import Grid
from simulator.dns.solver import NavierStokesSolver
from simulator.dns.tracers import follow_tracers, truth_at

GRID = Grid(32, 2 * pi)
NU, K, A = 0.05, 2.0, 1.0


def tg_velocity(x: np.ndarray, t: float) -> np.ndarray:
    """The decaying 2-D Taylor–Green vortex in the (x, y) plane, (P, 3)."""
    decay = A * np.exp(-2 * NU * K**2 * t)
    u = np.zeros_like(x)
    u[:, 0] = decay * np.sin(K * x[:, 0]) * np.cos(K * x[:, 1])
    u[:, 1] = -decay * np.cos(K * x[:, 0]) * np.sin(K * x[:, 1])
    return u


def tg_acceleration(x: np.ndarray, t: float) -> np.ndarray:
    """∂u/∂t + (u·∇)u of the vortex, from its closed form, (P, 3)."""
    u = tg_velocity(x, t)
    c, s = np.cos(K * x), np.sin(K * x)
    decay = A * np.exp(-2 * NU * K**2 * t)
    dudx = decay * K * c[:, 0] * c[:, 1]
    dudy = -decay * K * s[:, 0] * s[:, 1]
    dvdx = decay * K * s[:, 0] * s[:, 1]
    dvdy = -decay * K * c[:, 0] * c[:, 1]
    a = -2 * NU * K**2 * u
    a[:, 0] += u[:, 0] * dudx + u[:, 1] * dudy
    a[:, 1] += u[:, 0] * dvdx + u[:, 1] * dvdy
    return a


def exact_paths(x0: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Trajectories by solve_ivp on the closed form, (T, P, 3), to 1e-12."""

    def rhs(t, y):
        return tg_velocity(y.reshape(-1, 3), t).ravel()

    sol = solve_ivp(rhs, (0, times[-1]), x0.ravel(), t_eval=times, rtol=1e-12, atol=1e-12)
    return sol.y.T.reshape(len(times), -1, 3)


@pytest.fixture(scope="module")
def followed():
    solver = NavierStokesSolver(GRID, nu=NU)
    x = GRID.coordinates()
    xyz = np.meshgrid(x, x, x, indexing="ij")
    u0 = np.zeros((3, *GRID.shape))
    u0[0] = A * np.sin(K * xyz[0]) * np.cos(K * xyz[1])
    u0[1] = -A * np.cos(K * xyz[0]) * np.sin(K * xyz[1])
    state = solver.state(u0)
    rng = np.random.default_rng(3)
    # Anywhere in space: the box tiles it (some points several boxes away).
    x0 = rng.uniform(-3 * GRID.box_side, 4 * GRID.box_side, (200, 3))
    times = np.array([0.0, 0.05, 0.1, 0.3, 0.7])
    truth, end = follow_tracers(solver, state, x0, times)
    return solver, x0, times, truth, end


def test_tracers_follow_the_exact_trajectories(followed):
    # Over 0.7 time units (≈ 1.4 turnovers of the vortex, 1/(A K)) the RK4 error of a
    # CFL step h ≈ 0.12 is ~h⁴ per unit time ≈ 2e-4 of the vortex size; the quintic
    # spline adds ~1e-5 of u. A wrong stage weight or stage field errs by O(h) ≈ 0.1.
    _, x0, times, truth, _ = followed
    exact = exact_paths(x0, times)
    error = np.abs(truth.positions - exact).max()
    assert error < 1e-3 * (1 / K)


def test_truth_is_the_flow_at_the_tracers(followed):
    # The field's own velocity and acceleration at the tracers' positions: interpolation
    # of a single Fourier mode per axis (k = 2 on 32 points, θ = 0.39) by the quintic
    # spline errs by ~θ⁶ ≈ 4e-3 of the field at most, times the mode's small weight.
    solver, _, times, truth, end = followed
    for f, t in enumerate(times):
        x = truth.positions[f]
        assert np.abs(truth.velocity[f] - tg_velocity(x, t)).max() < 1e-3 * A
        scale = A**2 * K
        assert np.abs(truth.acceleration[f] - tg_acceleration(x, t)).max() < 1e-3 * scale
    assert end.time == pytest.approx(times[-1], rel=1e-14)
    u, a = truth_at(solver, end, truth.positions[-1])
    assert np.array_equal(u, truth.velocity[-1]) and np.array_equal(a, truth.acceleration[-1])


def test_bad_times_and_positions_are_refused(followed):
    solver, x0, _, _, end = followed
    with pytest.raises(ValueError, match="times"):
        follow_tracers(solver, end, x0, np.array([0.1, 0.2]))
    with pytest.raises(ValueError, match="positions"):
        follow_tracers(solver, end, np.full((2, 3), np.nan), np.array([0.0, 0.1]))
