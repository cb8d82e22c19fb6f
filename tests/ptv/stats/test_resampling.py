"""How correlated successive snapshots are, and the block bootstrap that respects it."""

import numpy as np
import pytest

from ptv.stats.resampling import (
    SnapshotCorrelation,
    autocorrelation_time,
    block_length,
    block_weights,
)


def _ar1(rho: float, m: int, series: int, rng: np.random.Generator) -> np.ndarray:
    """Series of an AR(1) process x_t = ρ x_{t−1} + √(1 − ρ²) e_t, unit variance."""
    x = np.empty((m, series))
    x[0] = rng.normal(size=series)
    for t in range(1, m):
        x[t] = rho * x[t - 1] + np.sqrt(1 - rho**2) * rng.normal(size=series)
    return x


def test_independent_snapshots_have_tau_one_and_blocks_of_one():
    """Independent draws: the pooled lag-one correlation is −1/M on average, so τ floors
    at 1 and every snapshot is drawn on its own (the bootstrap's bits are unchanged)."""
    rng = np.random.default_rng(1)
    blocks = [
        block_length(autocorrelation_time(rng.normal(size=(40, 12)))) for _ in range(200)
    ]
    # ρ₁ pooled over 12 independent series of 40 has a standard error of 0.046: blocks
    # start at ρ₁ = 0.1, 2.4 of those errors above the mean of −1/40; about 1 % of the
    # draws cross it.
    assert blocks.count(1) >= 194


@pytest.mark.parametrize("rho", [0.4, 0.7])
def test_an_exponential_correlation_gives_its_integrated_time(rho):
    """For an AR(1) process τ = (1 + ρ)/(1 − ρ) exactly. The lag-one estimate from 20
    series of M = 200 snapshots is biased low by about (1 + 3ρ)/M (Marriott & Pope
    1954) and scatters by √((1 − ρ²)/(20 M)); within the bias plus 4 of those."""
    m, series = 200, 20
    x = _ar1(rho, m, series, np.random.default_rng(2))
    found = autocorrelation_time(x)
    allowed = (1 + 3 * rho) / m + 4 * np.sqrt((1 - rho**2) / (m * series))
    assert found.rho1 == pytest.approx(rho, abs=allowed)
    assert found.tau == pytest.approx((1 + found.rho1) / (1 - found.rho1))
    assert found.effective_snapshots == pytest.approx(m / found.tau)
    assert block_length(found) == int(np.ceil(found.tau))


def test_too_few_snapshots_or_no_usable_series_give_tau_one():
    assert autocorrelation_time(np.ones((10, 3))).tau == 1.0  # no variance
    assert np.isnan(autocorrelation_time(np.arange(3.0)).rho1)
    assert autocorrelation_time(np.full((20, 2), np.nan)).series == 0


def test_a_block_is_capped_at_a_quarter_of_the_snapshots():
    assert block_length(SnapshotCorrelation(0.95, 12, 1)) == 3


def test_a_weak_resolved_correlation_draws_pairs():
    """ρ₁ = 0.17 (a DNS one eddy time apart): τ = 1.41, drawn in blocks of two."""
    assert block_length(SnapshotCorrelation(0.17, 20, 100)) == 2
    assert block_length(SnapshotCorrelation(0.05, 40, 100)) == 1


def test_block_weights_draw_whole_blocks_of_consecutive_snapshots():
    """Every replicate holds as many draws as snapshots; with blocks of 4 over 12
    snapshots each replicate is 3 runs of 4 consecutive (circular) snapshots."""
    w = block_weights(500, 12, 4, np.random.default_rng(3))
    assert w.shape == (500, 12)
    np.testing.assert_array_equal(w.sum(axis=1), 12)
    # Every snapshot is drawn once per replicate on average (circular blocks).
    np.testing.assert_allclose(w.mean(axis=0), 1.0, atol=0.2)
    # Neighbours are drawn together: their counts correlate, distant ones do not.
    corr = np.corrcoef(w.T)
    assert corr[0, 1] > 0.5
    assert corr[0, 6] < corr[0, 1] - 0.5


def test_a_block_bootstrap_recovers_the_error_of_a_correlated_mean():
    """The mean of M AR(1) snapshots (ρ = 0.6) has variance τ/M (τ = 4); the block
    bootstrap with the estimated block gets it, the one-at-a-time bootstrap reads
    √τ = 2 times low."""
    rng = np.random.default_rng(4)
    x = _ar1(0.6, 400, 1, rng)[:, 0]
    tau = (1 + 0.6) / (1 - 0.6)
    block = block_length(autocorrelation_time(x))
    means = block_weights(2000, 400, block, rng) @ x / 400
    single = block_weights(2000, 400, 1, rng) @ x / 400
    exact = np.sqrt(tau / 400)
    # A block bootstrap's variance is biased low by about block/M and scatters by
    # about sqrt(block/M); 25 % covers both at M = 400.
    assert np.std(means) == pytest.approx(exact, rel=0.25)
    assert np.std(single) < 0.7 * exact


def test_bad_blocks_are_refused():
    with pytest.raises(ValueError, match="block"):
        block_weights(10, 5, 6, np.random.default_rng(0))
    with pytest.raises(ValueError, match="series"):
        autocorrelation_time(np.zeros((2, 2, 2)))


def test_too_few_correlated_snapshots_are_drawn_one_at_a_time_with_a_warning(caplog):
    with caplog.at_level("WARNING", logger="ptv.stats.resampling"):
        assert block_length(SnapshotCorrelation(0.8, 7, 10)) == 1
    assert "too few to draw in blocks" in caplog.text
