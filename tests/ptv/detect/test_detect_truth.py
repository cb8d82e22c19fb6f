"""Particle detection against the simulator's truth (rendered spots with known centres).

Images come from ``simulator.render``: pixel-integrated Gaussian spots and a 12-bit
sensor (gain 0.4 DN/e⁻, 8 e⁻ read noise, 10 DN offset). Spots have σ = 0.6–0.9 px
(d_τ ≈ 3 px) and 1000–8000 photo-electrons (peak SNR ≈ 20–150).
"""

import numpy as np
import pytest
from scipy.spatial import cKDTree

from ptv.detect import DetectionFlag, _refine, detect_particles, estimate_background
from simulator.render.particle_images import render_particles
from simulator.render.sensor import Sensor

SENSOR = Sensor(gain=0.4, read_noise=8.0, offset=10.0, full_well=10000, bit_depth=12)
NOISY = Sensor(gain=0.4, read_noise=8.0, offset=10.0, full_well=10000, bit_depth=12, background=5)


def match(truth, det_xy, radius=1.0):
    """For each true centre, the index of the nearest detection within ``radius`` or -1."""
    if len(det_xy) == 0:
        return np.full(len(truth), -1)
    dist, j = cKDTree(det_xy).query(truth, distance_upper_bound=radius)
    return np.where(np.isfinite(dist), j, -1)


