"""Pixel-integrated Gaussian spots against the formulas of docs/imaging.md §3."""

import math

import numpy as np
import pytest
from scipy.special import erf, erfc

from simulator.render.particle_images import fraction_on_sensor, render_particles


def formula_image(xy, sigma, electrons, shape):
    """μ_ji = N/4 [erf((i+½−x)/√2σ) − erf((i−½−x)/√2σ)] [same in y], summed, every pixel."""
    rows, cols = shape
    i = np.arange(cols)[None, :]
    j = np.arange(rows)[None, :]
    xy = np.atleast_2d(xy)
    s = np.broadcast_to(sigma, len(xy))[:, None] * math.sqrt(2)
    n = np.broadcast_to(electrons, len(xy))[:, None]
    fx = erf((i + 0.5 - xy[:, :1]) / s) - erf((i - 0.5 - xy[:, :1]) / s)
    fy = erf((j + 0.5 - xy[:, 1:]) / s) - erf((j - 0.5 - xy[:, 1:]) / s)
    return np.einsum("pj,pi->ji", n / 4 * fy, fx)


def centroid(image):
    rows, cols = image.shape
    total = image.sum()
    return (
        (image.sum(axis=0) * np.arange(cols)).sum() / total,
        (image.sum(axis=1) * np.arange(rows)).sum() / total,
    )


def test_pixels_match_erf_formula():
    rng = np.random.default_rng(1)
    xy = rng.uniform([2, 2], [28, 18], size=(12, 2))
    sigma = rng.uniform(0.3, 2.0, size=12)
    ne = rng.uniform(100, 5000, size=12)
    got = render_particles(xy, sigma, ne, shape=(20, 30), roi_sigmas=12).image
    want = formula_image(xy, sigma, ne, (20, 30))
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12 * ne.max())


def test_total_is_sum_of_electrons_far_from_edges():
    rng = np.random.default_rng(2)
    n = 300
    xy = rng.uniform([20, 20], [380, 180], size=(n, 2))
    sigma = rng.uniform(0.4, 2.5, size=n)
    ne = rng.uniform(10, 1e4, size=n)
    # With an 8σ ROI the dropped tail is < 2 erfc(8/√2) ≈ 1e-15: exact integration.
    wide = render_particles(xy, sigma, ne, shape=(200, 400), roi_sigmas=8)
    assert wide.image.sum() == pytest.approx(ne.sum(), rel=1e-12)
    np.testing.assert_array_equal(wide.fraction_on_sensor, 1.0)
    # The default 5σ ROI drops at most 2 erfc(5/√2) of each spot, as documented.
    default = render_particles(xy, sigma, ne, shape=(200, 400))
    deficit = 1 - default.image.sum() / ne.sum()
    assert 0 <= deficit <= 2 * erfc(5 / math.sqrt(2))


@pytest.mark.parametrize("sigma", [0.75, 1.0])
def test_centroid_bias_small_for_three_pixel_spots(sigma):
    # d_τ ≈ 3 px; noise-free spots at random sub-pixel positions, 31 × 31 window.
    rng = np.random.default_rng(3)
    xy = 15 + rng.uniform(-0.5, 0.5, size=(200, 2))
    errors = []
    for p in xy:
        img = render_particles(p[None], sigma, 1000.0, shape=(31, 31)).image
        errors.append(np.subtract(centroid(img), p))
    assert np.abs(errors).max() <= 0.02
    # The analytic bias at this σ is (1/π) e^{−2π²σ²} < 5e-6 px.
    assert np.abs(errors).max() <= 1e-5


@pytest.mark.parametrize("sigma", [0.3, 0.4, 0.5])
def test_centroid_bias_matches_analytic_peak_locking(sigma):
    # docs/imaging.md §6: pixel-integrated CoM on an infinite window is biased by
    # −(1/π) e^{−2π²σ²} sin 2πx̃; the next harmonic is (1/2π) e^{−8π²σ²} ≤ 1.3e-4 px.
    frac = np.linspace(-0.5, 0.5, 41)
    xy = np.column_stack([20 + frac, 10 - frac])
    amp = math.exp(-2 * math.pi**2 * sigma**2) / math.pi
    second = math.exp(-8 * math.pi**2 * sigma**2) / (2 * math.pi)
    for (x, y), f in zip(xy, frac, strict=True):
        img = render_particles([[x, y]], sigma, 1.0, shape=(21, 41), roi_sigmas=20).image
        cx, cy = centroid(img)
        assert cx - x == pytest.approx(-amp * math.sin(2 * math.pi * f), abs=1.01 * second)
        assert cy - y == pytest.approx(-amp * math.sin(-2 * math.pi * f), abs=1.01 * second)
    if sigma == 0.4:
        assert amp == pytest.approx(0.0134, abs=5e-4)  # "0.013 px at σ = 0.4"


def test_full_fourier_series_of_the_bias():
    # Poisson summation gives the whole series: Σ_k (−1)^k/(πk) e^{−2π²σ²k²} sin 2πkx̃.
    sigma = 0.3
    for f in np.linspace(-0.45, 0.45, 10):
        img = render_particles([[20 + f, 10]], sigma, 1.0, shape=(21, 41), roi_sigmas=30).image
        k = np.arange(1, 8)
        series = np.sum(
            (-1.0) ** k
            / (np.pi * k)
            * np.exp(-2 * np.pi**2 * sigma**2 * k**2)
            * np.sin(2 * np.pi * k * f)
        )
        assert centroid(img)[0] - (20 + f) == pytest.approx(series, abs=1e-12)


