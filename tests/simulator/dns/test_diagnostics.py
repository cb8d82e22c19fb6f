"""Diagnostics: spectrum, energy, dissipation and the measured scales against fields whose
values are known in closed form or computed independently on the grid."""

from math import pi, sqrt

import numpy as np
import pytest

from simulator.dns.diagnostics import energy_spectrum, measured_parameters, spectral_sums
from simulator.dns.forcing import ConstantPowerForcing
from simulator.dns.grid import Grid
from simulator.dns.solver import NavierStokesSolver

GRID = Grid(32, 0.2)
NU = 1.0e-4


def shear_wave(grid: Grid, n: int, amplitude: float) -> np.ndarray:
    """u = (A sin(n k₀ y), 0, 0): one shell, n; energy A²/4, dissipation ν A² (n k₀)²/2."""
    x = grid.coordinates()
    u = np.zeros((3, *grid.shape))
    u[0] = amplitude * np.sin(n * grid.k0 * x)[None, :, None]
    return u


def test_single_wave_lands_in_its_shell_with_its_energy():
    solver = NavierStokesSolver(GRID, nu=NU)
    state = solver.state(shear_wave(GRID, 5, 0.3))
    k, e = energy_spectrum(state.velocity_hat, GRID)
    assert k[4] == pytest.approx(5 * GRID.k0)
    assert e[4] * GRID.k0 == pytest.approx(0.3**2 / 4, rel=1e-13)
    assert np.abs(np.delete(e, 4)).max() <= 1e-15 * e[4]
    sums = spectral_sums(state.velocity_hat, GRID, NU)
    assert sums.energy == pytest.approx(0.3**2 / 4, rel=1e-13)
    assert sums.dissipation == pytest.approx(NU * 0.3**2 * (5 * GRID.k0) ** 2 / 2, rel=1e-13)
    assert sums.inverse_k == pytest.approx(0.3**2 / 4 / (5 * GRID.k0), rel=1e-13)


def test_sums_agree_with_grid_averages_of_a_random_field():
    # ½⟨|u|²⟩ and 2ν⟨s_ij s_ij⟩ averaged over the grid points (Parseval: exact for a
    # resolved field, so equal to round-off) and Σ E(k_n)·k₀ = ½⟨|u|²⟩ by construction
    solver = NavierStokesSolver(GRID, nu=NU, forcing=ConstantPowerForcing(1e-3))
    rng = np.random.default_rng(0)
    state = solver.state(rng.standard_normal((3, *GRID.shape)))
    fields = solver.fields(state)
    s = 0.5 * (fields.gradient + fields.gradient.transpose(1, 0, 2, 3, 4))
    sums = spectral_sums(state.velocity_hat, GRID, NU)
    assert sums.energy == pytest.approx(0.5 * np.mean(np.sum(fields.velocity**2, 0)), rel=1e-12)
    assert sums.dissipation == pytest.approx(2 * NU * np.mean(np.sum(s**2, (0, 1))), rel=1e-12)
    _, e = energy_spectrum(state.velocity_hat, GRID)
    assert np.sum(e) * GRID.k0 == pytest.approx(sums.energy, rel=1e-12)


def test_measured_parameters_follow_their_definitions():
    energy, dissipation, inverse_k, nu = 1.5, 0.1, 0.02, 1e-6  # u′ = 1 m/s
    p = measured_parameters(
        GRID, nu, energy=energy, dissipation=dissipation, inverse_k=inverse_k, injection=0.1
    )
    assert p.u_rms == pytest.approx(1.0)
    assert p.eta == pytest.approx((nu**3 / 0.1) ** 0.25)
    assert p.tau_eta == pytest.approx(sqrt(nu / 0.1))
    assert p.taylor_microscale == pytest.approx(sqrt(15 * nu / 0.1))
    assert p.r_lambda == pytest.approx(sqrt(15 / (0.1 * nu)))  # (15u′⁴/(εν))^{1/2}
    assert p.integral_scale == pytest.approx(pi / 2 * inverse_k)
    assert p.eddy_time == pytest.approx(p.integral_scale)
    assert p.kmax_eta == pytest.approx(GRID.kmax * p.eta)
    assert p.as_dict()["n"] == 32 and p.box_side == 0.2
    with pytest.raises(ValueError, match="must be > 0"):
        measured_parameters(GRID, nu, energy=0.0, dissipation=0.1, inverse_k=1.0, injection=0.1)
