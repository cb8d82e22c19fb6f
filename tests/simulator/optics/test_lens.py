"""Lens model: OpenCV cross-checks, tilted-sensor geometry, undistortion, validation."""

import cv2
import numpy as np
import pytest

from simulator.optics.lens import Lens, radial_fold, tilt_from_normal, undistort


def _lens(**kw):
    base = dict(focal_length=0.05, pixel_pitch=5.5e-6, k1=-0.8, k2=3.0, k3=-10.0, p1=4e-4,
                p2=-3e-4, tau_x=0.03, tau_y=-0.05, principal_point=(1030.2, 540.7))
    base.update(kw)
    return Lens(**base)


def _normalized_grid(n=15, half=0.12):
    g = np.linspace(-half, half, n)
    x, y = np.meshgrid(g, 0.55 * g)
    return np.column_stack([x.ravel(), y.ravel()])


def test_normalized_to_pixel_matches_opencv_project_points():
    lens = _lens()
    xn = _normalized_grid()
    xy, valid = lens.normalized_to_pixel(xn)
    assert valid.all()
    obj = np.column_stack([xn, np.ones(len(xn))])
    ref, _ = cv2.projectPoints(obj, np.zeros(3), np.zeros(3), lens.camera_matrix(),
                               lens.opencv_dist_coeffs())
    np.testing.assert_allclose(xy, ref.reshape(-1, 2), atol=1e-8)


def test_pixel_to_normalized_matches_opencv_undistort_points():
    lens = _lens()
    xn = _normalized_grid()
    xy, _ = lens.normalized_to_pixel(xn)
    back = lens.pixel_to_normalized(xy)
    np.testing.assert_allclose(back, xn, atol=1e-13)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-15)
    ref = cv2.undistortPoints(xy.reshape(-1, 1, 2), lens.camera_matrix(),
                              lens.opencv_dist_coeffs(), criteria=crit)
    np.testing.assert_allclose(back, ref.reshape(-1, 2), atol=1e-7)


def test_tilted_sensor_is_the_chief_ray_hit_on_a_tilted_plane():
    """Pixel = in-plane coordinates of the ray's hit on the plane R(τ) through (0, 0, c)."""
    tau_x, tau_y = 0.04, -0.07
    lens = Lens(0.05, 5.5e-6, tau_x=tau_x, tau_y=tau_y, image_distance=0.0532)
    cx_, sx_, cy_, sy_ = np.cos(tau_x), np.sin(tau_x), np.cos(tau_y), np.sin(tau_y)
    rot = np.array([[cy_, 0, -sy_], [0, 1, 0], [sy_, 0, cy_]]) @ np.array(
        [[1, 0, 0], [0, cx_, sx_], [0, -sx_, cx_]])
    xn = _normalized_grid(7, 0.1)
    xy, valid = lens.normalized_to_pixel(xn)
    assert valid.all()
    c = lens.image_distance
    u = (xy[:, 0] - lens.principal_point[0]) * lens.pixel_pitch
    v = (xy[:, 1] - lens.principal_point[1]) * lens.pixel_pitch
    on_sensor = np.array([0, 0, c]) + u[:, None] * rot[0] + v[:, None] * rot[1]
    assert np.allclose(on_sensor @ rot[2], c * rot[2, 2])  # on the tilted plane
    rays = np.column_stack([xn, np.ones(len(xn))])
    cross = np.cross(on_sensor, rays)
    assert np.max(np.linalg.norm(cross, axis=1)) < 1e-15  # collinear with the chief ray


def test_tilt_from_normal_inverts_the_normal():
    lens = Lens(0.05, 5.5e-6, tau_x=0.1, tau_y=-0.2)
    from simulator.optics.lens import sensor_normal

    tx, ty = tilt_from_normal(sensor_normal(lens.tau_x, lens.tau_y))
    assert tx == pytest.approx(0.1, abs=1e-15) and ty == pytest.approx(-0.2, abs=1e-15)


def test_pinhole_without_distortion_is_the_textbook_formula():
    lens = Lens(0.035, 4.8e-6, sensor_size=(1024, 768))
    xn = _normalized_grid(5, 0.05)
    xy, valid = lens.normalized_to_pixel(xn)
    assert valid.all()
    fx = 0.035 / 4.8e-6
    np.testing.assert_allclose(xy[:, 0], fx * xn[:, 0] + 511.5, atol=1e-9)
    np.testing.assert_allclose(xy[:, 1], fx * xn[:, 1] + 383.5, atol=1e-9)


def test_radial_fold_is_where_the_radial_map_turns():
    k1, k2, k3 = -0.6, 0.1, 0.0
    q = radial_fold(k1, k2, k3)
    r = np.sqrt(q)
    deriv = 1 + 3 * k1 * r**2 + 5 * k2 * r**4 + 7 * k3 * r**6
    assert abs(deriv) < 1e-12
    assert radial_fold(0.1, 0.0, 0.0) == np.inf


def test_points_beyond_the_fold_are_invalid_and_not_inverted():
    lens = Lens(0.01, 5.5e-6, k1=-0.6)
    r_fold = np.sqrt(radial_fold(-0.6, 0, 0))
    xn = np.array([[0.5 * r_fold, 0.0], [1.2 * r_fold, 0.0]])
    xy, valid = lens.normalized_to_pixel(xn)
    assert valid.tolist() == [True, False]
    assert np.isnan(xy[1]).all()
    # a distorted radius above the fold's maximum has no preimage
    beyond = np.array([[1.01 * r_fold * (1 - 0.6 * r_fold**2), 0.0]])
    assert np.isnan(undistort(beyond, -0.6, 0, 0, 0, 0)).all()


def test_on_sensor_bounds():
    lens = Lens(0.05, 5.5e-6, sensor_size=(100, 50))
    xy = np.array([[-0.5, -0.5], [99.5, 49.5], [-0.51, 0], [0, 49.51], [np.nan, 1]])
    assert lens.on_sensor(xy).tolist() == [True, True, False, False, False]


@pytest.mark.parametrize(
    ("kw", "name"),
    [
        (dict(focal_length=-0.05), "focal_length"),
        (dict(focal_length=0.0), "focal_length"),
        (dict(pixel_pitch=np.nan), "pixel_pitch"),
        (dict(f_number=0.0), "f_number"),
        (dict(sensor_size=(0, 10)), "sensor_size"),
        (dict(k1=np.inf), "k1"),
        (dict(tau_x=1.0), "tau_x"),
        (dict(image_distance=-1.0), "image_distance"),
        (dict(principal_point=(np.nan, 1.0)), "principal_point"),
    ],
)
def test_bad_lens_parameters_raise_naming_them(kw, name):
    base = dict(focal_length=0.05, pixel_pitch=5.5e-6)
    base.update(kw)
    with pytest.raises(ValueError, match=name):
        Lens(**base)


def test_focus_distance_is_gauss_conjugate():
    lens = Lens(0.05, 5.5e-6, image_distance=0.0525)
    assert 1 / lens.focus_distance + 1 / 0.0525 == pytest.approx(1 / 0.05, rel=1e-14)
    assert Lens(0.05, 5.5e-6).focus_distance == np.inf
