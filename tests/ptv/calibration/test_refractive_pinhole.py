"""A pinhole behind a flat window: the refraction against the simulator's independent
ray optics (its forward Newton in tan θ and its plane-by-plane tracer), the round trip,
the fit, the file and bad windows."""

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ptv.calibration.io import load_calibrations, save_calibrations
from ptv.calibration.pinhole import PinholeCalibration, PinholeModel
from ptv.calibration.refractive_pinhole import (
    FlatWindow,
    RefractivePinholeCalibration,
    air_directions,
    fit_refractive_pinhole,
    window_rays,
)
from simulator.optics.forward import solve_chief_rays
from simulator.optics.interfaces import FlatInterfaces, back_project

SIZE = (1280, 1024)


def simulator_stack(window: FlatWindow) -> FlatInterfaces:
    """The same window in the simulator's convention (normal toward the water, planes
    in the order a ray meets them)."""
    return FlatInterfaces(
        normal=-window.normal,
        offsets=[-(window.distance + window.thickness), -window.distance],
        indices=window.indices,
    )


@st.composite
def scenes(draw):
    """A window of any tilt, a camera outside it and points in the medium."""
    tilt = np.radians(draw(st.floats(0.0, 40.0)))
    turn = draw(st.floats(0.0, 2 * np.pi))
    normal = np.array([np.sin(tilt) * np.cos(turn), np.sin(tilt) * np.sin(turn), np.cos(tilt)])
    window = FlatWindow(
        normal,
        draw(st.floats(-0.1, 0.1)),
        draw(st.floats(0.0, 0.03)),
        draw(st.floats(1.4, 1.7)),
        draw(st.floats(1.0, 1.6)),
    )
    lateral = np.array(draw(st.tuples(*[st.floats(-0.2, 0.2)] * 3)))
    lateral -= (lateral @ normal) * normal
    centre = (window.distance + window.thickness + draw(st.floats(0.05, 1.0))) * normal + lateral
    count = draw(st.integers(1, 20))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    sideways = rng.uniform(-0.3, 0.3, (count, 3))
    sideways -= np.outer(sideways @ normal, normal)
    depth = rng.uniform(1e-4, 0.4, count)
    points = (window.distance - depth)[:, None] * normal + sideways
    return window, centre, points


@settings(max_examples=200, deadline=None)
@given(scene=scenes())
def test_air_directions_agree_with_the_simulators_forward_solver(scene):
    window, centre, points = scene
    reference = solve_chief_rays(centre, points, simulator_stack(window))
    assert reference.valid.all()
    np.testing.assert_allclose(
        air_directions(centre, points, window), reference.directions, rtol=0, atol=1e-9
    )


@settings(max_examples=200, deadline=None)
@given(scene=scenes())
def test_rays_into_the_medium_agree_with_the_simulators_tracer(scene):
    window, centre, points = scene
    directions = points - centre
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    origins = np.broadcast_to(centre, directions.shape)
    ours = window_rays(centre, directions, window)
    reference = back_project(origins, directions, simulator_stack(window))
    np.testing.assert_allclose(ours.origins, reference.origins, rtol=0, atol=1e-12)
    np.testing.assert_allclose(ours.directions, reference.directions, rtol=0, atol=1e-12)


def camera_behind(window: FlatWindow, centre, aim) -> RefractivePinholeCalibration:
    """A distorted pinhole at ``centre`` looking at ``aim`` through ``window``."""
    centre, aim = np.asarray(centre, float), np.asarray(aim, float)
    z = (aim - centre) / np.linalg.norm(aim - centre)
    x = np.cross([0.0, 1.0, 0.0], z)
    x /= np.linalg.norm(x)
    rot = np.array([x, np.cross(z, x), z])
    params = np.zeros(17)
    params[:8] = 5800.0, 5810.0, 655.0, 500.0, -0.1, 0.2, 3e-4, -2e-4
    params[11:14] = cv2.Rodrigues(rot)[0].ravel()
    params[14:17] = -rot @ centre
    pinhole = PinholeCalibration(SIZE, PinholeModel(), params, 0.0, "truth")
    return RefractivePinholeCalibration(pinhole, window)


WINDOW = FlatWindow([0.0, 0.0, 1.0], 0.03, 0.01, 1.49, 1.33)


def reference_pixels(camera: RefractivePinholeCalibration, points: np.ndarray) -> np.ndarray:
    """Pixels through the window by the simulator's forward solver and OpenCV's
    projection (no code of the model under test)."""
    centre = camera.centre
    directions = solve_chief_rays(centre, points, simulator_stack(camera.window)).directions
    p = camera.params
    xy, _ = cv2.projectPoints(
        centre + directions, p[11:14], p[14:17], camera.pinhole.camera_matrix,
        p[[4, 5, 6, 7, 8]],
    )  # fmt: skip
    return xy.reshape(-1, 2)


