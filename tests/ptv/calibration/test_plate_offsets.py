"""Plate self-calibration: printing errors of a plate recovered from its views.

Two perspective cameras with radial distortion (written out here) see a plate whose
columns and rows are off the 5 mm grid by ~80 µm at three traverse positions; the dots'
images carry 0.02 px of noise (1.2 µm in the plate at 62 µm per pixel). A polynomial of
degree 3 in the grid index is absorbed by the cubic plane maps, so the truth is compared
with that part removed.
"""

import numpy as np
import pytest

from ptv.calibration.grid_errors import TraverseDots
from ptv.calibration.plate_offsets import estimate_plate_offsets

PITCH = 0.005
NOISE_PX = 0.02


def _camera(yaw: float, k1: float):
    """A pinhole camera 0.5 m from the origin looking at it, f = 8000 px, distortion k1."""
    cx, sx, cy, sy = np.cos(0.05), np.sin(0.05), np.cos(yaw), np.sin(yaw)
    rotation = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]]) @ np.array(
        [[1, 0, 0], [0, cx, -sx], [0, sx, cx]]
    )
    centre = -0.5 * rotation[:, 2]

    def project(points: np.ndarray) -> np.ndarray:
        local = (points - centre) @ rotation
        x, y = local[:, 0] / local[:, 2], local[:, 1] / local[:, 2]
        factor = 1 + k1 * (x * x + y * y)
        return np.column_stack([8000 * x * factor + 1024, 8000 * y * factor + 544])

    return project


def _without_cubic(values: np.ndarray, index: np.ndarray) -> np.ndarray:
    design = np.stack([(index / 10.0) ** a for a in range(4)], 1)
    coef, *_ = np.linalg.lstsq(design, values, rcond=None)
    return values - design @ coef


@pytest.fixture(scope="module")
def plate():
    rng = np.random.default_rng(0)
    ii, jj = np.meshgrid(np.arange(-10, 11), np.arange(-7, 8), indexing="xy")
    indices = np.column_stack([ii.ravel(), jj.ravel()])
    column_dx, row_dy = rng.normal(0, 80e-6, 21), rng.normal(0, 80e-6, 15)
    dot_xy = rng.normal(0, 20e-6, (len(indices), 2))
    return indices, column_dx, row_dy, dot_xy


def _views(plate, *, per_dot: bool, seed: int = 1):
    indices, column_dx, row_dy, dot_xy = plate
    rng = np.random.default_rng(seed)
    offsets = np.column_stack([column_dx[indices[:, 0] + 10], row_dy[indices[:, 1] + 7]])
    if per_dot:
        offsets = dot_xy
    dots = {}
    for name, project in {"a": _camera(0.5, -0.2), "b": _camera(-0.5, 0.1)}.items():
        dots[name] = []
        for z in (-0.005, 0.0, 0.005):
            world = np.column_stack([indices * PITCH + offsets, np.full(len(indices), z)])
            pixels = project(world) + rng.normal(0, NOISE_PX, (len(indices), 2))
            dots[name].append(TraverseDots(z, indices, pixels, PITCH))
    return dots


def test_column_and_row_offsets_are_recovered(plate):
    _, column_dx, row_dy, _ = plate
    estimate = estimate_plate_offsets(_views(plate, per_dot=False))
    columns, rows = np.arange(-10, 11), np.arange(-7, 8)
    got_dx = estimate.of(np.column_stack([columns, np.zeros_like(columns)]))[:, 0]
    got_dy = estimate.of(np.column_stack([np.zeros_like(rows), rows]))[:, 1]
    # Each column is seen 90 times (15 rows × 6 views): its noise 0.13 µm; the cubic
    # maps' misfit of a distorted perspective view adds under 1 µm.
    np.testing.assert_allclose(got_dx, _without_cubic(column_dx, columns), atol=2e-6)
    np.testing.assert_allclose(got_dy, _without_cubic(row_dy, rows), atol=2e-6)
    # What the maps could not absorb was the plate: the residual falls to the noise.
    assert estimate.rms_before_m > 20e-6
    assert estimate.rms_after_m < 3 * np.sqrt(2) * NOISE_PX * 62e-6


def test_per_dot_offsets_are_recovered(plate):
    indices, *_, dot_xy = plate
    estimate = estimate_plate_offsets(_views(plate, per_dot=True), mode="dots")
    truth = dot_xy.copy()
    i, j = indices[:, 0] / 10, indices[:, 1] / 10
    design = np.stack([i**a * j**b for a in range(4) for b in range(4 - a)], 1)
    for c in range(2):
        truth[:, c] -= design @ np.linalg.lstsq(design, truth[:, c], rcond=None)[0]
    # One dot in 6 views: 1.2/√6 ≈ 0.5 µm of noise per axis. The cubic maps' misfit of a
    # distorted perspective view, largest at the plate's corners, is no longer averaged
    # over a column: up to ~4 µm there.
    error = estimate.of(indices) - truth
    assert np.sqrt(np.mean(error**2)) < 1.5e-6
    assert np.abs(error).max() < 5e-6


def test_corrected_dots_carry_the_offsets(plate):
    dots = _views(plate, per_dot=False)
    estimate = estimate_plate_offsets(dots)
    corrected = estimate.corrected(dots)
    first = corrected["a"][0]
    np.testing.assert_allclose(
        first.observation().world_xy, first.indices * PITCH + estimate.of(first.indices)
    )
    grid = estimate.positions(first.indices, [0.0, 0.001])
    np.testing.assert_allclose(grid[1, :, :2], first.observation().world_xy)
    np.testing.assert_allclose(grid[1, :, 2], 0.001)


def test_bad_mode_and_too_few_columns(plate):
    dots = _views(plate, per_dot=False)
    with pytest.raises(ValueError, match="mode must be one of"):
        estimate_plate_offsets(dots, mode="columns")
    narrow = {
        name: [TraverseDots(d.z, d.indices[:60], d.pixels[:60], PITCH) for d in planes]
        for name, planes in dots.items()
    }  # the first 60 dots: rows -7 to -5 only
    with pytest.raises(ValueError, match="rows seen"):
        estimate_plate_offsets(narrow)
