"""The references of the image-stack claims: the Cramér–Rao bound in its closed-form
limits, and the brute-force matcher on rays of known points."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from validation.truth.brute_matching import brute_force_match
from validation.truth.localisation_bound import localisation_bound


class _Rays:
    def __init__(self, origins, directions):
        self.origins = origins
        self.directions = directions


def test_photon_limited_bound_is_sigma_over_root_n_for_wide_spots():
    # No read noise, σ ≫ 1 px: the Poisson bound of a continuous Gaussian, σ_a/√N with
    # σ_a² = σ² + 1/12 for the pixel's width (Mortensen et al. 2010).
    sigma, electrons = 3.0, 1e4
    bound = localisation_bound(
        np.array([[50.2, 40.7]]), np.array([sigma]), np.array([electrons]), 0.0
    )
    np.testing.assert_allclose(bound[0], np.sqrt((sigma**2 + 1 / 12) / electrons), rtol=0.01)


def test_read_noise_limited_bound_is_thompsons_background_term():
    # Read noise b ≫ the signal per pixel: var = 8πσ_a⁴b²/N² (Thompson et al. 2002).
    sigma, electrons, b = 2.0, 1e3, 1e3
    bound = localisation_bound(
        np.array([[10.0, 10.0]]), np.array([sigma]), np.array([electrons]), b
    )
    expected = np.sqrt(8 * np.pi * (sigma**2 + 1 / 12) ** 2 * b**2 / electrons**2)
    np.testing.assert_allclose(bound[0], expected, rtol=0.01)


def _rays_through(origin, points):
    d = points - origin
    return _Rays(
        np.broadcast_to(origin, points.shape).copy(), d / np.linalg.norm(d, axis=1)[:, None]
    )


BOX = (np.array([-0.05, -0.05, -0.005]), np.array([0.05, 0.05, 0.005]))


@settings(max_examples=25, deadline=None)
@given(st.integers(1, 40), st.integers(0, 2**31 - 1))
def test_exact_rays_of_separate_points_match_to_the_points(n, seed):
    rng = np.random.default_rng(seed)
    points = rng.uniform(BOX[0] * 0.9, BOX[1] * 0.9, size=(n, 3))
    a = _rays_through(np.array([-0.3, 0.0, -0.5]), points)
    order = rng.permutation(n)
    b = _rays_through(np.array([0.3, 0.0, -0.5]), points[order])
    matched = brute_force_match((a, b), BOX, 1e-9 + 1e-12)
    assert len(matched) == n
    np.testing.assert_allclose(np.sort(matched, axis=0), np.sort(points, axis=0), atol=1e-12)


def test_a_ray_pair_outside_the_box_or_beyond_the_tolerance_is_no_match():
    inside, outside = np.array([[0.0, 0.0, 0.0]]), np.array([[0.0, 0.0, 0.02]])
    for point in (inside, outside):
        a = _rays_through(np.array([-0.3, 0.0, -0.5]), point)
        b = _rays_through(np.array([0.3, 0.0, -0.5]), point + np.array([0.0, 2e-4, 0.0]))
        assert len(brute_force_match((a, b), BOX, 1.5e-4)) == 0


def test_the_cheaper_pairing_wins_a_shared_detection():
    p = np.array([[0.0, 0.0, 0.0]])
    a = _rays_through(np.array([-0.3, 0.0, -0.5]), p)
    b = _rays_through(
        np.array([0.3, 0.0, -0.5]), p + np.array([[0.0, 1e-4, 0.0], [0.0, 2e-5, 0.0]])
    )
    (matched,) = brute_force_match((a, b), BOX, 1.5e-4)
    assert matched[1] == pytest.approx(1e-5, abs=2e-6)