@settings(max_examples=100, deadline=None)
@given(
    x=st.floats(-0.15, 0.15), y=st.floats(-0.15, 0.15), height=st.floats(0.2, 0.8),
    pixels=st.lists(st.tuples(st.floats(0, 1279), st.floats(0, 1023)), min_size=1,
                    max_size=10),
    depth=st.floats(1e-3, 0.3),
)  # fmt: skip
def test_a_pixels_ray_projects_back_onto_the_pixel(x, y, height, pixels, depth):
    camera = camera_behind(WINDOW, (x, y, height), (0.0, 0.0, -0.05))
    xy = np.array(pixels)
    rays = camera.pixel_to_ray(xy)
    ok = rays.valid
    points = rays.origins[ok] + depth * rays.directions[ok]
    np.testing.assert_allclose(camera.project(points), xy[ok], rtol=0, atol=1e-6)
    np.testing.assert_allclose(reference_pixels(camera, points), xy[ok], rtol=0, atol=1e-6)


def stepped_target() -> np.ndarray:
    """73 points on three levels 8 mm apart, as OpenPTV's test_cavity target, m."""
    rows = [(25, 8), (-25, 8), (15, 0), (-15, 0), (0, -8)]
    return np.array([(x, y, z) for y, z in rows for x in range(-35, 35, 5)], float) * 1e-3


def test_a_camera_behind_a_window_is_fitted_to_its_exact_pixels():
    truth = camera_behind(WINDOW, (0.08, 0.02, 0.57), (0.0, 0.0, 0.0))
    points = stepped_target()
    pixels = reference_pixels(truth, points)
    # The straight-ray start errs by tens of mm in the centre (the refraction is folded
    # into its focal length and distortion).
    straight = cv2.calibrateCamera(
        [points.astype(np.float32)], [pixels.astype(np.float32)], SIZE,
        truth.pinhole.camera_matrix, np.zeros(5), flags=cv2.CALIB_USE_INTRINSIC_GUESS,
    )  # fmt: skip
    params = np.zeros(17)
    k, dist = straight[1], straight[2].ravel()
    params[:8] = k[0, 0], k[1, 1], k[0, 2], k[1, 2], *dist[:4]
    params[11:14], params[14:17] = straight[3][0].ravel(), straight[4][0].ravel()
    start = PinholeCalibration(SIZE, PinholeModel(), params, straight[0], "opencv")
    assert np.linalg.norm(start.centre - truth.centre) > 0.01
    fit = fit_refractive_pinhole(start, WINDOW, points, pixels)
    assert fit.rms < 1e-4
    # Exact pixels of 73 points fix the 12 parameters: the pose to well under a µm.
    np.testing.assert_allclose(fit.centre, truth.centre, rtol=0, atol=1e-6)
    volume = np.stack(
        np.meshgrid(*[np.linspace(-0.05, 0.05, 5)] * 2, np.linspace(-0.03, 0.02, 5)), axis=-1
    ).reshape(-1, 3)
    np.testing.assert_allclose(fit.project(volume), truth.project(volume), rtol=0, atol=1e-3)


def test_the_window_survives_the_calibration_file(tmp_path):
    camera = camera_behind(WINDOW, (0.08, 0.02, 0.57), (0.0, 0.0, 0.0))
    save_calibrations(tmp_path / "pinhole.h5", {"cam1": camera})
    back = load_calibrations(tmp_path / "pinhole.h5")["cam1"]
    assert back.window.as_dict() == WINDOW.as_dict()
    points = stepped_target()
    np.testing.assert_array_equal(back.project(points), camera.project(points))


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ({**WINDOW.as_dict(), "tilt": 3}, "unknown field(s) tilt"),
        ({"normal": [0, 0, 1], "distance": 0.1}, "missing field(s) thickness, glass_index"),
        ({**WINDOW.as_dict(), "glass_index": 0.9}, "glass_index 0.9 is below air_index 1.0"),
        ({**WINDOW.as_dict(), "normal": [0, 0, 0]}, "normal must be a non-zero 3-vector"),
        ({**WINDOW.as_dict(), "thickness": -0.01}, "thickness must be >= 0 m"),
    ],
)
def test_a_bad_window_is_named(spec, message):
    with pytest.raises(ValueError, match=r"^cameras\.cam1\.window: ") as err:
        FlatWindow.from_dict(spec, source="cameras.cam1.window")
    assert message in str(err.value)


def test_a_camera_or_target_on_the_wrong_side_is_refused():
    camera = camera_behind(WINDOW, (0.08, 0.02, 0.57), (0.0, 0.0, 0.0))
    flipped = FlatWindow([0.0, 0.0, -1.0], 0.03, 0.01, 1.49, 1.33)
    points = stepped_target()
    with pytest.raises(ValueError, match="is not outside its window"):
        fit_refractive_pinhole(camera.pinhole, flipped, points, np.zeros((len(points), 2)))
    with pytest.raises(ValueError, match="not beyond the window's wet face"):
        fit_refractive_pinhole(
            camera.pinhole, WINDOW, points + np.array([0, 0, 0.04]), points[:, :2]
        )
    with pytest.raises(ValueError, match="not outside the window"):
        RefractivePinholeCalibration(camera.pinhole, flipped)
