"""S2(r) by the multi-Δt fit on a flow with an exactly known structure function.

Particles move in the simple shear u = G·x, G = g e_x e_yᵀ. G is nilpotent, so the
acceleration G²x vanishes and the displacement is exactly ΔX̃ = Δt·G·x: S2 has no Δt³
term. White Gaussian noise of known σ is added independently to every measured
position, so the noise term is N = 4σ² (docs/statistics.md §1 with ρ = 0). The sample truth
of a bin is the mean of [(G r)·e]² over its actual pairs, from `pair_sums` on the exact
velocities at the measured positions.
"""

import numpy as np
import pytest

from ptv.bins import LogBins
from ptv.stats.multidt import largest_dt, smallest_and_largest_dt
from ptv.stats.pairs import pair_sums
from ptv.stats.structure import double_frame_sums, structure_function, time_resolved_sums

DT = np.array([1.0, 2.0, 3.0, 4.0, 5.0]) * 1e-3  # s
G = np.zeros((3, 3))
G[0, 1] = 20.0  # 1/s
SIGMA = 10e-6  # m, position noise per component
BINS = LogBins(1e-3, 1.6e-2, 6)
P = 300  # particles per snapshot, in a 20 mm cube


def snapshot(rng, dts):
    x = rng.uniform(0, 0.02, (P, 3))
    x0 = x + SIGMA * rng.standard_normal((P, 3))
    disp = np.stack(
        [x + dt * x @ G.T + SIGMA * rng.standard_normal((P, 3)) - x0 for dt in dts], axis=1
    )
    return x0, disp, x @ G.T


@pytest.fixture(scope="module")
def time_resolved():
    rng = np.random.default_rng(11)
    snaps, truth = [], None
    for _ in range(30):
        x0, disp, v = snapshot(rng, DT)
        snaps.append((x0, disp))
        t = pair_sums(x0, v, BINS)
        truth = t if truth is None else truth + t
    return time_resolved_sums(snaps, BINS), truth.mean[:, 0]


def check_recovers_truth(sf, truth, noise_rtol=0.05):
    assert sf.fitted.all()
    pull = (sf.s2 - truth) / sf.se_s2
    assert np.all(np.abs(pull) < 4), pull
    precise = sf.se_s2 / sf.s2 < 0.01
    assert precise.sum() >= 3
    assert np.allclose(sf.s2[precise], truth[precise], rtol=0.03)
    noise = 4 * SIGMA**2
    assert np.all(np.abs(sf.noise - noise) < 4 * sf.se_noise)
    # Bins share particles, so their c2 errors are correlated: compare the average loosely.
    assert abs(np.average(sf.noise, weights=sf.se_noise**-2) / noise - 1) < noise_rtol


@pytest.mark.parametrize("method", ["wls", "gls"])
def test_time_resolved_fit_recovers_noise_free_s2_and_the_noise(time_resolved, method):
    sums, truth = time_resolved
    sf = structure_function(sums, DT, method=method, rng=1)
    check_recovers_truth(sf, truth)
    assert sf.method == f"{method}-bootstrap" and sf.s2_boot.shape == (200, BINS.n_bins)
    assert np.median(sf.chi2_dof) < 2.5  # χ²₃/3 with an estimated covariance: heavy tail
    # Raw S2 at the smallest Δt is biased upward by N/Δt² (docs/statistics.md §3, claim #6).
    bias = (sf.raw_s2[:, 0] - truth) * DT[0] ** 2
    assert np.allclose(bias, 4 * SIGMA**2, rtol=0.1)
    assert sf.raw_s2[0, 0] > 5 * truth[0]
    assert np.all(sf.s2 < sf.raw_s2.min(axis=1))  # claim 14
    assert np.allclose(sf.r, sums.mean_separation) and np.all(np.diff(sf.r) > 0)


def test_subset_fits_use_only_the_chosen_dt(time_resolved):
    sums, truth = time_resolved
    full = structure_function(sums, DT, rng=1)
    for idx in (largest_dt(DT, 3), smallest_and_largest_dt(DT)):
        sf = structure_function(sums, DT, use=idx, rng=1)
        assert sf.used.tolist() == [i in idx for i in range(DT.size)]
        # Extrapolating from the 3 largest Δt to Δt = 0 determines c2 less well.
        check_recovers_truth(sf, truth, noise_rtol=0.1)
        assert np.array_equal(sf.raw_s2, full.raw_s2)
    two = structure_function(sums, DT, use=smallest_and_largest_dt(DT), rng=1)
    assert np.all(np.isnan(two.chi2_dof))
    # The line through the two end points: S2 = (y_max − y_min)/(Δt_max² − Δt_min²).
    y = sums.mean
    assert np.allclose(two.s2, (y[:, -1] - y[:, 0]) / (DT[-1] ** 2 - DT[0] ** 2))


