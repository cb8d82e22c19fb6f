"""The references of the image-formation claims: the spot fit, the specified spots and the
sensor's reading distribution, each against an independent computation."""

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.stats import norm

from simulator.render.camera_frames import ParticleLighting, record_particles
from simulator.render.sensor import Sensor
from simulator.rigs import load_rig
from validation.truth.sensor_spec import (
    SensorSpec,
    background_moments,
    background_pmf,
    difference_mad_sigma,
    draw_spots,
    saturation_probability,
)
from validation.truth.spot_fit import fit_spots, fit_windows, pixel_integrated
from validation.truth.spot_spec import specified_image, specified_spots

SENSOR = SensorSpec(
    gain=0.4, read_noise=8.0, offset=10.0, full_well=1e4, bit_depth=12, background=0.0
)


def test_pixel_integrated_is_the_gaussian_integrated_over_each_pixel():
    centre, sigma = np.array([0.3]), np.array([0.7])
    pixels = np.arange(-4, 5, dtype=float)[None]
    density = lambda t: norm.pdf(t, 0.3, 0.7)  # noqa: E731
    expected = [quad(density, i - 0.5, i + 0.5)[0] for i in pixels[0]]
    np.testing.assert_allclose(pixel_integrated(centre, sigma, pixels)[0], expected, atol=1e-12)


def test_the_fit_recovers_noise_free_spots_exactly():
    rng = np.random.default_rng(1)
    count = 50
    sigma, amount = rng.uniform(0.5, 1.0, count), rng.uniform(300, 3000, count)
    centre = 4 + rng.uniform(-0.5, 0.5, (count, 2))
    pixels = np.broadcast_to(np.arange(9.0), (count, 9))
    windows = 12.0 + amount[:, None, None] * (
        pixel_integrated(centre[:, 1], sigma, pixels)[:, :, None]
        * pixel_integrated(centre[:, 0], sigma, pixels)[:, None, :]
    )
    fits = fit_windows(windows, np.zeros((count, 2)))
    # The fit stops once a step moves the centre and σ by less than 1e-4 px.
    assert fits.converged.all()
    np.testing.assert_allclose(fits.sigma, sigma, atol=1e-4)
    np.testing.assert_allclose(fits.amount, amount, rtol=1e-4)
    np.testing.assert_allclose(fits.xy, centre, atol=1e-4)
    np.testing.assert_allclose(fits.background, 12.0, atol=1e-3)


def test_fit_spots_places_the_centres_in_the_frame_and_refuses_an_edge():
    image = np.full((40, 50), 10.0)
    image[20:23, 30:33] += 100.0
    fits = fit_spots(image, np.array([[31.0, 21.0]]))
    np.testing.assert_allclose(fits.xy, [[31.0, 21.0]], atol=1e-3)
    with pytest.raises(ValueError, match="edge"):
        fit_spots(image, np.array([[2.0, 21.0]]))


def test_drawn_spots_fitted_give_their_sigma_and_light_within_the_noise():
    # The fit on noisy spots: the medians within 1 % (a fitted σ scatters by about 4 %
    # per spot at these brightnesses; the median of 4000 by 0.1 %; the bias of a least-
    # squares fit at a peak signal-to-noise ratio above 20 is a few tenths of a percent).
    rng = np.random.default_rng(2)
    count = 4000
    sigma, electrons = rng.uniform(0.6, 0.9, count), rng.uniform(1000, 3000, count)
    fraction = rng.uniform(-0.5, 0.5, (count, 2))
    windows = draw_spots(sigma, electrons, fraction, SENSOR, rng)
    fits = fit_windows(windows, np.zeros((count, 2)))
    assert np.median(fits.sigma / sigma) == pytest.approx(1.0, abs=0.01)
    assert np.median(fits.amount / (SENSOR.gain * electrons)) == pytest.approx(1.0, abs=0.01)
    assert np.median(fits.background) == pytest.approx(SENSOR.offset, abs=0.05)
    assert np.median(np.abs(fits.xy - (4 + fraction))) < 0.05


@pytest.mark.parametrize("background", [0.0, 30.0])
def test_background_moments_follow_the_sensor_noise(background):
    # Far from the ADC's ends, a rounded reading has the variance gain²(b + read²) plus
    # the rounding's 1/12 (Sheppard), and the mean offset + gain b.
    sensor = SensorSpec(1.0, 10.0, 100.0, 1e4, 12, background)
    mean, sd = background_moments(sensor)
    assert mean == pytest.approx(100.0 + background, abs=1e-6)
    assert sd == pytest.approx(np.sqrt(background + 100.0 + 1 / 12), rel=1e-4)


