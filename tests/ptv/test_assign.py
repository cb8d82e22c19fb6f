"""The sparse one-to-one assignment against the dense augmented Hungarian solution."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import linear_sum_assignment

from ptv._assign import assign


def dense_optimum(rows, cols, cost, shape, u):
    """Minimum of Σ cost + u·(idle rows + idle cols) by the dense augmented matrix."""
    n_r, n_c = shape
    big = 1e6
    m = np.full((n_r + n_c, n_c + n_r), big)
    m[rows, cols] = cost
    m[np.arange(n_r), n_c + np.arange(n_r)] = u
    m[n_r + np.arange(n_c), np.arange(n_c)] = u
    m[n_r:, n_c:] = 0.0
    r, c = linear_sum_assignment(m)
    return m[r, c].sum()


def total(chosen, rows, cols, cost, shape, u):
    r, c = rows[chosen], cols[chosen]
    assert len(np.unique(r)) == len(r) and len(np.unique(c)) == len(c)
    return cost[chosen].sum() + u * (shape[0] - len(r) + shape[1] - len(c))


@settings(max_examples=200, deadline=None)
@given(
    n_r=st.integers(1, 7),
    n_c=st.integers(1, 7),
    density=st.floats(0.05, 1.0),
    u=st.sampled_from([0.3, 1.0]),
    seed=st.integers(0, 2**32 - 1),
)
def test_sparse_assignment_is_optimal(n_r, n_c, density, u, seed):
    rng = np.random.default_rng(seed)
    mask = rng.random((n_r, n_c)) < density
    rows, cols = np.nonzero(mask)
    cost = rng.random(len(rows))
    chosen = assign(rows, cols, cost, (n_r, n_c), unmatched_cost=u)
    assert np.all(np.diff(chosen) > 0)
    got = total(chosen, rows, cols, cost, (n_r, n_c), u)
    assert got == pytest.approx(dense_optimum(rows, cols, cost, (n_r, n_c), u), abs=1e-9)


def test_lone_edges_and_bad_input():
    rows, cols = np.array([0, 1]), np.array([1, 0])
    assert assign(rows, cols, np.array([0.5, 2.5]), (2, 2)).tolist() == [0]
    assert assign([], [], [], (0, 0)).tolist() == []
    with pytest.raises(ValueError, match="only once"):
        assign([0, 0], [1, 1], [0.1, 0.2], (1, 2))
    with pytest.raises(ValueError, match="outside the shape"):
        assign([2], [0], [0.1], (2, 2))
    with pytest.raises(ValueError, match="finite and >= 0"):
        assign([0], [0], [-1.0], (1, 1))
    with pytest.raises(ValueError, match="one length"):
        assign([0, 1], [0], [0.1], (2, 2))