def test_pair_count_errors_fit_the_same_line(time_resolved):
    sums, truth = time_resolved
    sf = structure_function(sums, DT, errors="pairs")
    assert sf.method == "wls" and sf.s2_boot is None
    assert np.allclose(sf.s2, truth, rtol=0.1)


def test_double_frame_runs_with_different_snapshots_per_dt():
    rng = np.random.default_rng(12)
    runs, truth = [], None
    for dt in DT:
        run = []
        for _ in range(12):
            x0, disp, v = snapshot(rng, [dt])
            run.append((x0, disp[:, 0]))
            t = pair_sums(x0, v, BINS)
            truth = t if truth is None else truth + t
        runs.append(run)
    sums = double_frame_sums(runs, BINS)
    assert sums.stratum.tolist() == np.repeat(np.arange(DT.size), 12).tolist()
    sf = structure_function(sums, DT, rng=3)
    check_recovers_truth(sf, truth.mean[:, 0])


def test_sparse_bins_are_left_unfitted():
    rng = np.random.default_rng(13)
    snaps = [snapshot(rng, DT)[:2] for _ in range(3)]
    sums = time_resolved_sums(snaps, LogBins(1e-4, 1.6e-2, 8))
    sf = structure_function(sums, DT, min_pairs=50, rng=0)
    empty = sums.total_count[:, 0] < 50
    assert empty[0] and not empty[-1]
    assert np.all(np.isnan(sf.s2[empty])) and np.all(np.isfinite(sf.s2[~empty]))
    assert np.array_equal(sf.fitted, ~empty)


def test_bad_input_is_rejected(time_resolved):
    sums, _ = time_resolved
    with pytest.raises(ValueError, match="5 Δt columns but dt has 4"):
        structure_function(sums, DT[:4])
    with pytest.raises(ValueError, match="at least 2 distinct Δt"):
        structure_function(sums, np.full(5, 1e-3))
    with pytest.raises(ValueError, match="errors must be"):
        structure_function(sums, DT, errors="magic")
    with pytest.raises(ValueError, match="needs a covariance"):
        structure_function(sums, DT, errors="pairs", method="gls")
    x = np.zeros((4, 3))
    x[1, 0] = np.nan
    with pytest.raises(ValueError, match=r"snapshot 0: .*NaN"):
        time_resolved_sums([(x, np.zeros((4, 2, 3)))], BINS)
    with pytest.raises(ValueError, match=r"shape \(P, K, 3\)"):
        time_resolved_sums([(np.zeros((4, 3)), np.zeros((4, 3)))], BINS)
    with pytest.raises(
        ValueError, match=r"run 0, snapshot 0: displacements must have shape \(P, 3\)"
    ):
        double_frame_sums([[(np.zeros((4, 3)), np.zeros((4, 2, 3)))]], BINS)
    with pytest.raises(ValueError, match="increments"):
        double_frame_sums([[(np.zeros((4, 3)), np.zeros((5, 3)))]], BINS)


def test_chord_midpoint_binning_recovers_the_truth_at_the_midpoints():
    """In the shear G² = 0, so G r̄ = G r: binned by the chord midpoint r̄, every pair's
    q/Δt² is exactly [(G r̄)·ē]², the truth at r̄ (noise-free here). The pairs of a bin
    differ between Δt columns, and the fit must still give that truth."""
    rng = np.random.default_rng(5)
    snaps, truth = [], None
    for _ in range(20):
        x = rng.uniform(0, 0.02, (P, 3))
        disp = np.stack([dt * x @ G.T for dt in DT], axis=1)
        snaps.append((x, disp))
        for k in range(len(DT)):  # the truth of column k, at its midpoints
            t = pair_sums(x + disp[:, k] / 2, x @ G.T, BINS)
            truth = t if truth is None else truth + t
    sums = time_resolved_sums(snaps, BINS, binning="midpoint")
    assert not np.array_equal(sums.total_count[:, 0], sums.total_count[:, -1])
    sf = structure_function(sums, DT)
    assert sf.fitted.all()
    # The columns' populations differ by the pairs whose midpoint crossed a bin edge
    # (separations move by up to g·Δt_max/2 = 5 %): under 1 % of a bin's truth.
    assert np.allclose(sf.s2, truth.mean[:, 0], rtol=0.01)
    assert np.allclose(sf.noise, 0.0, atol=1e-3 * np.max(sf.s2) * DT[0] ** 2)
