"""The conventions claims' references and the detector-noise claim's contamination range."""

import numpy as np
import pytest
from scipy.stats import norm

from ptv.bins import LogBins
from ptv.stats.pairs import pair_sums
from validation.claims.conventions import _pair_reference
from validation.claims.formation import _contaminated_range
from validation.truth.independent import log_edges


def test_the_pair_reference_counts_as_the_stack_and_averages_the_model():
    rng = np.random.default_rng(0)
    snapshots = [(rng.uniform(0, 0.05, (60, 3)), None) for _ in range(3)]
    edges = log_edges(1e-3, 4e-2, 8)
    count, near_edge, mean_r, mean_model = _pair_reference(snapshots, edges, lambda r: r**2)
    sums = [pair_sums(x, np.zeros_like(x), LogBins(1e-3, 4e-2, 8)) for x, _ in snapshots]
    stack = sums[0] + sums[1] + sums[2]
    assert np.all(near_edge == 0)
    np.testing.assert_array_equal(count, stack.count)
    np.testing.assert_allclose(mean_r, stack.mean_separation, rtol=1e-12)
    # ⟨r²⟩ ≥ ⟨r⟩² in every bin (Jensen), equal only for one pair.
    filled = count > 0
    assert np.all(mean_model[filled] >= mean_r[filled] ** 2 * (1 - 1e-12))


def test_no_contamination_allows_nothing():
    low, high = _contaminated_range(np.array(0.0))
    assert low == pytest.approx(0.0, abs=1e-12)
    assert high == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize("p", [0.01, 0.05])
def test_the_contamination_range_is_where_outliers_put_the_median(p):
    # A fraction p of |d| at 0 (low end) or far out (high end) moves the median of a
    # half-normal sample to the quantiles the range states.
    rng = np.random.default_rng(0)
    n = 2_000_000
    clean = np.abs(rng.standard_normal(int(n * (1 - p))))
    low, high = _contaminated_range(np.array(p))
    q = norm.ppf(0.75)
    for outlier, expected in ((0.0, low), (1e9, high)):
        sample = np.concatenate([clean, np.full(n - clean.size, outlier)])
        # SE of the sample median: √(¼/n)/(2φ(q)) ≈ 0.06 % of q; 5 SE.
        assert np.median(sample) / q - 1 == pytest.approx(expected, abs=3e-3)