def test_spot_half_off_the_sensor():
    shape = (21, 20)
    # Centre on the left edge of the sensor (x = −½): half the light is on the sensor.
    res = render_particles([[-0.5, 10.0]], 1.0, 1000.0, shape=shape)
    assert res.image.sum() == pytest.approx(500.0, rel=2e-6)
    assert res.fraction_on_sensor[0] == pytest.approx(0.5, rel=1e-15)
    assert res.visible[0]
    assert res.in_frame[0]  # the sensor area is [−½, W − ½)
    # Centre off the sensor: only the tail reaches column 0, Q(1.5σ) of the light.
    res = render_particles([[-2.0, 10.0]], 1.0, 1000.0, shape=shape)
    want = 1000 * 0.5 * erfc(1.5 / math.sqrt(2))
    assert res.image.sum() == pytest.approx(want, rel=2e-5)
    assert 1000 * res.fraction_on_sensor[0] == pytest.approx(want, rel=1e-14)
    assert res.visible[0]
    assert not res.in_frame[0]
    np.testing.assert_allclose(
        fraction_on_sensor([[-0.5, 10.0], [np.nan, 1.0], [19.5, -0.5]], [1.0, np.nan, 2.0], shape),
        [0.5, 0.0, 0.25],
        rtol=1e-15,
    )
    # Corner: a quarter.
    res = render_particles([[19.5, -0.5]], 0.8, 1000.0, shape=shape)
    assert res.image.sum() == pytest.approx(250.0, rel=2e-6)


def test_edge_pixels_equal_the_formula_for_off_sensor_centres():
    xy = np.array([[-1.7, 5.2], [10.3, -2.4], [22.1, 14.9], [8.0, 21.3]])
    got = render_particles(xy, 1.2, 1000.0, shape=(20, 21), roi_sigmas=12).image
    np.testing.assert_allclose(got, formula_image(xy, 1.2, 1000.0, (20, 21)), atol=1e-10)


def test_overlapping_spots_add():
    a = render_particles([[10.2, 8.7]], 1.1, 300.0, shape=(20, 20)).image
    b = render_particles([[11.0, 9.4]], 0.9, 700.0, shape=(20, 20)).image
    both = render_particles(
        [[10.2, 8.7], [11.0, 9.4]], [1.1, 0.9], [300.0, 700.0], shape=(20, 20)
    ).image
    np.testing.assert_allclose(both, a + b, rtol=1e-14, atol=1e-14)


def test_nan_positions_are_invisible():
    xy = np.array([[5.0, 5.0], [np.nan, 3.0], [np.nan, np.nan], [-100.0, 5.0]])
    res = render_particles(xy, [1.0, np.nan, 1.0, 1.0], [100.0, np.nan, 5.0, 100.0], shape=(10, 10))
    np.testing.assert_array_equal(res.visible, [True, False, False, False])
    np.testing.assert_array_equal(res.fraction_on_sensor[1:], 0.0)
    only = render_particles([[5.0, 5.0]], 1.0, 100.0, shape=(10, 10))
    np.testing.assert_array_equal(res.image, only.image)


def test_truth_is_kept_and_copied():
    xy = np.array([[3.0, 4.0], [5.5, 6.5]])
    res = render_particles(xy, 0.8, [10.0, 20.0], shape=(12, 10))
    xy[0, 0] = 99.0
    np.testing.assert_array_equal(res.xy, [[3.0, 4.0], [5.5, 6.5]])
    np.testing.assert_array_equal(res.sigma, [0.8, 0.8])
    np.testing.assert_array_equal(res.electrons, [10.0, 20.0])
    assert res.image.dtype == np.float64
    assert res.image.shape == (12, 10) == res.shape


def test_no_particles_give_an_empty_image():
    res = render_particles(np.empty((0, 2)), 1.0, 1.0, shape=(4, 5))
    np.testing.assert_array_equal(res.image, np.zeros((4, 5)))
    assert res.visible.shape == (0,)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"xy": np.zeros((3, 3))}, r"xy must have shape \(N, 2\)"),
        ({"xy": np.zeros(2)}, r"xy must have shape \(N, 2\)"),
        ({"xy": [[1.0, np.inf]]}, "xy"),
        ({"xy": [["a", "b"]]}, "xy"),
        ({"sigma": 0.0}, "sigma"),
        ({"sigma": [1.0, -1.0]}, "sigma"),
        ({"sigma": [1.0, 1.0, 1.0]}, "sigma"),
        ({"sigma": np.nan}, "sigma"),
        ({"electrons": -5.0}, "electrons"),
        ({"electrons": [1.0, np.inf]}, "electrons"),
        ({"shape": (0, 10)}, "shape"),
        ({"shape": (10,)}, "shape"),
        ({"shape": (10.0, 10)}, "shape"),
        ({"roi_sigmas": 0.0}, "roi_sigmas"),
        ({"min_half_width": 0}, "min_half_width"),
    ],
)
def test_bad_inputs_raise(kwargs, match):
    args = {"xy": [[1.0, 2.0], [3.0, 4.0]], "sigma": 1.0, "electrons": 10.0, "shape": (8, 8)}
    args.update(kwargs)
    xy, sigma, electrons = args.pop("xy"), args.pop("sigma"), args.pop("electrons")
    with pytest.raises(ValueError, match=match):
        render_particles(xy, sigma, electrons, **args)
