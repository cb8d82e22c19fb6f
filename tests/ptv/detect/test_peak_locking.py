"""Peak-locking diagnostic: on synthetic positions with known bias, and on detections."""

import numpy as np
import pytest
from scipy.spatial import cKDTree

from ptv.detect import PeakLocking, detect_particles, peak_locking
from simulator.render.particle_images import render_particles
from simulator.render.sensor import Sensor

NOISY = Sensor(gain=0.4, read_noise=8.0, offset=10.0, full_well=10000, bit_depth=12, background=5)


def test_uniform_positions_are_not_locked():
    rng = np.random.default_rng(1)
    pl = peak_locking(rng.uniform(0, 500, (20000, 2)), bins=10)
    assert isinstance(pl, PeakLocking)
    assert pl.n == 20000
    assert pl.counts.shape == (2, 10) and pl.counts.sum() == 40000
    assert np.allclose(pl.edges, np.linspace(-0.5, 0.5, 11))
    assert not pl.locked()
    assert pl.p_value > 0.01
    assert np.abs(pl.amplitude).max() < 0.005


@pytest.mark.parametrize("a", [0.02, -0.03])
def test_known_sinusoidal_bias_is_measured(a):
    """x̂ = x − a sin 2πx: the amplitude estimate recovers a, the tests reject uniformity."""
    rng = np.random.default_rng(2)
    x = rng.uniform(0, 500, (20000, 2))
    pl = peak_locking(x - a * np.sin(2 * np.pi * x))
    assert pl.amplitude == pytest.approx([a, a], rel=0.15)
    assert pl.locked()
    assert pl.p_harmonic.max() < 1e-10 and pl.p_chi2.max() < 1e-10
    centre_bins = pl.counts[:, 4:6].sum(axis=1)
    edge_bins = pl.counts[:, [0, -1]].sum(axis=1)
    assert ((centre_bins > edge_bins) == (a > 0)).all()


def test_integer_positions_are_fully_locked():
    pl = peak_locking(np.arange(200, dtype=float).reshape(100, 2))
    assert pl.harmonic == pytest.approx([1.0, 1.0])
    assert pl.locked(alpha=1e-20)


def test_accepts_detections():
    image = render_particles([[10.3, 12.7]], 0.8, 3000.0, shape=(24, 24)).image
    det = detect_particles(image)
    assert peak_locking(det).n == 1


@pytest.mark.parametrize(
    ("positions", "bins", "match"),
    [
        (np.zeros((0, 2)), 10, "empty"),
        (np.zeros((5, 3)), 10, r"shape \(N, 2\)"),
        (np.array([[1.0, np.nan]]), 10, "finite"),
        (np.zeros((5, 2)), 1, "bins"),
    ],
)
def test_bad_input(positions, bins, match):
    with pytest.raises(ValueError, match=match):
        peak_locking(positions, bins=bins)


def scene(sigma, seed, n=4000, electrons=(3000, 8000), noise=True):
    """Randomly placed particles on a 1000 × 1200 image (0.0033 per px²), and truth."""
    rng = np.random.default_rng(seed)
    shape = (1000, 1200)
    xy = rng.uniform([3, 3], [shape[1] - 4, shape[0] - 4], size=(n, 2))
    image = render_particles(xy, sigma, rng.uniform(*electrons, n), shape=shape).image
    return xy, (NOISY.record(image, rng) if noise else image)


def matched(xy, det, *, clean=True):
    """Detections within 1 px of a true centre (only clean ones: no overlap etc.)."""
    dist, j = cKDTree(det.xy).query(xy, distance_upper_bound=1.0)
    j = j[np.isfinite(dist)]
    return det.xy[j[det.clean[j]]] if clean else det.xy[j]


def test_default_detector_is_flat_on_random_particles():
    xy, image = scene(0.75, seed=3)
    assert not peak_locking(xy).locked()  # the truth itself
    det = detect_particles(image)
    for subset in (det, det.select(det.clean)):  # all, and those not overlapped
        pl = peak_locking(subset)
        assert pl.n > 3000
        assert not pl.locked()
        assert np.abs(pl.amplitude).max() < 0.01


def test_small_window_centroid_is_flagged_as_peak_locked():
    """A 3 × 3 centroid truncates a σ = 0.75 px spot: ~0.065 px of locking."""
    xy, image = scene(0.75, seed=4)
    det = detect_particles(image, estimator="centroid", radius=1)
    pl = peak_locking(matched(xy, det))
    assert pl.locked(alpha=1e-10)
    assert (pl.amplitude > 0.04).all()  # pulled towards pixel centres


def test_centroid_of_undersampled_spots_is_flagged_as_peak_locked():
    """3 × 3 centroid at σ = 0.4 px (noise-free): −(1/π)e^(−2π²σ²) sin 2πx̃, 0.0135 px."""
    xy, image = scene(0.4, seed=5, n=8000, noise=False)
    det = detect_particles(image, estimator="centroid", radius=1)
    dist, j = cKDTree(det.xy).query(xy, distance_upper_bound=1.0)
    ok = np.isfinite(dist)
    ok[ok] = det.clean[j[ok]]
    pl = peak_locking(det.xy[j[ok]])
    assert pl.n > 4000
    assert pl.locked()
    # The same statistic on the true positions moved by the analytic bias law (which
    # takes out the sampling noise of the amplitude estimate, ~0.003 px here).
    frac = xy[ok] - np.round(xy[ok])
    law = -np.exp(-2 * np.pi**2 * 0.4**2) / np.pi * np.sin(2 * np.pi * frac)
    expected = peak_locking(xy[ok] + law)
    assert pl.amplitude == pytest.approx(expected.amplitude, abs=0.002)
    assert (pl.amplitude > 0.008).all()


def test_threshold_cut_makes_the_noisy_centroid_peak_locked():
    """With noise the (I − T)₊ weights lock the centroid; the Gaussian fit does not."""
    xy, image = scene(0.75, seed=6, electrons=(700, 1200))
    centroid = peak_locking(matched(xy, detect_particles(image, estimator="centroid")))
    gauss = peak_locking(matched(xy, detect_particles(image, estimator="gauss")))
    assert centroid.locked(alpha=1e-6)
    assert not gauss.locked()


def test_the_default_detector_stays_flat_at_low_signal():
    """300-700 e⁻ per spot over 8 e⁻ of read noise (the dim wings of a laser sheet): a
    fit of ln I alone pulls towards pixel centres by ~0.008 px there; the refinement of
    isolated spots in linear intensity leaves them flat."""
    sensor = Sensor()  # no background light: read noise only
    found = []
    for seed in range(6):
        rng = np.random.default_rng(200 + seed)
        shape = (1000, 1200)
        xy = rng.uniform([3, 3], [shape[1] - 4, shape[0] - 4], size=(3000, 2))
        spots = render_particles(xy, 0.75, rng.uniform(300, 700, len(xy)), shape=shape)
        found.append(matched(xy, detect_particles(sensor.record(spots.image, rng))))
    pl = peak_locking(np.concatenate(found))
    assert pl.n > 15000
    assert not pl.locked()
    assert np.abs(pl.amplitude).max() < 0.005
