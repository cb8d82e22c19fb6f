"""The references of the image-stack claims: the Cramér–Rao bound in its closed-form
limits, the least-squares fit's error beside it, and the brute-force matcher on rays of
known points."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from validation.truth.brute_matching import brute_force_match
from validation.truth.localisation_bound import least_squares_errors, localisation_bound
from validation.truth.sensor_spec import SensorSpec


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


def test_least_squares_reference_lies_between_the_bound_and_four_thirds_of_it():
    # Spots like the rendered case's (σ 0.65 px, 2000 e⁻, 8 e⁻ of read noise): an
    # unweighted least-squares Gaussian is unbiased and within 4/3 of the Cramér–Rao
    # bound, per axis (Mortensen et al. 2010).
    n = 4000
    rng = np.random.default_rng(0)
    sigma, electrons = np.full(n, 0.65), np.full(n, 2000.0)
    fraction = rng.uniform(-0.5, 0.5, (n, 2))
    sensor = SensorSpec(
        gain=0.4, read_noise=8.0, offset=10.0, full_well=1e4, bit_depth=12, background=0.0
    )
    errors = least_squares_errors(sigma, electrons, fraction, sensor, rng, draws=2)
    assert errors.shape == (2 * n, 2)
    bound = np.sqrt(np.mean(localisation_bound(fraction, sigma, electrons, 8.0) ** 2, axis=0))
    rms = np.sqrt(np.mean(errors**2, axis=0))
    assert np.all(np.abs(errors.mean(axis=0)) < 4 * rms / np.sqrt(len(errors)))
    assert np.all(rms > bound) and np.all(rms < 4 / 3 * bound)


def test_least_squares_reference_needs_a_draw():
    with pytest.raises(ValueError, match="draws"):
        least_squares_errors(
            np.ones(1), np.ones(1), np.zeros((1, 2)), None, np.random.default_rng(0), draws=0
        )
