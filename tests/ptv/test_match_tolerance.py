"""The matching tolerance measured on the rig and the data, against cameras known exactly.

The cameras here are ideal pinholes in air written for the test (no refraction, no
distortion), so that the pixel footprint has a closed form and a calibration error can
be put in by hand.
"""

from types import SimpleNamespace

import numpy as np
import pytest

from ptv.matching.stereo import match
from ptv.matching.tolerance import (
    PIXEL_FLOOR,
    SPREAD_PER_MEDIAN,
    match_tolerance,
    pixel_footprint,
)

FOCAL = 0.05  # m
PITCH = 5.5e-6  # m
SIZE = (2048, 2048)
DISTANCE = 1.0  # m, camera to the volume's centre
VOLUME = ((-0.05, -0.05, -0.05), (0.05, 0.05, 0.05))


class AirPinhole:
    """An ideal pinhole camera at ``position`` looking at the origin."""

    def __init__(self, position):
        self.position = np.asarray(position, dtype=np.float64)
        axis = -self.position / np.linalg.norm(self.position)
        x = np.cross([0.0, 1.0, 0.0], axis)
        x /= np.linalg.norm(x)
        self.rotation = np.stack([x, np.cross(axis, x), axis])  # rows: camera x, y, z
        self.centre = 0.5 * np.asarray(SIZE, dtype=np.float64)

    def project(self, points):
        local = (np.atleast_2d(points) - self.position) @ self.rotation.T
        xy = FOCAL / PITCH * local[:, :2] / local[:, 2:3] + self.centre
        inside = (local[:, 2] > 0) & np.all((xy >= 0) & (xy <= SIZE), axis=1)
        return np.where(inside[:, None], xy, np.nan)

    def pixel_to_ray(self, xy):
        local = np.column_stack(
            [(np.atleast_2d(xy) - self.centre) * PITCH / FOCAL, np.ones(len(np.atleast_2d(xy)))]
        )
        directions = local @ self.rotation
        directions /= np.linalg.norm(directions, axis=1, keepdims=True)
        return SimpleNamespace(
            origins=np.broadcast_to(self.position, directions.shape).copy(),
            directions=directions,
        )


def three_cameras():
    angle = np.radians(30.0)
    return [
        AirPinhole(DISTANCE * np.array([np.sin(a) * c, s, np.cos(a) * c]))
        for a, s, c in ((-angle, 0.0, 1.0), (angle, 0.0, 1.0), (0.0, np.sin(angle), np.cos(angle)))
    ]


def test_the_pixel_footprint_is_the_pinhole_s_closed_form():
    # At the principal point, the ray of the next pixel is atan(pitch / f) off the axis:
    # its distance from the axis point at D is D·pitch/√(f² + pitch²).
    expected = DISTANCE * PITCH / np.hypot(FOCAL, PITCH)
    assert pixel_footprint(three_cameras(), VOLUME) == pytest.approx(expected, rel=1e-6)


def frames(cameras, rng, *, n=400, count=3, noise=0.05, error=None):
    """Detections of ``count`` frames of n particles, unshuffled (row i: particle i),
    with pixel noise and, on the last camera, a smooth error of the calibration."""
    out = []
    for _ in range(count):
        points = rng.uniform(-0.04, 0.04, (n, 3))
        per_camera = []
        for c, cam in enumerate(cameras):
            xy = cam.project(points) + rng.normal(0.0, noise, (n, 2))
            if error is not None and c == len(cameras) - 1:
                xy = xy + error * np.sin(2 * np.pi * xy[:, ::-1] / SIZE[0])
            per_camera.append(xy)
        out.append(per_camera)
    return out


def matched_fraction(cameras, detections, tolerance):
    """Particles matched in all cameras with their own detections, over all frames."""
    right = total = 0
    for xy in detections:
        m = match(cameras, xy, VOLUME, tolerance=tolerance, min_cameras=len(cameras))
        right += np.sum(np.all(m.indices == m.indices[:, :1], axis=1))
        total += len(xy[0])
    return right / total


def test_a_good_calibration_is_matched_at_the_pixel_floor():
    cameras = three_cameras()
    measured = match_tolerance(
        cameras, frames(cameras, np.random.default_rng(1)), VOLUME, min_cameras=3
    )
    assert measured.tolerance == pytest.approx(PIXEL_FLOOR * measured.pixel_footprint)
    assert measured.iterations == 1
    assert measured.median_ray_distance < measured.tolerance / SPREAD_PER_MEDIAN


def test_a_poor_calibration_gets_the_tolerance_its_errors_need():
    # One camera's pixels are off by up to 4 px (a poor fit): at the pixel floor most
    # particles are lost; the measured tolerance finds what any wider one finds. (A wider
    # one finds no more: the few particles left are lost to wrong triplets that the
    # calibration error makes cheaper than the right ones, at any tolerance.)
    cameras = three_cameras()
    detections = frames(cameras, np.random.default_rng(2), error=4.0)
    measured = match_tolerance(cameras, detections, VOLUME, min_cameras=3)
    floor = PIXEL_FLOOR * measured.pixel_footprint
    widest = matched_fraction(cameras, detections, 5 * measured.tolerance)
    assert widest > 0.8
    assert matched_fraction(cameras, detections, floor) < 0.5 * widest
    assert measured.tolerance > 3 * floor
    assert matched_fraction(cameras, detections, measured.tolerance) >= 0.99 * widest


def test_no_match_at_all_is_an_error_that_names_the_calibration():
    cameras = three_cameras()
    rng = np.random.default_rng(3)
    unrelated = [[rng.uniform(0, 2048, (50, 2)) for _ in cameras] for _ in range(2)]
    with pytest.raises(ValueError, match=r"no particle matched .* calibration is of this rig"):
        match_tolerance(cameras, unrelated, VOLUME, min_cameras=3)


def test_a_camera_that_misses_the_volume_is_named():
    cameras = three_cameras()
    away = ((0.9, 0.9, 0.9), (1.0, 1.0, 1.0))
    with pytest.raises(ValueError, match="camera 0 does not image the centre"):
        pixel_footprint(cameras, away)