def test_difference_mad_sigma_of_a_constant_reading_is_a_quarter_bin():
    # d = 0 always, spread over [−½, ½]: median |d| = ¼.
    sensor = SensorSpec(1.0, 0.0, 100.0, 1e4, 12, 0.0)
    assert difference_mad_sigma(sensor) == pytest.approx(0.25 / norm.ppf(0.75) / np.sqrt(2))


def test_difference_mad_sigma_of_wide_gaussian_readings_is_their_sigma():
    # 30 DN of read noise: the rounding adds 1/12 per reading and 1/12 to d, 1e-4 of σ.
    sensor = SensorSpec(1.0, 30.0, 1000.0, 1e6, 12, 0.0)
    assert difference_mad_sigma(sensor) == pytest.approx(30.0, rel=2e-4)


def test_difference_mad_sigma_matches_sampled_differences():
    sensor = SensorSpec(0.3, 8.0, 10.0, 1e4, 12, 2.0)
    rng = np.random.default_rng(3)
    p = background_pmf(sensor)
    a, b = (rng.choice(p.size, 2_000_000, p=p) for _ in range(2))
    d = np.abs(a - b + rng.uniform(-0.5, 0.5, a.size))
    sampled = np.median(d) / norm.ppf(0.75) / np.sqrt(2)
    # SE of a median: 1.2533 σ_d/√n ≈ 0.1 % of it.
    assert difference_mad_sigma(sensor) == pytest.approx(sampled, rel=4e-3)


def test_saturation_probability_matches_a_monte_carlo_sensor():
    rng = np.random.default_rng(3)
    full = SENSOR.gain * SENSOR.full_well + SENSOR.offset
    band = (int(np.ceil(full - 16)), int(full + 16))
    expected = np.array([0.0, 9800.0, 10_000.0, 10_150.0, 30_000.0])
    draws = 20_000
    count = np.minimum(rng.poisson(expected, (draws, len(expected))), SENSOR.full_well)
    reading = np.rint(
        SENSOR.gain * (count + rng.normal(0, SENSOR.read_noise, count.shape)) + SENSOR.offset
    )
    measured = ((reading >= band[0]) & (reading <= band[1])).mean(axis=0)
    p = saturation_probability(expected, SENSOR, band)
    error = np.sqrt(p * (1 - p) / draws) + 1e-9
    assert np.all(np.abs(measured - p) <= 4 * error)
    assert p[0] == 0.0 and p[-1] > 0.999


def test_specified_spots_are_the_renderers_on_a_rig():
    # The documented formulas against what the renderer drew: the renderer takes the
    # diffraction spot at the camera's median magnification, the specification at the
    # particle's own, which moves σ by at most a few 1e-4 on these rigs.
    rig = load_rig("box-4cam")
    rng = np.random.default_rng(4)
    points = np.array(rig.sheet.centre) + (rng.random((300, 3)) - 0.5) * np.array(rig.sheet.size)
    lighting = ParticleLighting(electrons_at_reference=2000.0)
    for camera in rig.cameras:
        frame = record_particles(camera, points, lighting=lighting, sensor=Sensor(), rng=0)
        spec = specified_spots(camera, points, lighting)
        seen = np.isfinite(frame.sigma)
        np.testing.assert_allclose(spec.sigma[seen], frame.sigma[seen], rtol=2e-3)
        np.testing.assert_allclose(spec.electrons, frame.electrons, rtol=1e-12)
        np.testing.assert_allclose(spec.xy[seen], frame.xy[seen], atol=1e-9)


def test_specified_image_holds_each_spots_light():
    rig = load_rig("paper-stereo")
    camera = rig.cameras[0]
    lighting = ParticleLighting(electrons_at_reference=2000.0)
    points = np.array([[0.0, 0.0, 0.0], [0.01, -0.01, 0.002]])
    spec = specified_spots(camera, points, lighting)
    shape = (camera.lens.sensor_size[1], camera.lens.sensor_size[0])
    image = specified_image(spec, shape)
    assert image.sum() == pytest.approx(spec.electrons.sum(), rel=1e-5)
