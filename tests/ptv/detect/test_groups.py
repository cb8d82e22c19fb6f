"""The pairs of detections close enough to be fitted together, and their chains."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from ptv.detect._groups import _components, close_pairs

_COORDINATE = st.floats(-1e4, 1e4, allow_nan=False, allow_infinity=False)


@settings(max_examples=200, deadline=None)
@given(
    arrays(np.float64, st.tuples(st.integers(0, 60), st.just(2)), elements=_COORDINATE),
    st.sampled_from([0.8, 6.0, 300.0]),
    st.floats(1e-3, 1.0),
)
def test_close_pairs_are_the_pairs_within_the_radius(xy, radius, squeeze):
    xy = xy * squeeze  # from spread out to crowded
    d2 = ((xy[:, None, :] - xy[None, :, :]) ** 2).sum(axis=2)
    i, j = np.nonzero(np.triu(d2 <= radius**2, k=1))
    pairs = close_pairs(xy, radius)
    assert (pairs[:, 0] < pairs[:, 1]).all()
    assert sorted(map(tuple, pairs.tolist())) == sorted(zip(i.tolist(), j.tolist(), strict=True))


@settings(max_examples=200, deadline=None)
@given(st.integers(1, 80), st.data())
def test_chains_are_scipys_connected_components_in_the_same_order(n, data):
    pairs = np.array(
        data.draw(st.lists(st.tuples(st.integers(0, n - 1), st.integers(0, n - 1)), max_size=120)),
        dtype=np.int64,
    ).reshape(-1, 2)
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    expected = connected_components(graph, directed=False)[1]
    assert _components(n, pairs).tolist() == expected.tolist()
