"""Camera: pinhole truth, refraction truth, visibility masks, bad input."""

import numpy as np
import pytest

from simulator.optics.camera import Camera
from simulator.optics.interfaces import flat_window
from simulator.optics.lens import Lens
from simulator.optics.placement import look_at_camera
from simulator.optics.rays import Rays

LENS = Lens(0.05, 5.5e-6)


def _straight_camera(window=None):
    """Camera at the origin looking along +Z, image x along +X, image y along +Y."""
    return Camera(np.zeros(3), np.eye(3), LENS, window)


def test_pinhole_projection_is_the_textbook_formula():
    cam = Camera(np.array([0.1, -0.2, -1.0]), np.eye(3), LENS)
    points = np.array([[0.1, -0.2, 0.0], [0.15, -0.18, 0.2], [0.05, -0.25, -0.1]])
    xy = cam.project(points)
    rel = points - cam.center
    fx = 0.05 / 5.5e-6
    expected = np.column_stack([fx * rel[:, 0] / rel[:, 2] + 1023.5,
                                fx * rel[:, 1] / rel[:, 2] + 543.5])
    assert xy.shape == (3, 2)
    np.testing.assert_allclose(xy, expected, atol=1e-9)


def test_refraction_at_a_perpendicular_window_matches_snell_by_hand():
    """Camera on the axis of a window normal to Z; a point in water at lateral offset ρ.
    Solve ρ = h_a tan θ_a + t tan θ_g + h_w tan θ_w with scipy's brentq (independent of
    the Newton code) and compare the pixel with f_x tan θ_a."""
    from scipy.optimize import brentq

    h_a, t, n_g, n_w = 0.5, 0.02, 1.52, 1.333
    cam = _straight_camera(flat_window([0, 0, 1.0], h_a, t, n_glass=n_g, n_water=n_w))
    rho, h_w = 0.03, 0.25
    point = np.array([[rho, 0.0, h_a + t + h_w]])

    def miss(theta):
        s = np.sin(theta)
        return (h_a * np.tan(theta) + t * np.tan(np.arcsin(s / n_g))
                + h_w * np.tan(np.arcsin(s / n_w)) - rho)

    theta = brentq(miss, 0.0, 0.5, xtol=1e-15)
    xy = cam.project(point)
    assert xy[0, 0] == pytest.approx(LENS.fx * np.tan(theta) + 1023.5, abs=1e-7)
    assert xy[0, 1] == pytest.approx(543.5, abs=1e-9)


def test_pixel_to_ray_without_window_is_the_pinhole_ray():
    cam = look_at_camera([0, 0, 0], LENS, distance=0.8, azimuth=0.4, elevation=0.1)
    xy = np.array([[0.0, 0.0], [1023.5, 543.5], [2047.0, 1087.0]])
    rays = cam.pixel_to_ray(xy)
    assert isinstance(rays, Rays)
    np.testing.assert_allclose(rays.origins, np.broadcast_to(cam.center, (3, 3)))
    # the centre pixel looks along the optical axis, towards the target
    np.testing.assert_allclose(rays.directions[1], cam.axis, atol=1e-15)
    np.testing.assert_allclose(cam.project(rays.point_at(0.8)), xy, atol=1e-8)


def test_invisible_points_are_nan_rows():
    window = flat_window([0, 0, 1.0], 0.3, 0.02)
    cam = _straight_camera(window)
    points = np.array(
        [
            [0.0, 0.0, 0.6],  # visible, in water
            [0.0, 0.0, -0.5],  # behind the camera (and on the air side)
            [0.0, 0.0, 0.2],  # in the air, in front of the window
            [0.0, 0.0, 0.31],  # inside the glass
            [2.0, 0.0, 0.6],  # in water, far off the sensor
        ]
    )
    xy = cam.project(points)
    assert np.isfinite(xy[0]).all() and np.isnan(xy[1:]).all()
    rich, visible = cam.project_visible(points)
    assert visible.tolist() == [True, False, False, False, False]
    np.testing.assert_array_equal(rich, xy)
    air_cam = _straight_camera()
    xy = air_cam.project(np.array([[0, 0, -1.0], [0, 0, 1.0], [1.0, 0, 0.0]]))
    assert np.isfinite(xy).all(axis=1).tolist() == [False, True, False]
    assert np.isnan(xy[[0, 2]]).all()


def test_totally_reflected_pixels_give_nan_rays():
    """A camera in water looking into air through glass: oblique pixels never get out."""
    stack = flat_window([0, 0, 1.0], 0.1, 0.01, n_air=1.333, n_glass=1.52, n_water=1.0)
    wide = Lens(0.01, 5.5e-6)  # ±29.4° horizontal field; critical angle water→air 48.6°
    cam = Camera(np.zeros(3), np.eye(3), wide, stack)
    tilted = Camera(np.zeros(3), _rotation_about_y(np.radians(40)), wide, stack)
    xy = np.array([[1023.5, 543.5], [0.0, 543.5], [2047.0, 543.5]])
    assert cam.pixel_to_ray(xy).valid.all()
    valid = tilted.pixel_to_ray(xy).valid
    # 40° + 29° > critical angle on one side only
    assert valid.sum() == 2 and not valid.all()


def _rotation_about_y(angle):
    c, s = np.cos(angle), np.sin(angle)
    # world → camera: camera axis = (sin, 0, cos) in world
    return np.array([[c, 0, -s], [0, 1, 0], [s, 0, c]])


@pytest.mark.parametrize(
    ("bad", "match"),
    [
        (np.array([[0.0, 0.0, np.nan]]), r"finite.*nan"),
        (np.array([[0.0, np.inf, 1.0]]), r"finite.*inf"),
        (np.zeros((3, 2)), r"shape \(N, 3\)"),
    ],
)
def test_project_rejects_bad_points(bad, match):
    with pytest.raises(ValueError, match=match):
        _straight_camera().project(bad)


def test_pixel_to_ray_rejects_bad_pixels():
    with pytest.raises(ValueError, match=r"pixel coordinates.*nan"):
        _straight_camera().pixel_to_ray(np.array([[np.nan, 1.0]]))
    with pytest.raises(ValueError, match=r"shape \(N, 2\)"):
        _straight_camera().pixel_to_ray(np.zeros(2))


def test_bad_camera_parameters_raise():
    with pytest.raises(ValueError, match="rotation"):
        Camera(np.zeros(3), 2 * np.eye(3), LENS)
    with pytest.raises(ValueError, match="rotation"):
        Camera(np.zeros(3), np.diag([1.0, 1.0, -1.0]), LENS)
    with pytest.raises(ValueError, match="center"):
        Camera(np.array([0, np.nan, 0]), np.eye(3), LENS)
    with pytest.raises(ValueError, match="camera side"):
        Camera(np.array([0, 0, 0.5]), np.eye(3), LENS, flat_window([0, 0, 1.0], 0.3, 0.02))
