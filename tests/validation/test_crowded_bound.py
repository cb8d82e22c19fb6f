"""The crowded-image Cramér–Rao bound in the limits where it is known."""

import numpy as np
import pytest

from validation.truth.crowded_bound import crowded_localisation_bound
from validation.truth.localisation_bound import localisation_bound

SHAPE = (64, 64)


def test_a_lone_spot_on_a_pixel_centre_has_the_isolated_bound():
    # Centred on a pixel, the spot is symmetric: x and y decouple from its brightness,
    # its width and the background, so not knowing them costs nothing.
    xy, sigma, electrons = np.array([[30.0, 31.0]]), np.array([0.8]), np.array([2000.0])
    background, read = 5.0, 8.0
    crowded = crowded_localisation_bound(xy, sigma, electrons, background, read, SHAPE)
    isolated = localisation_bound(xy, sigma, electrons, np.sqrt(read**2 + background))
    np.testing.assert_allclose(crowded, np.hypot(*isolated[0]), rtol=1e-6)


def test_an_unknown_brightness_and_width_cost_off_a_pixel_centre():
    xy, sigma, electrons = np.array([[30.3, 31.4]]), np.array([0.8]), np.array([2000.0])
    crowded = crowded_localisation_bound(xy, sigma, electrons, 5.0, 8.0, SHAPE)
    isolated = localisation_bound(xy, sigma, electrons, np.sqrt(64.0 + 5.0))
    assert crowded[0] > np.hypot(*isolated[0])


def test_far_neighbours_leave_each_bound_alone():
    xy = np.array([[20.0, 20.0], [44.0, 40.0]])
    sigma, electrons = np.array([0.8, 1.0]), np.array([2000.0, 5000.0])
    pair = crowded_localisation_bound(xy, sigma, electrons, 5.0, 8.0, SHAPE)
    alone = [
        crowded_localisation_bound(xy[[k]], sigma[[k]], electrons[[k]], 5.0, 8.0, SHAPE)[0]
        for k in range(2)
    ]
    np.testing.assert_allclose(pair, alone, rtol=1e-12)


@pytest.mark.parametrize("sigma", [0.7, 1.0])
def test_a_neighbour_closing_in_raises_the_bound(sigma):
    bounds = []
    for separation in (4.0, 2.0, 1.5, 1.0):
        xy = np.array([[30.0, 30.0], [30.0 + separation, 30.0]])
        spots = (xy, np.full(2, sigma), np.full(2, 3000.0))
        bounds.append(crowded_localisation_bound(*spots, 5.0, 8.0, SHAPE)[0])
    assert np.all(np.diff(bounds) > 0)
    assert bounds[-1] > 3 * bounds[0]
