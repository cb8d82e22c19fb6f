"""Input checking, the Detections container and the background estimate."""

import numpy as np
import pytest

from ptv.detect import (
    BackgroundEstimate,
    DetectionFlag,
    Detections,
    check_image,
    detect_particles,
    estimate_background,
)


@pytest.mark.parametrize(
    ("image", "match"),
    [
        (np.zeros((4, 5, 3)), r"2-D.*ndim=3"),
        (np.zeros(7), r"2-D.*ndim=1"),
        (np.zeros((0, 0)), "empty"),
        (np.zeros((0, 12), dtype=np.uint16), "empty"),
        (np.ones((3, 3), dtype=bool), "dtype bool"),
        (np.ones((3, 3), dtype=complex), "dtype complex"),
        (np.array([["a", "b"]]), "real numbers"),
    ],
)
def test_bad_images_are_named(image, match):
    for fn in (check_image, detect_particles, estimate_background):
        with pytest.raises(ValueError, match=match):
            fn(image)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_pixel_is_located(bad):
    image = np.zeros((6, 8))
    image[4, 2] = bad
    with pytest.raises(ValueError, match=r"NaN or infinite, first at \(row 4, column 2\)"):
        detect_particles(image)
    with pytest.raises(ValueError, match="finite"):
        detect_particles(image.astype(np.float32))


def test_check_image_dtypes():
    assert check_image(np.zeros((2, 3), np.uint8)).dtype == np.uint16
    assert check_image(np.zeros((2, 3), np.uint16)).dtype == np.uint16
    for dt in (np.int16, np.int64, np.float16, np.float32, np.float64):
        assert check_image(np.zeros((2, 3), dt)).dtype == np.float64
    strided = np.zeros((10, 10), np.uint16)[::2, ::3]
    assert check_image(strided).flags.c_contiguous
    assert check_image([[1, 2], [3, 4]]).dtype == np.float64


@pytest.mark.parametrize(
    ("option", "match"),
    [
        ({"threshold_sigmas": 0}, "threshold_sigmas must be"),
        ({"threshold_sigmas": -2.0}, "threshold_sigmas must be"),
        ({"threshold_sigmas": float("nan")}, "threshold_sigmas must be"),
        ({"estimator": "fit"}, "estimator must be one of"),
        ({"radius": 0}, "radius must be"),
        ({"radius": 1.5}, "radius must be"),
        ({"min_dip": -0.1}, "min_dip must be"),
        ({"dip_sigmas": -1}, "dip_sigmas must be"),
        ({"max_elongation": 0.5}, "max_elongation must be"),
        ({"min_size": 0}, "min_size must be"),
        ({"saturation": "high"}, "saturation must be"),
        ({"tiles": (0, 2)}, "tiles must be"),
        ({"tiles": (2, 100)}, "tiles must be"),
        ({"tiles": 3}, "tiles must be"),
        ({"background": 12.0}, "background must be"),
        ({"diameter": 0}, "diameter must be a finite number > 0"),
        ({"diameter": float("nan")}, "diameter must be a finite number > 0"),
        ({"diameter": True}, "diameter must be a finite number > 0"),
        ({"diameter": 25.0}, r"diameter 25 px is larger than the image \(20 x 30 px\)"),
        ({"diameter": 15.0, "background": 12.0}, "background must be"),
    ],
)
def test_bad_options_are_named(option, match):
    with pytest.raises(ValueError, match=match):
        detect_particles(np.zeros((20, 30)), **option)


def test_background_of_another_shape_is_refused():
    bg = estimate_background(np.zeros((20, 30)))
    with pytest.raises(ValueError, match=r"shape \(20, 30\).*\(21, 30\)"):
        detect_particles(np.zeros((21, 30)), background=bg)


def test_detections_container():
    det = Detections(
        xy=[[1.0, 2.0], [3.5, 4.25], [7.0, 0.5]],
        intensity=[10, 20, 30],
        peak=[5, 6, 7],
        size=[3, 4, 5],
        flags=[0, DetectionFlag.OVERLAP, DetectionFlag.FALLBACK],
        shape=(10, 12),
    )
    assert len(det) == 3
    assert det.xy.dtype == np.float64 and det.size.dtype == np.int64
    assert det.flags.dtype == np.uint8
    assert det.has(DetectionFlag.OVERLAP).tolist() == [False, True, False]
    assert det.clean.tolist() == [True, False, True]
    sub = det.select(det.clean)
    assert len(sub) == 2 and sub.intensity.tolist() == [10.0, 30.0] and sub.shape == (10, 12)
    with pytest.raises(ValueError, match=r"peak must have shape \(3,\)"):
        Detections(xy=det.xy, intensity=det.intensity, peak=[1, 2], size=det.size,
                   flags=det.flags, shape=(10, 12))  # fmt: skip
    with pytest.raises(ValueError, match=r"xy must have shape \(N, 2\)"):
        Detections(xy=np.zeros((3, 3)), intensity=det.intensity, peak=det.peak,
                   size=det.size, flags=det.flags, shape=(10, 12))  # fmt: skip
    with pytest.raises(AttributeError):
        det.xy = np.zeros((3, 2))  # frozen


