"""Pair binning against a brute-force loop over pairs, and against exact linear fields."""

import numba
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from ptv.bins import LogBins
from ptv.stats.pairs import pair_sums


def brute_force(x, d, bins):
    i, j = np.triu_indices(len(x), 1)
    r = x[j] - x[i]
    dist = np.linalg.norm(r, axis=1)
    e = r / dist[:, None]
    q = np.einsum("pkc,pc->pk", d[j] - d[i], e) ** 2
    b = np.searchsorted(bins.edges, dist, side="right") - 1
    ok = (b >= 0) & (b < bins.n_bins)
    count = np.bincount(b[ok], minlength=bins.n_bins)
    sum_q = np.zeros((bins.n_bins, d.shape[1]))
    np.add.at(sum_q, b[ok], q[ok])
    return count, sum_q


@given(seed=st.integers(0, 2**32 - 1), n=st.integers(2, 120), k=st.integers(1, 6))
def test_pair_sums_equal_brute_force(seed, n, k):
    rng = np.random.default_rng(seed)
    x = rng.uniform(0, 0.05, (n, 3))
    d = rng.normal(size=(n, k, 3))
    bins = LogBins(1e-3, 0.04, 9)
    sums = pair_sums(x, d, bins)
    count, sum_q = brute_force(x, d, bins)
    # Pairs within round-off of an edge may fall either side: compare totals robustly.
    assert abs(int(sums.count.sum()) - int(count.sum())) <= 1
    assert np.array_equal(sums.count, count) or np.abs(sums.count - count).sum() <= 2
    if np.array_equal(sums.count, count):
        assert np.allclose(sums.sum_q, sum_q, rtol=1e-12, atol=1e-12)


def test_uniform_strain_gives_its_exact_longitudinal_increment():
    # For u = G x with symmetric G, (δu·e)² = (eᵀGe)² r²; with G = g I it is g² r².
    rng = np.random.default_rng(1)
    x = rng.uniform(-0.01, 0.01, (400, 3))
    g = 3.0
    sums = pair_sums(x, g * x, LogBins(1e-4, 0.03, 120))
    filled = sums.count > 0
    r2 = sums.mean_separation[filled] ** 2
    # ⟨r²⟩ over a bin of log-width 0.048 exceeds ⟨r⟩² by < (0.048)²/12 ≈ 2e-4.
    assert np.allclose(sums.mean[filled, 0], g**2 * r2, rtol=5e-4)


def test_bad_shapes_and_values_are_rejected():
    bins = LogBins(1e-3, 1e-2, 3)
    with pytest.raises(ValueError, match="positions"):
        pair_sums(np.zeros((4, 2)), np.zeros((4, 3)), bins)
    with pytest.raises(ValueError, match="increments"):
        pair_sums(np.zeros((4, 3)), np.zeros((5, 3)), bins)
    with pytest.raises(ValueError, match="NaN"):
        pair_sums(np.full((4, 3), np.nan), np.zeros((4, 3)), bins)
    with pytest.raises(ValueError, match="r_min"):
        LogBins(0.0, 1.0, 3)
    with pytest.raises(ValueError, match="n_bins"):
        LogBins(1e-3, 1.0, 0)


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="one thread: nothing to compare")
def test_sums_do_not_depend_on_the_number_of_threads():
    """Results must be reproducible on any machine: same bits on 1 thread and on all."""
    rng = np.random.default_rng(4)
    x = rng.uniform(-0.5, 0.5, (1500, 3)) * np.array([0.07, 0.07, 0.008])
    d = rng.normal(size=(1500, 5, 3)) * 1e-5
    bins = LogBins(5e-4, 0.035, 24)
    threads = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        single = pair_sums(x, d, bins)
    finally:
        numba.set_num_threads(threads)
    every = pair_sums(x, d, bins)
    for name in ("count", "sum_q", "sum_q2", "sum_r"):
        assert np.array_equal(getattr(single, name), getattr(every, name)), name


def brute_force_midpoint(x, d, bins):
    """Per column: bin and project each pair on its chord midpoint r + (d_j − d_i)/2."""
    i, j = np.triu_indices(len(x), 1)
    count = np.zeros((bins.n_bins, d.shape[1]), dtype=np.int64)
    sum_q = np.zeros((bins.n_bins, d.shape[1]))
    for m in range(d.shape[1]):
        u = d[j, m] - d[i, m]
        mid = x[j] - x[i] + u / 2
        dist = np.linalg.norm(mid, axis=1)
        q = (np.sum(u * mid, axis=1) / dist) ** 2
        b = np.searchsorted(bins.edges, dist, side="right") - 1
        ok = (b >= 0) & (b < bins.n_bins)
        count[:, m] = np.bincount(b[ok], minlength=bins.n_bins)
        np.add.at(sum_q[:, m], b[ok], q[ok])
    return count, sum_q


@given(seed=st.integers(0, 2**32 - 1), n=st.integers(2, 120), k=st.integers(1, 6))
def test_midpoint_sums_equal_brute_force(seed, n, k):
    rng = np.random.default_rng(seed)
    x = rng.uniform(0, 0.05, (n, 3))
    d = rng.normal(scale=2e-3, size=(n, k, 3))
    bins = LogBins(1e-3, 0.04, 9)
    sums = pair_sums(x, d, bins, binning="midpoint")
    count, sum_q = brute_force_midpoint(x, d, bins)
    assert sums.count.shape == (9, k) and sums.sum_r.shape == (9, k)
    # Pairs within round-off of an edge may fall either side.
    assert np.abs(sums.count - count).sum() <= 2
    if np.array_equal(sums.count, count):
        assert np.allclose(sums.sum_q, sum_q, rtol=1e-12, atol=1e-18)


def test_midpoint_binning_removes_the_odd_terms_of_a_uniform_strain():
    """Particles in u = a x (1-D strain) move as x e^{at}: a pair r0 apart along x has
    q = r0² (e^h − 1)², h = aΔt. Binned at t, q/(a² r0² Δt²) = 1 + h + ... (odd terms);
    at the chord midpoint r̄ = r0 (1 + e^h)/2, q/(a² r̄² Δt²) = [tanh(h/2)/(h/2)]², even."""
    a, dt = 40.0, np.array([1e-3, 2e-3, 4e-3])
    x = np.zeros((2, 3))
    x[1, 0] = 4e-3
    d = x[:, None, :] * (np.exp(a * dt) - 1)[None, :, None]
    bins = LogBins(1e-3, 1e-2, 1)
    start = pair_sums(x, d, bins)
    mid = pair_sums(x, d, bins, binning="midpoint")
    h = a * dt
    r_mid = 4e-3 * (1 + np.exp(h)) / 2
    assert np.allclose(start.sum_q[0] / (a * 4e-3 * dt) ** 2, ((np.exp(h) - 1) / h) ** 2)
    assert np.allclose(mid.sum_r[0], r_mid, rtol=1e-14)
    assert np.allclose(mid.sum_q[0] / (a * r_mid * dt) ** 2, (np.tanh(h / 2) / (h / 2)) ** 2)


def test_an_unknown_binning_is_refused():
    with pytest.raises(ValueError, match="binning"):
        pair_sums(np.zeros((2, 3)), np.zeros((2, 3)), LogBins(1e-3, 1e-2, 3), binning="end")
