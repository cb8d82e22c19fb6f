"""Eulerian moments and fits against a synthetic flow with known statistics.

Particles fill a box larger than the grid and move in straight lines (no acceleration)
with velocity U0 + u′_i ξ (ξ standard normal, anisotropic u′_i). Every measured position
carries independent Gaussian noise of std σ, so per component
⟨ΔX⟩ = U0 Δt exactly and Var ΔX = u′_i² Δt² + 2σ².
"""

import numpy as np
import pytest

from ptv.stats.eulerian import Grid, eulerian_fit, eulerian_moments, u_prime

DT = np.array([1.0, 2.0, 3.0, 4.0, 5.0]) * 1e-3  # s
U0 = np.array([0.05, -0.02, 0.0])  # m/s
UP = np.array([0.10, 0.08, 0.12])  # m/s, per component
SIGMA = 20e-6  # m
GRID = Grid((0.0, 0.0, 0.0), (0.04, 0.04, 0.01), (4, 4, 2))


def measure(rng, n, *, offset=0.0):
    """Double-frame style: independent particles at each Δt."""
    pos, disp = [], []
    for dt in DT:
        x = rng.uniform((-0.005, -0.005, -0.002), (0.045, 0.045, 0.012), (n, 3))
        v = U0 + UP * rng.standard_normal((n, 3))
        x0 = x + SIGMA * rng.standard_normal((n, 3))
        x1 = x + v * dt + SIGMA * rng.standard_normal((n, 3)) + offset
        pos.append(x0)
        disp.append(x1 - x0)
    return pos, disp


@pytest.fixture(scope="module")
def fitted():
    rng = np.random.default_rng(21)
    pos, disp = measure(rng, 60000)
    return eulerian_fit(eulerian_moments(pos, disp, DT, GRID))


def test_grid_index_matches_brute_force():
    rng = np.random.default_rng(0)
    p = rng.uniform(-0.01, 0.05, (2000, 3))
    idx = GRID.index(p)
    c = GRID.centres
    h = (np.array(GRID.upper) - np.array(GRID.lower)) / GRID.shape
    inside = np.all((p >= GRID.lower) & (p < GRID.upper), axis=1)
    assert np.array_equal(idx >= 0, inside)
    # The cell of a point is the one whose centre is within half a cell in every axis.
    for i in np.flatnonzero(inside)[:200]:
        assert np.all(np.abs(p[i] - c[idx[i]]) <= h / 2 + 1e-15)
    assert GRID.n_cells == 32 and c.shape == (32, 3)


def test_moments_equal_per_cell_numpy():
    rng = np.random.default_rng(1)
    pos, disp = measure(rng, 3000)
    mom = eulerian_moments(pos, disp, DT, GRID)
    for k in (0, 4):
        cell = GRID.index(pos[k])
        for g in (0, 13, 31):
            d = disp[k][cell == g]
            assert mom.count[g, k] == len(d)
            assert np.allclose(mom.mean[g, k], d.mean(axis=0))
            assert np.allclose(mom.var[g, k], d.var(axis=0, ddof=1))
            assert np.allclose(mom.se_mean[g, k], d.std(axis=0, ddof=1) / np.sqrt(len(d)))


def test_mean_velocity_and_zero_offset(fitted):
    assert fitted.valid.all()
    pull_u = (fitted.mean_velocity - U0) / fitted.se_mean_velocity
    pull_b = fitted.offset / fitted.se_offset
    for pull in (pull_u, pull_b):  # 96 independent cell-components
        assert abs(pull.mean()) < 0.4 and 0.75 < pull.std() < 1.25
    # Claim 5: the mean displacement is linear in Δt with β0 within 2σ of zero.
    assert np.mean(np.abs(pull_b) < 2) > 0.88
    assert 0.6 < np.mean(fitted.mean_chi2_dof) < 1.4


