"""Calibration accuracy against truth: synthetic dots, true dot centres, the model error.

The Table 1 metric itself (:mod:`ptv.calibration.grid_errors`) needs no truth; here are
what only a rendered experiment knows: dot observations without images (exact
projections plus noise), the true dot centres (which add the plate's tilt, bow,
manufacturing and traverse errors, which no calibration built on nominal positions can
know; docs/errata.md E6 for the metric's mean of |Δ|).

Model error: random points inside the measurement volume are projected by the true
cameras without any detection noise and triangulated with the calibrations; it isolates
what the calibration model itself gets wrong.
"""

from collections.abc import Sequence

import numpy as np

from ptv.calibration.grid_errors import PositionErrors, TraverseDots
from ptv.camera_model import CameraModel
from ptv.triangulate import triangulate
from simulator.optics import Camera
from simulator.particles import Box
from simulator.target import PhysicalPlate


def synthetic_plane_dots(
    cameras: Sequence[Camera],
    plate: PhysicalPlate,
    *,
    noise_px: float,
    rng: np.random.Generator | int | None = None,
) -> list[list[TraverseDots]]:
    """Dot observations without images: exact projections plus Gaussian centre noise.

    Parameters
    ----------
    cameras : sequence of Camera
        The true cameras.
    plate : PhysicalPlate
        The plate and its traverse.
    noise_px : float
        Standard deviation of the dot-centre noise per image axis, px.
    rng : numpy.random.Generator, int or None
        Noise source.

    Returns
    -------
    list (per camera) of list (per plane) of TraverseDots
        Dots whose centre projects onto the sensor.
    """
    rng = np.random.default_rng(rng)
    indices = plate.design.indices
    out = []
    for camera in cameras:
        planes = []
        for j, pose in enumerate(plate.poses):
            xy = camera.project(plate.dot_centres(j))
            seen = np.isfinite(xy).all(axis=1)
            noisy = xy[seen] + rng.normal(0.0, noise_px, (int(seen.sum()), 2))
            planes.append(TraverseDots(pose.z_nominal, indices[seen], noisy, plate.design.pitch))
        out.append(planes)
    return out


def true_positions(plate: PhysicalPlate) -> np.ndarray:
    """True dot centres (tilt, bow, manufacturing and traverse errors), (N_Z, D, 3)."""
    return np.stack([plate.dot_centres(j) for j in range(len(plate.poses))])


def model_errors(
    calibrations: Sequence[CameraModel],
    cameras: Sequence[Camera],
    volume: Box,
    *,
    points: int = 2000,
    rng: np.random.Generator | int | None = None,
) -> PositionErrors:
    """Pure model error at random points of ``volume`` seen by every true camera.

    Parameters
    ----------
    calibrations : sequence of CameraModel
        The calibrations under test.
    cameras : sequence of Camera
        The true cameras, in the same order.
    volume : Box
        Where the points are drawn, m.
    points : int
        Number of points drawn.
    rng : numpy.random.Generator, int or None
        Point positions.

    Returns
    -------
    PositionErrors
    """
    truth = volume.sample(points, np.random.default_rng(rng))
    pixels = [camera.project(truth) for camera in cameras]
    seen = np.all([np.isfinite(p).all(axis=1) for p in pixels], axis=0)
    tri = triangulate(calibrations, [p[seen] for p in pixels])
    return PositionErrors(truth[seen], tri.points - truth[seen], np.full(int(seen.sum()), -1))
