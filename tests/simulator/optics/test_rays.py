"""Rays: validation and point_at."""

import numpy as np
import pytest

from simulator.optics.rays import Rays, as_points


def test_point_at_scalar_and_per_ray():
    rays = Rays(origins=[[0, 0, 0], [1, 2, 3]], directions=[[0, 0, 1], [1, 0, 0]])
    np.testing.assert_allclose(rays.point_at(2.0), [[0, 0, 2], [3, 2, 3]])
    np.testing.assert_allclose(rays.point_at(np.array([1.0, -1.0])), [[0, 0, 1], [0, 2, 3]])
    with pytest.raises(ValueError, match="shape"):
        rays.point_at(np.ones(3))


def test_invalid_rows_are_nan_in_both_arrays():
    rays = Rays(origins=[[0, 0, 0], [np.nan, 0, 0]], directions=[[0, 0, 1], [0, 0, 1]])
    assert rays.valid.tolist() == [True, False]
    assert np.isnan(rays.directions[1]).all()
    assert len(rays) == 2


def test_rays_are_read_only_and_validated():
    rays = Rays(origins=[[0, 0, 0]], directions=[[0, 0, 1]])
    with pytest.raises(ValueError):
        rays.origins[0, 0] = 1.0
    with pytest.raises(ValueError, match="unit vectors"):
        Rays(origins=[[0, 0, 0]], directions=[[0, 0, 2]])
    with pytest.raises(ValueError, match=r"shape \(N, 3\)"):
        Rays(origins=[[0, 0]], directions=[[0, 1]])
    with pytest.raises(ValueError, match="shape of origins"):
        Rays(origins=[[0, 0, 0]], directions=[[0, 0, 1], [0, 0, 1]])


def test_as_points_names_the_bad_value():
    with pytest.raises(ValueError, match=r"points must be finite; row 1 is \[0.0, nan, 0.0\]"):
        as_points([[0, 0, 0], [0, np.nan, 0]], 3, "points")
