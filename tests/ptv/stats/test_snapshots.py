"""Per-snapshot sums and the bootstrap over snapshots, against exact error formulas."""

import numpy as np
import pytest

from ptv.stats.multidt import fit_multi_dt, fit_multi_dt_bootstrap
from ptv.stats.pairs import PairSums
from ptv.stats.snapshots import SnapshotSums, cluster_mean

DT = np.array([0.1, 0.2, 0.3, 0.4, 0.5]) * 1e-3  # s


def synthetic_pair_sums(q):
    """PairSums of one snapshot from its q values, shape (B, n, K)."""
    b, n, _ = q.shape
    return PairSums(
        count=np.full(b, n, dtype=np.int64),
        sum_q=q.sum(axis=1),
        sum_q2=(q**2).sum(axis=1),
        sum_r=np.full(b, float(n)),
    )


def test_layouts_pool_to_the_plain_sum():
    rng = np.random.default_rng(0)
    snaps = [synthetic_pair_sums(rng.exponential(1.0, (4, 10, 3))) for _ in range(5)]
    tr = SnapshotSums.from_time_resolved(snaps)
    total = snaps[0]
    for s in snaps[1:]:
        total = total + s
    assert tr.count.shape == (5, 4, 3) and np.all(tr.stratum == 0)
    assert np.allclose(tr.mean, total.mean)
    assert np.allclose(tr.mean_separation, total.mean_separation)
    # Double frame: run k has its own snapshots, with one column each.
    runs = [
        [synthetic_pair_sums(rng.exponential(1.0, (4, 7, 1))) for _ in range(m)] for m in (3, 5)
    ]
    df = SnapshotSums.from_double_frame(runs)
    assert df.count.shape == (8, 4, 2)
    assert df.stratum.tolist() == [0, 0, 0, 1, 1, 1, 1, 1]
    for k, run in enumerate(runs):
        tot = run[0]
        for s in run[1:]:
            tot = tot + s
        assert np.allclose(df.mean[:, k], tot.mean[:, 0])
        assert np.array_equal(df.total_count[:, k], tot.count)


def test_bootstrap_weights_keep_the_snapshot_count_of_each_stratum():
    rng = np.random.default_rng(1)
    runs = [
        [synthetic_pair_sums(rng.exponential(1.0, (2, 3, 1))) for _ in range(m)] for m in (4, 9, 2)
    ]
    sums = SnapshotSums.from_double_frame(runs)
    w = sums.bootstrap_weights(500, rng=2)
    for s, m in enumerate((4, 9, 2)):
        assert np.all(w[:, sums.stratum == s].sum(axis=1) == m)
    # Each snapshot is drawn once on average.
    assert np.allclose(w.mean(axis=0), 1.0, atol=0.2)
    # Same seed → same replicates.
    assert np.array_equal(sums.bootstrap_means(20, rng=3), sums.bootstrap_means(20, rng=3))


def make_snapshots(rng, s_true, noise, *, m, n, a, shared):
    """q of n pairs per snapshot and bin at every Δt, shape (M, B, n, K).

    q = (δv·Δt + δb)² with δv ~ N(0, S(1 + a·g)) sharing a factor g per snapshot and bin
    (pairs of a snapshot are correlated; bins are independent repetitions) and
    δb ~ N(0, noise). With shared=True the same δv enters every Δt (time-resolved data);
    otherwise each Δt gets its own snapshots.
    """
    b, k = s_true.size, DT.size
    g = rng.uniform(-1, 1, (m, b, 1, k if not shared else 1))
    shape_v = (m, b, n, 1) if shared else (m, b, n, k)
    dv = rng.standard_normal(shape_v) * np.sqrt(s_true[None, :, None, None] * (1 + a * g))
    db = rng.standard_normal((m, b, n, k)) * np.sqrt(noise)
    return (dv * DT + db) ** 2


def test_bootstrap_error_agrees_with_the_exact_wls_error_for_independent_snapshots():
    rng = np.random.default_rng(4)
    m, n, a = 60, 40, 0.8
    s_true = np.geomspace(2e-3, 5e-2, 40)  # m²/s²
    noise = 2 * (10e-6) ** 2  # m², Var(δb·e) for 10 µm noise
    q = make_snapshots(rng, s_true, noise, m=m, n=n, a=a, shared=False)
    runs = [[synthetic_pair_sums(q[i, :, :, k : k + 1]) for i in range(m)] for k in range(DT.size)]
    sums = SnapshotSums.from_double_frame(runs)
    # Exact Var(y_k): y = mean of M·n values (v + ...)² ... computed from the generator:
    # per snapshot T = Σ q with q = μ_g z², μ_g = S(1+a g)Δt² + noise, g ~ U(−1, 1).
    # Var(y) = [E Var(T|g) + Var E(T|g)]/(M n²) = [2n E μ_g² + n² Var μ_g]/(M n²).
    mu0 = s_true[:, None] * DT**2 + noise
    dmu = a * s_true[:, None] * DT**2
    e_mu2 = mu0**2 + dmu**2 / 3
    var_y = (2 * n * e_mu2 + n**2 * dmu**2 / 3) / (m * n**2)
    exact = fit_multi_dt(DT, sums.mean, sigma=np.sqrt(var_y))
    boot = fit_multi_dt_bootstrap(DT, sums.mean, sums.bootstrap_means(400, rng=5))
    ratio = boot.se_c1 / exact.se_c1
    assert abs(np.median(ratio) - 1) < 0.1
    assert np.all(np.abs(ratio - 1) < 0.25)
    # The naive pair-count error ignores the snapshot correlation: it is too small here.
    assert np.median(sums.naive_sem / np.sqrt(var_y)) < 0.7
    # And the bootstrap errors describe the scatter of c1 around the truth.
    pull = (boot.c1 - s_true) / boot.se_c1
    assert abs(pull.mean()) < 0.5 and 0.7 < pull.std() < 1.3


