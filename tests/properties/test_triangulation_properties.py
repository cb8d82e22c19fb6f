"""Hypothesis: triangulation of exact rays returns their common point; skew-ray geometry."""

import numpy as np
from hypothesis import assume, given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from ptv.triangulate import closest_points

coords = st.floats(-0.1, 0.1)
points = arrays(np.float64, 3, elements=coords)
unit_like = arrays(np.float64, 3, elements=st.floats(-1, 1)).filter(
    lambda v: np.linalg.norm(v) > 0.1
)


@given(
    p=points,
    dirs=st.lists(unit_like, min_size=2, max_size=4),
    s=st.lists(st.floats(-0.5, 0.5), min_size=4, max_size=4),
)
def test_exact_rays_meet_at_their_point(p, dirs, s):
    v = np.array([d / np.linalg.norm(d) for d in dirs])
    # Not all parallel: the smallest angle between some pair exceeds ~1°.
    assume(max(np.linalg.norm(np.cross(v[0], w)) for w in v[1:]) > 0.02)
    o = p + np.array(s[: len(v)])[:, None] * v  # origins anywhere along each ray
    tri = closest_points(o[:, None, :], v[:, None, :])
    assert np.allclose(tri.points[0], p, atol=1e-10)
    assert np.all(tri.ray_distances < 1e-10)


@given(o1=points, o2=points, d1=unit_like, d2=unit_like)
def test_two_skew_rays_give_the_midpoint_of_their_common_perpendicular(o1, o2, d1, d2):
    v1, v2 = d1 / np.linalg.norm(d1), d2 / np.linalg.norm(d2)
    cross = np.cross(v1, v2)
    assume(np.linalg.norm(cross) > 0.05)
    skew = abs(np.dot(o2 - o1, cross)) / np.linalg.norm(cross)
    tri = closest_points(np.array([[o1], [o2]]), np.array([[v1], [v2]]))
    assert np.allclose(tri.ray_distances[:, 0], skew / 2, atol=1e-12)
    # The point's offsets from both rays are perpendicular to both directions.
    for o, v in ((o1, v1), (o2, v2)):
        foot = o + np.dot(tri.points[0] - o, v) * v
        assert abs(np.dot(tri.points[0] - foot, v1)) < 1e-10
        assert abs(np.dot(tri.points[0] - foot, v2)) < 1e-10


def test_parallel_or_missing_rays_give_nan():
    o = np.array([[[0, 0, 0.0]], [[1, 0, 0.0]]])
    v = np.array([[[0, 0, 1.0]], [[0, 0, 1.0]]])
    assert np.isnan(closest_points(o, v).points).all()
    v_missing = np.array([[[0, 0, 1.0]], [[np.nan] * 3]])
    assert np.isnan(closest_points(o, v_missing).points).all()
