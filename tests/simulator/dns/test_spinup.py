"""Spin-up: reproducible noise with the asked spectrum, upsampling, the stationary window
and its energy budget."""

from math import pi

import numpy as np
import pytest

from simulator.dns.diagnostics import energy_spectrum
from simulator.dns.forcing import ConstantPowerForcing
from simulator.dns.grid import Grid, dns_setup
from simulator.dns.solver import NavierStokesSolver
from simulator.dns.spinup import (
    STATIONARY_ENERGY,
    coarse_setup,
    initial_state,
    spin_up,
    stationary_flow,
    stationary_window,
    upsample,
)

GRID = Grid(32, 2 * pi)
EPSILON = 1.0


def forced_solver(grid: Grid = GRID, nu: float = 0.02) -> NavierStokesSolver:
    return NavierStokesSolver(grid, nu=nu, forcing=ConstantPowerForcing(EPSILON))


def test_same_seed_same_bits_and_the_asked_energy_and_shape():
    solver = forced_solver()
    a = initial_state(solver, rng=3)
    b = initial_state(solver, rng=np.random.default_rng(3))
    c = initial_state(solver, rng=4)
    assert np.array_equal(a.velocity_hat, b.velocity_hat)
    assert not np.array_equal(a.velocity_hat, c.velocity_hat)
    expected = STATIONARY_ENERGY * (EPSILON / GRID.k0) ** (2 / 3)
    assert solver.sums(a).energy == pytest.approx(expected, rel=1e-12)
    k, e = energy_spectrum(a.velocity_hat, GRID)
    shape = k**4 * np.exp(-2 * (k / (2 * GRID.k0)) ** 2)
    ratio = e / shape
    assert np.ptp(ratio) <= 1e-12 * ratio.max()  # shell by shell the asked shape
    custom = initial_state(solver, rng=3, energy=0.5, spectrum=lambda k: (k < 3.5).astype(float))
    k, e = energy_spectrum(custom.velocity_hat, GRID)
    assert np.all(e[3:] == 0) and solver.sums(custom).energy == pytest.approx(0.5, rel=1e-12)


def test_initial_state_is_divergence_free():
    state = initial_state(forced_solver(), rng=5)
    kx, ky, kz = GRID.wavenumbers()
    uh = state.velocity_hat
    div = kx[:, None, None] * uh[0] + ky[None, :, None] * uh[1] + kz[None, None, :] * uh[2]
    assert np.abs(div).max() <= 1e-14 * np.sqrt(GRID.k_squared()).max() * np.abs(uh).max()


def test_upsampled_field_is_the_same_function():
    # Zero padding is trigonometric interpolation: on the coarse points (every second
    # fine point) the fine field equals the coarse one to round-off, and energy is kept
    coarse, fine = GRID, Grid(64, GRID.box_side)
    small, big = forced_solver(coarse), forced_solver(fine)
    state = initial_state(small, rng=6)
    up = upsample(state, coarse, fine)
    u_c, u_f = small.velocity(state), big.velocity(up)
    assert np.abs(u_f[:, ::2, ::2, ::2] - u_c).max() <= 1e-13 * np.abs(u_c).max()
    assert big.sums(up).energy == pytest.approx(small.sums(state).energy, rel=1e-13)
    with pytest.raises(ValueError, match="cannot upsample"):
        upsample(state, coarse, Grid(64, 1.0))


def test_coarse_setup_keeps_box_and_resolution():
    setup = dns_setup(1e-6, 0.1, 64)
    small = coarse_setup(setup)
    assert small.grid.n == 32 and small.grid.box_side == setup.grid.box_side
    assert small.grid.kmax * small.eta == pytest.approx(setup.kmax_eta, rel=1e-14)


def test_spin_up_reports_progress_and_records_every_step():
    solver = forced_solver()
    calls = []
    state, history = spin_up(
        solver, initial_state(solver, rng=1), eddy_times=0.3, progress=lambda d, t: calls.append(d)
    )
    assert len(history.times) == len(calls) > 0
    assert calls[-1] == 0.3 and np.all(np.diff(calls) > 0)
    assert state.time == pytest.approx(history.times[-1] + history.steps[-1], rel=1e-14)
    assert np.sum(history.steps / history.eddy_time()) >= 0.3


def test_window_snapshots_fall_exactly_on_the_interval():
    solver = forced_solver()
    state = initial_state(solver, rng=2)
    seen = []
    run = stationary_window(solver, state, snapshots=3, interval=0.02, on_snapshot=seen.append)
    assert run.states == () and len(seen) == 3
    assert np.allclose(np.diff(run.times), 0.02, rtol=1e-13)
    assert [s.time for s in seen] == list(run.times)
    kept = stationary_window(solver, state, snapshots=1, interval=0.01)
    assert len(kept.states) == 1 and kept.history.times[-1] < 0.01


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"snapshots": 0, "interval": 0.1}, "^snapshots"),
        ({"snapshots": 2, "interval": 0.0}, "^interval"),
        ({"snapshots": 2, "interval": float("nan")}, "^interval"),
    ],
)
def test_bad_window_inputs(kwargs, match):
    solver = forced_solver()
    with pytest.raises(ValueError, match=match):
        stationary_window(solver, initial_state(solver, rng=0), **kwargs)


def test_bad_spin_up_inputs():
    solver = forced_solver()
    state = initial_state(solver, rng=0)
    with pytest.raises(ValueError, match=r"^eddy_times"):
        spin_up(solver, state, eddy_times=-1.0)
    free = NavierStokesSolver(GRID, nu=0.02)
    with pytest.raises(ValueError, match="needs a forcing"):
        stationary_window(free, state, snapshots=2, interval=0.1)
    with pytest.raises(ValueError, match=r"^energy is required"):
        initial_state(free, rng=0)
    with pytest.raises(ValueError, match=r"^spacing"):
        stationary_flow(dns_setup(1e-6, 0.1, 32), snapshots=2, spacing=0.5)


@pytest.mark.slow
def test_stationary_flow_at_32_cubed_balances_its_energy_budget():
    # Injection is exactly ε and the nonlinear term conserves energy, so over a window W
    # the mean dissipation is ε − ΔE/W: its error is the energy drift. Energy fluctuates by
    # ~5 % over T_L with E/(ε T_L) ≈ 2.5 (docs/dns.md §5), so 25 T_L bring ΔE/(εW)
    # to ~0.5–1 %; 2 % is the target budget. 32³ at k_max η = 1.5 in SI units.
    setup = dns_setup(1e-6, 0.1, 32)
    _, run = stationary_flow(setup, snapshots=26, spacing=1.0, rng=11)
    p = run.parameters
    assert abs(run.energy_budget - 1.0) <= 0.02
    assert p.kmax_eta == pytest.approx(1.5, rel=0.1)  # η from the measured dissipation
    assert len(run.states) == 26
    e = run.history.energy
    drift = (e[-1] - e[0]) / (run.history.times[-1] - run.history.times[0])
    assert p.epsilon == pytest.approx(p.epsilon_injection - drift, rel=0.01)


def test_stationary_flow_reports_its_progress_up_to_one():
    calls = []
    _, run = stationary_flow(
        dns_setup(1e-6, 0.1, 32), snapshots=1, rng=0, progress=lambda d, t: calls.append(d / t)
    )
    assert len(run.states) == 1 and run.interval > 0
    assert np.all(np.diff(calls) >= 0) and calls[-1] == pytest.approx(1.0, rel=1e-12)
    with pytest.raises(ValueError, match=r"^snapshots"):
        stationary_flow(dns_setup(1e-6, 0.1, 32), snapshots=0)