@pytest.mark.parametrize(("gls", "m", "n", "bins"), [(False, 40, 30, 300), (True, 600, 5, 120)])
def test_bootstrap_errors_match_the_scatter_for_time_resolved_snapshots(gls, m, n, bins):
    # Δt columns share the velocity sample: strongly correlated estimates. The spread of
    # the refitted c1 accounts for that with diagonal weights (WLS) at any M; GLS with a
    # bootstrap covariance needs many snapshots (with M = 40 it is biased low by ~0.4σ
    # and scatters more than WLS: the covariance is estimated from the same data).
    rng = np.random.default_rng(6)
    s_true = np.full(bins, 1e-2)
    noise = 2 * (10e-6) ** 2
    q = make_snapshots(rng, s_true, noise, m=m, n=n, a=0.5, shared=True)
    sums = SnapshotSums.from_time_resolved([synthetic_pair_sums(q[i]) for i in range(m)])
    y_boot = sums.bootstrap_means(300, rng=7)
    fit = fit_multi_dt_bootstrap(DT, sums.mean, y_boot, gls=gls)
    pull = (fit.c1 - s_true) / fit.se_c1
    assert abs(pull.mean()) < 0.4 and 0.8 < pull.std() < 1.25
    # χ² with the bootstrap covariance: ≈ 1 for a line, large with curvature.
    assert 0.75 < np.mean(fit.chi2_dof) < 1.4
    cubic = -0.3 * s_true[0] / DT.max() * DT**3
    bent = fit_multi_dt_bootstrap(DT, sums.mean + cubic, y_boot + cubic, gls=gls)
    assert np.median(bent.chi2_dof) > 3


def test_bad_input_is_rejected():
    with pytest.raises(ValueError, match="no snapshots"):
        SnapshotSums.from_time_resolved([])
    one = PairSums(np.ones(2, np.int64), np.ones((2, 2)), np.ones((2, 2)), np.ones(2))
    with pytest.raises(ValueError, match="one column"):
        SnapshotSums.from_double_frame([[one]])
    col = PairSums(np.ones(2, np.int64), np.ones((2, 1)), np.ones((2, 1)), np.ones(2))
    with pytest.raises(ValueError, match="run 1 has no snapshots"):
        SnapshotSums.from_double_frame([[col], []])
    sums = SnapshotSums.from_double_frame([[col, col], [col]])
    with pytest.raises(ValueError, match="stratum 1 has 1 snapshot"):
        sums.bootstrap_means(10, rng=0)
    with pytest.raises(ValueError, match="n_boot"):
        sums.bootstrap_means(1, rng=0)
    with pytest.raises(ValueError, match="sum_q has shape"):
        SnapshotSums(
            np.ones((1, 2, 2)),
            np.ones((1, 2, 3)),
            np.ones((1, 2, 2)),
            np.ones((1, 2, 2)),
            np.zeros(1),
        )
    with pytest.raises(ValueError, match="NaN"):
        SnapshotSums(
            np.ones((1, 2, 2)),
            np.full((1, 2, 2), np.nan),
            np.ones((1, 2, 2)),
            np.ones((1, 2, 2)),
            np.zeros(1),
        )


def test_cluster_mean_of_equal_weights_is_the_mean_and_its_standard_error():
    rng = np.random.default_rng(8)
    values = rng.normal(size=(12, 4, 3))
    mean, se = cluster_mean(np.full(12, 7.0), values)
    assert np.allclose(mean, values.mean(axis=0))
    assert np.allclose(se, values.std(axis=0, ddof=1) / np.sqrt(12))
    _, cov = cluster_mean(np.full(12, 7.0), values, full=True)
    assert cov.shape == (12, 12)
    assert np.allclose(cov, np.cov(values.reshape(12, -1), rowvar=False) / 12)


def test_cluster_mean_ignores_snapshots_without_weight():
    values = np.array([[1.0, np.nan], [3.0, 5.0], [np.nan, 7.0]])
    weights = np.array([[1.0, 0.0], [3.0, 1.0], [0.0, 1.0]])
    mean, se = cluster_mean(weights, values)
    assert np.allclose(mean, [2.5, 6.0])
    # Two snapshots per column: 2·Σ w²(x − x̄)² / (Σ w)².
    assert np.allclose(se, np.sqrt([2 * (1.5**2 + 9 * 0.5**2) / 16, 2 * 2 / 4]))
    _, lone = cluster_mean(np.array([1.0, 0.0]), np.array([4.0, np.nan]))
    assert np.isnan(lone)
