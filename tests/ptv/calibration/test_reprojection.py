"""How well each plate image calibrated: reprojection RMS and the plane-fit warning."""

import numpy as np
import pytest

from ptv.calibration.grid_errors import TraverseDots
from ptv.calibration.model_free import calibrate_model_free
from ptv.calibration.reprojection import (
    PLANE_RESIDUAL_LIMIT_PX,
    large_plane_residual,
    reprojection_rms,
)

PITCH = 5e-3
SIZE = (640, 480)
GRID = np.array([(i, j) for i in range(-5, 6) for j in range(-4, 5)])


class _Telecentric:
    """A camera of 10 px/mm looking down Z: pixel = centre + 1e4 · (X, Y)."""

    def project(self, points):
        return np.array([320.0, 240.0]) + 1e4 * np.asarray(points)[:, :2]


def _plane(z, shift=None):
    pixels = _Telecentric().project(np.column_stack([GRID * PITCH, np.zeros(len(GRID))]))
    if shift is not None:
        pixels = pixels + shift
    return TraverseDots(z, GRID, pixels, PITCH)


def test_the_rms_is_the_dots_displacement_from_their_projection():
    rng = np.random.default_rng(1)
    angle = rng.uniform(0, 2 * np.pi, len(GRID))
    shift = 0.3 * np.column_stack([np.cos(angle), np.sin(angle)])  # every dot 0.3 px off
    assert reprojection_rms(_Telecentric(), _plane(0.0)) == pytest.approx(0.0, abs=1e-12)
    assert reprojection_rms(_Telecentric(), _plane(0.0, shift)) == pytest.approx(0.3)


def test_a_dot_off_the_plane_fit_is_named_and_an_exact_grid_is_not():
    planes = [_plane(0.0), _plane(-5e-3)]
    exact = calibrate_model_free([p.observation() for p in planes], SIZE)
    assert large_plane_residual("cam1", exact, planes, ["a.tif", "b.tif"]) is None
    shift = np.zeros((len(GRID), 2))
    moved = int(np.flatnonzero((GRID == (2, 1)).all(axis=1))[0])
    shift[moved] = (4.0 * PLANE_RESIDUAL_LIMIT_PX, 0.0)  # a dot indexed on a blend
    planes[1] = _plane(-5e-3, shift)
    spoilt = calibrate_model_free([p.observation() for p in planes], SIZE)
    warning = large_plane_residual("cam1", spoilt, planes, ["a.tif", "b.tif"])
    assert warning.startswith("cam1: the cubic plane fit of b.tif misses dot (2, 1) by")
    assert "other image" not in warning
