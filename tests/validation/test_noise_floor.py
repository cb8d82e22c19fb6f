"""What dot-centre noise alone allows a calibration, from the true cameras."""

import numpy as np
import pytest

from simulator.rigs import load_rig
from simulator.target import PlateDesign, build_plate, traverse_positions
from validation.truth.noise_floor import (
    CUBIC_TERMS,
    model_error_floor,
    noise_floor,
    residual_floor,
)


@pytest.fixture(scope="module")
def dots():
    plate = build_plate(PlateDesign(), traverse_positions(), rng=0)
    return np.concatenate([plate.dot_centres(j) for j in (0, 6, 12)])


def test_the_noise_floor_is_linear_in_the_dot_noise(dots):
    cameras = load_rig("paper-stereo").cameras
    small, large = noise_floor(cameras, dots, 0.05), noise_floor(cameras, dots, 0.1)
    assert large.d == pytest.approx(2 * small.d, rel=1e-12)
    assert large.dots == small.dots == len(dots)
    # docs/calibration.md §8: 0.1 mm per pixel, about 160 µm of d per pixel of noise.
    assert small.object_pixel == pytest.approx(1e-4, rel=0.02)
    assert 140e-6 < small.d / 0.05 < 170e-6
    assert 0 < small.se_d < 0.02 * small.d


def test_the_residual_floor_is_that_of_a_least_squares_cubic_fit():
    rng = np.random.default_rng(1)
    u, v = np.meshgrid(np.linspace(-1, 1, 21), np.linspace(-1, 1, 21))
    u, v = u.ravel(), v.ravel()
    design = np.stack([u**i * v**j for i in range(4) for j in range(4 - i)], axis=1)
    assert design.shape[1] == CUBIC_TERMS
    noise = rng.normal(0.0, 0.05, (200, len(u), 2))
    fitted = design @ np.linalg.lstsq(design, noise.transpose(1, 0, 2).reshape(len(u), -1))[0]
    residual = noise.transpose(1, 0, 2).reshape(len(u), -1) - fitted
    rms = np.sqrt(np.mean(residual**2) * 2)
    assert rms == pytest.approx(residual_floor(0.05, [len(u)], CUBIC_TERMS), rel=0.01)


def test_the_model_error_floor_shrinks_with_more_dots_and_planes():
    z = np.linspace(-6e-3, 6e-3, 13)
    base = model_error_floor(8e-6, 441, z, CUBIC_TERMS)
    assert model_error_floor(8e-6, 4 * 441, z, CUBIC_TERMS) == pytest.approx(base / 2)
    assert model_error_floor(8e-6, 441, z[::6], CUBIC_TERMS) > base
    assert 0.3e-6 < base < 0.6e-6  # the prototype's 0.4 µm (docs/calibration.md §8)
