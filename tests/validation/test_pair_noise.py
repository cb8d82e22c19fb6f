"""The noise term over actual pairs (validation.truth.pair_noise) against a pair loop
written out and against the noise statistics it must reproduce."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from ptv.bins import LogBins
from validation.truth import pair_noise
from validation.truth.pair_noise import PairNoiseSums

BINS = LogBins(1e-4, 1e-2, 5)


def _loop(positions, errors, edges):
    """Σ q and pair counts per bin by a double loop over i < j."""
    n_bins = len(edges) - 1
    sums, counts = np.zeros((errors.shape[1], n_bins)), np.zeros((errors.shape[1], n_bins))
    for i in range(len(positions)):
        for j in range(i + 1, len(positions)):
            d = positions[j] - positions[i]
            r = float(np.sqrt(d @ d))
            b = int(np.searchsorted(edges, r, side="right")) - 1
            if not 0 <= b < n_bins:
                continue
            for k in range(errors.shape[1]):
                q = float(((errors[j, k] - errors[i, k]) @ d / r) ** 2)
                if np.isfinite(q):
                    sums[k, b] += q
                    counts[k, b] += 1
    return sums, counts


@settings(max_examples=25, deadline=None)
@given(n=st.integers(0, 40), seed=st.integers(0, 2**31 - 1))
def test_sums_match_a_pair_loop(n, seed):
    rng = np.random.default_rng(seed)
    positions = rng.uniform(0, 0.006, (n, 3))
    errors = rng.normal(0, 1e-5, (n, 2, 3))
    errors[rng.random(n) < 0.2, 1] = np.nan  # some particles without ΔX at the 2nd Δt
    got = PairNoiseSums.of_snapshot(positions, errors, BINS)
    sums, counts = _loop(positions, errors, BINS.edges)
    np.testing.assert_allclose(got.sum_q, sums, rtol=1e-10, atol=1e-30)
    np.testing.assert_array_equal(got.pairs, counts)


def test_independent_isotropic_noise_gives_twice_the_variance():
    """E[((δ_j − δ_i)·e)²] = 2σ² for independent errors of variance σ² per component."""
    rng = np.random.default_rng(1)
    sigma = 2e-6
    total = PairNoiseSums.empty(1, BINS)
    for m in range(30):
        positions = rng.uniform(0, 0.01, (400, 3))
        errors = rng.normal(0, sigma, (400, 1, 3))
        total = total.merged(PairNoiseSums.of_snapshot(positions, errors, BINS, seed=m))
    ratio = total.mean()[0] / (2 * sigma**2)
    # Each q is 2σ²·χ²₁: relative error √(2/pairs) for independent pairs; pairs that share
    # particles add up to √(2/particles), that of a sample variance (5 standard errors).
    standard_error = np.sqrt(2 / total.pairs[0] + 2 / (30 * 400))
    assert np.all(np.abs(ratio - 1) < 5 * standard_error)


def test_anticorrelated_neighbours_raise_the_noise_term():
    """Two particles that share their error with opposite signs (a joint fit trading
    light between two blended spots) give 4σ_c² more than independent noise would."""
    rng = np.random.default_rng(2)
    n = 300
    x = rng.uniform(0, 0.01, (n, 3))
    positions = np.concatenate([x, x + np.array([1.5e-4, 0, 0])])  # partners 150 µm apart
    shared = rng.normal(0, 3e-6, (n, 3))
    errors = np.concatenate([shared, -shared])[:, None, :]
    got = PairNoiseSums.of_snapshot(positions, errors, LogBins(1.4e-4, 1.6e-4, 1))
    # Only the partner pairs fall in the bin: q = (2 shared_x)², mean 4σ_c².
    assert got.pairs[0, 0] >= n
    assert abs(got.mean()[0, 0] / (4 * 9e-12) - 1) < 0.3


def test_large_snapshots_are_subsampled(monkeypatch):
    monkeypatch.setattr(pair_noise, "MAX_PARTICLES", 50)
    rng = np.random.default_rng(3)
    positions = rng.uniform(0, 0.005, (200, 3))
    got = PairNoiseSums.of_snapshot(positions, rng.normal(0, 1e-6, (200, 1, 3)), BINS)
    assert got.pairs.sum() <= 50 * 49 // 2