def test_background_of_gaussian_noise():
    rng = np.random.default_rng(4)
    image = rng.normal(100.0, 5.0, (1000, 1200))
    bright = rng.random(image.shape) < 0.03  # 3 % of bright "particle" pixels
    image[bright] += 500.0
    bg = estimate_background(image)
    assert bg.tiles == (1, 1)
    assert bg.level[0, 0] == pytest.approx(100.0, abs=0.3)
    # Each bright pixel spoils two differences: the noise comes out ~8 % high here.
    assert bg.noise[0, 0] == pytest.approx(5.0, rel=0.1)
    image[bright] -= 500.0
    assert estimate_background(image).noise[0, 0] == pytest.approx(5.0, rel=0.02)
    assert bg.threshold(6.0)[0, 0] == pytest.approx(bg.level[0, 0] + 6 * bg.noise[0, 0])


def test_background_of_quantised_noise_is_not_stuck_at_whole_numbers():
    rng = np.random.default_rng(5)
    for sigma in (0.8, 3.2):
        image = np.round(rng.normal(40.3, sigma, (800, 900))).astype(np.uint16)
        bg = estimate_background(image)
        assert bg.level[0, 0] == pytest.approx(40.3, abs=0.05)
        # Rounding adds 1/12 DN² of variance.
        assert bg.noise[0, 0] == pytest.approx(np.sqrt(sigma**2 + 1 / 12), rel=0.06)
    flat = estimate_background(np.full((30, 40), 7, np.uint16))
    assert flat.level[0, 0] == 7.0
    assert flat.noise[0, 0] == pytest.approx(1.4826 / 4 / np.sqrt(2), rel=1e-3)
    assert estimate_background(np.full((30, 40), 7.0)).noise[0, 0] == 0.0
    # Noise-free with a spot: floored at 1e-5 of the span.
    spot = np.full((30, 40), 7.0)
    spot[10, 10] = 1007.0
    assert estimate_background(spot).noise[0, 0] == pytest.approx(1e-2)


def test_tiled_background_follows_a_gradient():
    rng = np.random.default_rng(6)
    rows, cols = 600, 800
    level = 50.0 + 0.1 * np.arange(cols)[None, :] + 0.05 * np.arange(rows)[:, None]
    noise = 2.0 + 0.01 * np.arange(cols)[None, :] * np.ones((rows, 1))
    image = level + noise * rng.standard_normal((rows, cols))
    image[rng.random(image.shape) < 0.03] += 300.0  # bright "particle" pixels
    bg = estimate_background(image, tiles=(6, 8))
    assert bg.tiles == (6, 8)
    yy, xx = np.mgrid[50:550:50, 50:750:50]
    pts = np.column_stack((xx.ravel(), yy.ravel())).astype(float)
    got_level, got_noise = bg.at(pts)
    assert np.abs(got_level - level[yy, xx].ravel()).max() < 1.0
    assert np.abs(got_noise / noise[yy, xx].ravel() - 1).max() < 0.15
    # One estimate for the whole frame: the mean level, and the noise of the middle.
    whole = estimate_background(image)
    assert whole.level[0, 0] == pytest.approx(level.mean(), abs=2.0)
    assert whole.noise[0, 0] == pytest.approx(noise.mean(), rel=0.2)


def test_background_estimate_checks_its_fields():
    with pytest.raises(ValueError, match="grids of one shape"):
        BackgroundEstimate(level=np.zeros((2, 2)), noise=np.zeros((2, 3)), shape=(10, 10))
    with pytest.raises(ValueError, match="noise finite and >= 0"):
        BackgroundEstimate(level=np.zeros((1, 1)), noise=-np.ones((1, 1)), shape=(10, 10))
    with pytest.raises(ValueError, match="max_samples"):
        estimate_background(np.zeros((10, 10)), max_samples=0)


def test_threshold_inside_the_noise_stays_fast_and_flags_the_blobs():
    """k ≈ 0 joins half the pixels into huge regions with thousands of maxima each."""
    rng = np.random.default_rng(8)
    image = rng.normal(100.0, 5.0, (256, 384))
    det = detect_particles(image, threshold_sigmas=1e-6)
    assert len(det) > 0
    big = det.size > 1000
    assert big.any() and det.has(DetectionFlag.ELONGATED)[big].all()


def test_saturated_plateau_is_one_particle_at_its_centre():
    image = np.full((50, 60), 10, np.uint16)
    image[20:23, 30:34] = 4095
    det = detect_particles(image, saturation=4095)
    assert len(det) == 1
    assert det.xy[0].tolist() == [31.5, 21.0]
    assert det.size[0] == 12
    assert det.has(DetectionFlag.SATURATED)[0]
