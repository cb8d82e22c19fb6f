"""Plate self-calibration on the simulator's plate: each dot's manufacturing offset,
which the simulator drew and knows, recovered from dots seen through refracting windows.

The paper-stereo rig's two cameras see a plate whose dots scatter by 10 µm about the
grid at five traverse positions; the dot centres carry 0.05 px of noise, about 5 µm in
the plate (0.1 mm per pixel), so each dot, seen in 10 views, is known to ~1.6 µm per
axis. A cubic in the grid indices is absorbed by the plane maps and is removed from the
truth before comparing.
"""

import numpy as np
import pytest

from ptv.calibration.plate_offsets import estimate_plate_offsets
from simulator.rigs import load_rig
from simulator.target import Imperfections, PlateDesign, build_plate, traverse_positions
from validation.truth.calibration_errors import synthetic_plane_dots

SCATTER = 10e-6
NOISE_PX = 0.05
#: One pixel in the plate (0.1 mm) times the noise, over √(2 cameras × 5 positions).
PER_DOT_SIGMA = NOISE_PX * 1e-4 / np.sqrt(10)


@pytest.fixture(scope="module")
def observed():
    plate = build_plate(
        PlateDesign(),
        traverse_positions(5, 2e-3),
        imperfections=Imperfections(dot_position_std=SCATTER),
        rng=3,
    )
    rig = load_rig("paper-stereo")
    dots = synthetic_plane_dots(rig.cameras, plate, noise_px=NOISE_PX, rng=4)
    return plate, dict(zip(("a", "b"), dots, strict=True))


def test_each_dots_manufacturing_offset_is_recovered(observed):
    plate, dots = observed
    estimate = estimate_plate_offsets(dots, mode="dots")
    indices = plate.design.indices
    truth = plate.dot_xy - indices * plate.design.pitch
    scale = np.abs(indices).max()
    i, j = indices[:, 0] / scale, indices[:, 1] / scale
    design = np.stack([i**a * j**b for a in range(4) for b in range(4 - a)], 1)
    for c in range(2):
        truth[:, c] -= design @ np.linalg.lstsq(design, truth[:, c], rcond=None)[0]
    assert len(estimate.indices) == len(indices)  # every dot seen in every view
    error = estimate.of(indices) - truth
    assert np.sqrt(np.mean(error**2)) < 2 * PER_DOT_SIGMA
    # What the plane maps could not absorb was mostly the plate: the residual drops to
    # the centre noise (√2 · 5 µm in the plane, less what the maps and offsets fit).
    assert estimate.rms_after_m < 0.6 * estimate.rms_before_m