def jittered_grid(rng, n, *, pitch=12, cols=40, margin=8):
    """n centres on a grid of ``pitch`` px with uniform sub-pixel offsets, and the shape."""
    idx = np.arange(n)
    xy = np.column_stack((idx % cols, idx // cols)) * float(pitch) + margin
    xy += rng.uniform(0, 1, (n, 2))
    shape = (int(xy[:, 1].max()) + margin + 1, int(xy[:, 0].max()) + margin + 1)
    return xy, shape


def rms(err):
    """2-D rms of an (N, 2) error array, px."""
    return float(np.sqrt((err**2).sum(axis=1).mean()))


@pytest.fixture(scope="module")
def random_scene():
    """1024 × 768 image with 600 uniformly placed particles, noisy, and its truth."""
    rng = np.random.default_rng(20240501)
    shape = (768, 1024)
    n = 600
    xy = rng.uniform([3, 3], [shape[1] - 4, shape[0] - 4], size=(n, 2))
    sigma = rng.uniform(0.6, 0.9, n)
    electrons = rng.uniform(1000, 8000, n)
    truth = render_particles(xy, sigma, electrons, shape=shape)
    return xy, NOISY.record(truth.image, rng)


@pytest.mark.parametrize("estimator", ["gauss", "gauss3", "centroid"])
def test_subpixel_rms_error_against_truth(random_scene, estimator):
    xy, image = random_scene
    det = detect_particles(image, estimator=estimator)
    j = match(xy, det.xy)
    found = j >= 0
    assert found.mean() >= 0.95
    assert rms(det.xy[j[found]] - xy[found]) <= 0.1
    # Isolated particles (no other within 5 px) are much better than the 0.1 px budget.
    d2, _ = cKDTree(xy).query(xy, k=2)
    iso = found & (d2[:, 1] > 5)
    assert rms(det.xy[j[iso]] - xy[iso]) <= 0.05


def test_every_detection_is_a_particle(random_scene):
    xy, image = random_scene
    det = detect_particles(image)
    # Nothing spurious: each detection lies within 1 px of a true centre.
    assert (match(det.xy, xy) >= 0).all()


def test_yield_of_isolated_particles():
    rng = np.random.default_rng(7)
    xy, shape = jittered_grid(rng, 800)
    sigma = rng.uniform(0.6, 0.9, len(xy))
    electrons = rng.uniform(1000, 8000, len(xy))
    image = NOISY.record(render_particles(xy, sigma, electrons, shape=shape).image, rng)
    det = detect_particles(image)
    j = match(xy, det.xy)
    assert (j >= 0).mean() >= 0.95
    assert len(det) == len(xy)  # one detection per particle, none split, none spurious
    assert len(np.unique(j[j >= 0])) == (j >= 0).sum()
    assert (det.flags == 0).mean() >= 0.99


def test_no_detection_on_noise_only_frame():
    rng = np.random.default_rng(3)
    frame = NOISY.record(np.zeros((1088, 2048)), rng)
    assert len(detect_particles(frame)) == 0


@pytest.mark.parametrize("value", [0, 10, 4095])
def test_empty_uniform_image_gives_zero_detections(value):
    det = detect_particles(np.full((64, 80), value, dtype=np.uint16))
    assert len(det) == 0
    assert det.xy.shape == (0, 2) and det.shape == (64, 80)
    assert len(detect_particles(np.zeros((5, 7)))) == 0


def sub_pixel_phases(sigma, electrons=5000.0):
    """A 21 × 21 sweep of sub-pixel phases, one spot per phase, noise-free, and truth."""
    g = np.arange(21) / 20
    fx, fy = np.meshgrid(g, g)
    idx = np.arange(fx.size)
    xy = np.column_stack((10 + 12 * (idx % 40), 10 + 12 * (idx // 40))).astype(float)
    xy += np.column_stack((fx.ravel(), fy.ravel()))
    shape = (int(xy[:, 1].max()) + 12, int(xy[:, 0].max()) + 12)
    return xy, render_particles(xy, sigma, electrons, shape=shape).image


def bias(estimator, image, xy, **options):
    det = detect_particles(image, estimator=estimator, **options)
    j = match(xy, det.xy)
    assert (j >= 0).all() and len(det) == len(xy)
    return det.xy[j] - xy


@pytest.mark.parametrize("estimator", ["centroid", "gauss", "gauss3"])
def test_noise_free_bias_at_sigma_075(estimator):
    xy, electrons = sub_pixel_phases(0.75)
    for image in (electrons, SENSOR.record(electrons, noise=False)):
        assert np.abs(bias(estimator, image, xy)).max() <= 0.02
    # On the expected-electron image the Gaussian estimators are far better still
    # (docs/imaging.md §6: 3-point Gaussian on integrated pixels, 0.001 px at σ = 0.7).
    if estimator != "centroid":
        assert np.abs(bias(estimator, electrons, xy)).max() <= 0.002


def test_centroid_bias_at_small_sigma_follows_the_pixel_integration_law():
    """CoM of a pixel-integrated Gaussian: −(1/π) e^(−2π²σ²) sin 2πx̃ (docs/imaging.md §6)."""
    sigma = 0.4
    xy, electrons = sub_pixel_phases(sigma)
    err = bias("centroid", electrons, xy)
    frac = xy - np.round(xy)
    law = -np.exp(-2 * np.pi**2 * sigma**2) / np.pi * np.sin(2 * np.pi * frac)
    assert np.abs(err - law).max() <= 0.002
    assert np.abs(err).max() == pytest.approx(np.exp(-2 * np.pi**2 * sigma**2) / np.pi, rel=0.1)


def pairs(rng, separation, n_pairs=150, sigma=0.75):
    """Pairs of equal-ish spots ``separation`` px apart at random angles, noisy image."""
    centre, shape = jittered_grid(rng, n_pairs, pitch=16, cols=15, margin=10)
    angle = rng.uniform(0, np.pi, n_pairs)
    half = 0.5 * separation * np.column_stack((np.cos(angle), np.sin(angle)))
    xy = np.concatenate((centre - half, centre + half))
    electrons = rng.uniform(2000, 8000, 2 * n_pairs)
    image = NOISY.record(render_particles(xy, sigma, electrons, shape=shape).image, rng)
    return centre, xy, image


@pytest.mark.parametrize("separation", [2.0, 2.5, 3.0])
def test_overlapping_pairs_are_split_or_flagged(separation):
    rng = np.random.default_rng(int(separation * 10))
    centre, xy, image = pairs(rng, separation)
    n = len(centre)
    det = detect_particles(image)
    j = match(xy, det.xy)
    split = (j[:n] >= 0) & (j[n:] >= 0) & (j[:n] != j[n:])
    suspicious = DetectionFlag.OVERLAP | DetectionFlag.ELONGATED
    near = cKDTree(det.xy).query_ball_point(centre, r=separation / 2 + 1.5)
    flagged = np.array([bool((det.flags[k] & suspicious).any()) for k in near])
    assert (split | flagged).all()
    assert det.has(DetectionFlag.OVERLAP)[j[:n][split]].all()  # split ones say so
    if separation >= 3.0:
        assert split.mean() >= 0.95


def test_isolated_spots_are_not_flagged_as_elongated():
    rng = np.random.default_rng(11)
    xy, shape = jittered_grid(rng, 800)
    image = NOISY.record(render_particles(xy, 0.9, 3000.0, shape=shape).image, rng)
    det = detect_particles(image)
    assert not det.has(DetectionFlag.ELONGATED | DetectionFlag.OVERLAP).any()


def test_two_spots_three_pixels_apart_noise_free():
    xy = np.array([[20.3, 15.6], [23.3, 15.6]])
    image = render_particles(xy, 0.75, [4000.0, 2500.0], shape=(32, 40)).image
    det = detect_particles(image)
    assert len(det) == 2
    assert det.has(DetectionFlag.OVERLAP).all()
    j = match(xy, det.xy)
    assert (j >= 0).all()
    # Both spots are fitted together with the exact (pixel-integrated) model: their
    # centres come out exact (gauss3 and centroid, which cannot subtract, are ~0.1 px
    # off here; the deblended log fits alone ~0.02 px).
    assert np.abs(det.xy[j] - xy).max() <= 1e-4
    assert det.intensity[j[0]] > det.intensity[j[1]]


def test_intensity_peak_size_against_truth():
    rng = np.random.default_rng(5)
    xy, shape = jittered_grid(rng, 400)
    electrons = rng.uniform(2000, 8000, len(xy))
    truth = render_particles(xy, 0.75, electrons, shape=shape)
    image = NOISY.record(truth.image, rng)
    det = detect_particles(image)
    j = match(xy, det.xy)
    assert (j >= 0).all()
    # Integrated DN above background ≈ gain × electrons, less the tails below threshold.
    ratio = det.intensity[j] / (SENSOR.gain * electrons)
    assert 0.85 < np.median(ratio) <= 1.0
    assert np.corrcoef(det.intensity[j], electrons)[0, 1] > 0.98
    col, row = np.rint(det.xy[j]).astype(int).T
    expected_peak = SENSOR.gain * truth.image[row, col]
    assert np.median(np.abs(det.peak[j] - expected_peak) / expected_peak) < 0.1
    assert (det.size >= 1).all() and np.median(det.size) >= 5


def test_saturated_and_edge_particles_are_flagged():
    xy = np.array([[30.2, 20.4], [60.7, 20.1], [0.2, 40.5], [90.0, 59.6]])
    electrons = [60000.0, 3000.0, 3000.0, 3000.0]
    image = SENSOR.record(render_particles(xy, 0.75, electrons, shape=(60, 100)).image, 1)
    well_dn = SENSOR.gain * SENSOR.full_well + SENSOR.offset
    det = detect_particles(image, saturation=well_dn)
    j = match(xy, det.xy)
    assert (j >= 0).all()
    flags = det.flags[j]
    assert flags[0] & DetectionFlag.SATURATED and not flags[0] & DetectionFlag.EDGE
    assert flags[1] == 0
    assert flags[2] & DetectionFlag.EDGE and flags[3] & DetectionFlag.EDGE
    assert not (flags[1:] & DetectionFlag.SATURATED).any()
    # By default a uint16 image saturates only at 65535.
    assert not detect_particles(image).has(DetectionFlag.SATURATED).any()
    assert list(det.select(det.clean).xy[0]) == list(det.xy[j[1]])


def test_uneven_background_with_tiles():
    rng = np.random.default_rng(9)
    xy, shape = jittered_grid(rng, 600)
    rows, cols = shape
    # A smooth sheet-like background from 5 to 400 e⁻ per pixel across the frame.
    ramp = 5 + 395 * np.outer(np.ones(rows), np.linspace(0, 1, cols) ** 2)
    electrons = render_particles(xy, 0.75, rng.uniform(2000, 8000, len(xy)), shape=shape).image
    image = SENSOR.record(electrons + ramp, rng)
    det = detect_particles(image, tiles=(4, 8))
    j = match(xy, det.xy)
    assert (j >= 0).mean() >= 0.95
    assert (match(det.xy, xy) >= 0).all()
    assert rms(det.xy[j[j >= 0]] - xy[j >= 0]) <= 0.1
    # One global level is far below the bright side's background, which then comes out
    # as a host of spurious detections: the tiles are what keeps the threshold local.
    assert (match(detect_particles(image).xy, xy) < 0).sum() > 100


def test_same_result_for_every_input_dtype():
    rng = np.random.default_rng(2)
    xy, shape = jittered_grid(rng, 60, cols=10)
    image = NOISY.record(render_particles(xy, 0.75, 3000.0, shape=shape).image, rng)
    background = estimate_background(image)
    ref = detect_particles(image, background=background)
    for dtype in (np.float64, np.float32, np.int32, np.int64, np.uint32):
        other = detect_particles(image.astype(dtype), background=background)
        np.testing.assert_allclose(other.xy, ref.xy, atol=1e-9)
        np.testing.assert_allclose(other.intensity, ref.intensity, atol=1e-6)
        # Each dtype's own estimate (histogram for uint16, sorting for the others)
        # hardly moves the centres.
        own = detect_particles(image.astype(dtype))
        np.testing.assert_allclose(own.xy, ref.xy, atol=0.02)
    small = (image // 16).astype(np.uint8)
    det8 = detect_particles(small)
    assert (match(xy, det8.xy) >= 0).mean() >= 0.95


@pytest.mark.parametrize(("sigma", "electrons"), [(0.75, 3e3), (0.9, 2e5), (1.5, 1e6)])
def test_the_refinement_fits_faint_bright_and_wide_spots(sigma, electrons):
    """The integrated-Gaussian fit converges to the true centre whatever the scale of the
    spot (its normal equations are scaled before they are solved): noise-free, within a
    tenth of the last step it stops at (its convergence test)."""
    truth = np.array([[20.37, 19.71]])
    image = render_particles(truth, sigma, electrons, shape=(40, 40)).image + 5.0
    x, y = np.array([20.0]), np.array([20.0])  # a start 0.4 px off
    level = np.array([5.0])
    spots = _refine.start_spots(image, x, y, level, 0.8)
    one, no_neighbours = np.array([0]), np.zeros(0, np.int64)
    group = (one, np.array([0, 1]), no_neighbours, np.zeros(2, np.int64))
    refined, _ = _refine.refine_groups(image, spots, level, *group, spots.copy())
    assert refined[0]
    centre = spots[0, 1:3]
    assert np.hypot(*(centre - truth[0])) < _refine._TOLERANCE / 10
