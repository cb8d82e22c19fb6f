"""look_at_camera: pose, upright image, window geometry."""

import numpy as np
import pytest

from simulator.optics.lens import Lens
from simulator.optics.placement import WindowSpec, look_at_camera

LENS = Lens(0.05, 5.5e-6, principal_point=(1000.0, 500.0))
TARGET = np.array([0.01, -0.02, 0.005])


@pytest.mark.parametrize("obliquity_deg", [0.0, 12.0])
@pytest.mark.parametrize("direction", [0.0, np.pi / 4])
def test_target_images_at_the_principal_point(obliquity_deg, direction):
    window = WindowSpec(0.25, 0.015, np.radians(obliquity_deg), direction)
    cam = look_at_camera(TARGET, LENS, distance=0.9, azimuth=np.radians(-35),
                         elevation=np.radians(5), window=window)
    xy = cam.project(TARGET[None, :])
    np.testing.assert_allclose(xy[0], LENS.principal_point, atol=1e-8)


def test_pose_follows_azimuth_and_elevation():
    az, el = np.radians(30), np.radians(-10)
    cam = look_at_camera(TARGET, LENS, distance=0.7, azimuth=az, elevation=el)
    u = np.array([np.cos(el) * np.sin(az), np.sin(el), np.cos(el) * np.cos(az)])
    np.testing.assert_allclose(cam.center, TARGET + 0.7 * u, atol=1e-15)
    np.testing.assert_allclose(cam.axis, -u, atol=1e-15)


def test_image_is_upright_with_rows_along_world_y():
    cam = look_at_camera(TARGET, LENS, distance=0.7, azimuth=np.radians(40),
                         elevation=np.radians(8))
    x_axis, y_axis = cam.rotation[0], cam.rotation[1]
    assert x_axis[1] == pytest.approx(0.0, abs=1e-15)  # image x horizontal
    assert y_axis[1] < -0.99  # image y (rows, down) along −Y
    # a point above the target images on an earlier row
    xy = cam.project(np.array([TARGET, TARGET + np.array([0, 0.01, 0])]))
    assert xy[1, 1] < xy[0, 1]
    # straight on from +Z, image x runs along +X
    front = look_at_camera(TARGET, LENS, distance=0.7, azimuth=0.0)
    xy = front.project(np.array([TARGET, TARGET + np.array([0.01, 0, 0])]))
    assert xy[1, 0] > xy[0, 0]


def test_window_geometry():
    az = np.radians(30)
    spec = WindowSpec(0.2, 0.012, np.radians(15), 0.0)
    cam = look_at_camera(TARGET, LENS, distance=0.9, azimuth=az, window=spec)
    stack = cam.interfaces
    line = (TARGET - cam.center) / np.linalg.norm(TARGET - cam.center)
    assert np.degrees(np.arccos(stack.normal @ line)) == pytest.approx(15.0, abs=1e-10)
    assert stack.normal[1] == pytest.approx(0.0, abs=1e-15)  # tilted in the horizontal plane
    np.testing.assert_allclose(np.diff(stack.offsets), [0.012])
    # the wet face crosses the line of sight water_path before the target
    wet_hit = TARGET - 0.2 * line
    assert stack.normal @ wet_hit == pytest.approx(stack.offsets[-1], abs=1e-15)
    diagonal = look_at_camera(TARGET, LENS, distance=0.9, azimuth=az,
                              window=WindowSpec(0.2, 0.012, np.radians(15), np.pi / 4))
    tilt = diagonal.interfaces.normal - (diagonal.interfaces.normal @ line) * line
    frame_x = np.cross([0, 1.0, 0], line)
    frame_x /= np.linalg.norm(frame_x)  # the nominal image x (horizontal, ⊥ line)
    cos_to_x = tilt @ frame_x / np.linalg.norm(tilt)
    assert abs(cos_to_x) == pytest.approx(np.cos(np.pi / 4), abs=1e-12)


def test_bad_placements_raise():
    with pytest.raises(ValueError, match="does not fit"):
        look_at_camera(TARGET, LENS, distance=0.2, azimuth=0.0, window=WindowSpec(0.25))
    with pytest.raises(ValueError, match="parallel to the up vector"):
        look_at_camera(TARGET, LENS, distance=0.5, azimuth=0.0, elevation=np.pi / 2)
    with pytest.raises(ValueError, match="water_path"):
        WindowSpec(-0.1)
    with pytest.raises(ValueError, match="distance"):
        look_at_camera(TARGET, LENS, distance=-1.0, azimuth=0.0)