def test_offset_test_detects_a_non_zero_mean_noise():
    # A 30 µm frame-B shift (e.g. a cavity misalignment) makes β0 non-zero.
    rng = np.random.default_rng(22)
    shift = 30e-6
    pos, disp = measure(rng, 60000, offset=np.array([shift, 0.0, 0.0]))
    fit = eulerian_fit(eulerian_moments(pos, disp, DT, GRID))
    pull = fit.offset[:, 0] / fit.se_offset[:, 0]
    assert np.median(np.abs(pull)) > 2
    se_avg = np.sqrt(np.sum(fit.se_offset[:, 0] ** 2)) / GRID.n_cells
    assert abs(fit.offset[:, 0].mean() - shift) < 4 * se_avg
    # The velocity is unaffected: the shift is Δt-independent.
    assert abs(np.mean((fit.mean_velocity[:, 0] - U0[0]) / fit.se_mean_velocity[:, 0])) < 0.4


def test_variance_fit_removes_the_noise_and_gives_u_prime(fitted):
    pull = (fitted.variance - UP**2) / fitted.se_variance
    assert abs(pull.mean()) < 0.4 and 0.75 < pull.std() < 1.25
    pull_n = (fitted.noise - 2 * SIGMA**2) / fitted.se_noise
    assert abs(pull_n.mean()) < 0.4 and 0.75 < pull_n.std() < 1.25
    up = u_prime(fitted)
    truth = np.sqrt(np.mean(UP**2))
    assert abs(up.value - truth) < 4 * up.se and up.se / up.value < 0.01
    assert np.allclose(up.per_component, UP, rtol=0.02)
    assert np.isclose(u_prime(fitted, components=[1]).value, UP[1], rtol=0.02)
    assert up.n_cells == GRID.n_cells


def test_subset_and_sparse_cells():
    rng = np.random.default_rng(23)
    pos, disp = measure(rng, 400)  # ~12 per cell and Δt
    mom = eulerian_moments(pos, disp, DT, GRID)
    fit = eulerian_fit(mom, min_count=12, use=[0, 4])
    assert np.array_equal(fit.valid, np.all(mom.count[:, [0, 4]] >= 12, axis=1))
    assert np.all(np.isnan(fit.variance[~fit.valid]))
    v = fit.valid
    x = DT[[0, 4]] ** 2
    expect = (mom.var[v][:, 4] - mom.var[v][:, 0]) / (x[1] - x[0])
    assert np.allclose(fit.variance[v], expect)


def test_bad_input_is_rejected():
    x = [np.zeros((3, 3))] * 2
    with pytest.raises(ValueError, match="one positions and one displacements array per Δt"):
        eulerian_moments(x, x, DT, GRID)
    with pytest.raises(ValueError, match="at least 2 distinct Δt"):
        eulerian_moments(x[:1], x[:1], DT[:1], GRID)
    bad = [np.zeros((3, 3)), np.full((3, 3), np.nan)]
    with pytest.raises(ValueError, match="Δt #1: displacements contain NaN"):
        eulerian_moments(x, bad, DT[:2], GRID)
    with pytest.raises(ValueError, match=r"must both be \(N, 3\)"):
        eulerian_moments(x, [np.zeros((3, 3)), np.zeros((4, 3))], DT[:2], GRID)
    with pytest.raises(ValueError, match="no displacements"):
        eulerian_moments([np.zeros((0, 3))] * 2, [np.zeros((0, 3))] * 2, DT[:2], GRID)
    with pytest.raises(ValueError, match="lower < upper"):
        Grid((0, 0, 0), (1, 0, 1), (2, 2, 2))
    with pytest.raises(ValueError, match="shape must be"):
        Grid((0, 0, 0), (1, 1, 1), (2, 0, 2))
    empty = eulerian_fit(eulerian_moments(x, x, DT[:2], GRID))
    with pytest.raises(ValueError, match="no valid cell"):
        u_prime(empty)
