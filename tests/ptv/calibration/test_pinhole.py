"""The OpenCV pinhole baseline against known OpenCV cameras and the simulated rigs."""

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ptv.calibration.grid_errors import table1_errors
from ptv.calibration.model_free import PlaneObservation, calibrate_model_free
from ptv.calibration.pinhole import PARAMETER_NAMES, PinholeModel, project_parameters
from ptv.calibration.pinhole_fit import calibrate_pinhole
from simulator.rigs import load_rig
from simulator.target import PlateDesign, build_plate, traverse_positions
from validation.truth.calibration_errors import synthetic_plane_dots, true_positions

DESIGN = PlateDesign()
Z = traverse_positions()
SIZE = (2048, 1088)


# -- a known OpenCV camera ----------------------------------------------------------


def look_at(centre, yaw=0.0):
    """World → camera rotation of a camera at ``centre`` aimed at the origin, then yawed."""
    z = -centre / np.linalg.norm(centre)
    x = np.cross([0.0, 1.0, 0.0], z)
    x /= np.linalg.norm(x)
    rot = np.array([x, np.cross(z, x), z])
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]]) @ rot


def opencv_camera(cx=1010.0, dist=(-0.12, 0.4, 2e-4, -3e-4, 0.0)):
    """K, dist, rvec, tvec of a camera 1 m away at 35° that sees the plate centred."""
    centre = np.array([-0.57, 0.03, -0.82])
    rot = look_at(centre, yaw=-np.arctan((cx - 1024.0) / 9100.0))
    k = np.array([[9100.0, 0.0, cx], [0.0, 9150.0, 560.0], [0.0, 0.0, 1.0]])
    return k, np.asarray(dist, dtype=float), cv2.Rodrigues(rot)[0].ravel(), -rot @ centre


def opencv_observations(k, dist, rvec, tvec):
    out = []
    for z in Z:
        points = np.column_stack([DESIGN.nominal_xy, np.full(len(DESIGN.nominal_xy), z)])
        px = cv2.projectPoints(points, rvec, tvec, k, dist)[0][:, 0]
        ok = (px > -0.5).all(axis=1) & (px[:, 0] < SIZE[0] - 0.5) & (px[:, 1] < SIZE[1] - 0.5)
        out.append(PlaneObservation(z, px[ok], DESIGN.nominal_xy[ok]))
    return out


def assert_recovered(cal, k, dist, rvec, tvec):
    assert cal.rms < 1e-8
    assert np.allclose(cal.camera_matrix, k, rtol=1e-8, atol=1e-6)
    assert np.allclose(cal.dist_coeffs[:5], np.ravel(dist)[:5], rtol=1e-5, atol=1e-9)
    assert np.allclose(cal.rvec, rvec, atol=1e-10)
    assert np.allclose(cal.tvec, tvec, atol=1e-10)


@pytest.fixture(scope="module")
def known():
    k, dist, rvec, tvec = opencv_camera()
    cal = calibrate_pinhole(opencv_observations(k, dist, rvec, tvec), SIZE, focal_px=50e-3 / 5.5e-6)
    return cal, (k, dist, rvec, tvec)


def test_projection_is_opencvs_including_the_tilted_sensor():
    rng = np.random.default_rng(0)
    points = rng.uniform([-0.05, -0.05, 0.9], [0.05, 0.05, 1.1], (200, 3))
    k = np.array([[9000.0, 0.0, 1100.0], [0.0, 9050.0, 500.0], [0.0, 0.0, 1.0]])
    dist = np.zeros(14)
    dist[:5] = (-0.2, 0.5, 1e-3, -2e-3, 3.0)
    dist[12:] = (0.02, -0.03)
    rvec, tvec = np.array([0.02, -0.01, 0.03]), np.array([0.001, -0.002, 0.05])
    expect = cv2.projectPoints(points, rvec, tvec, k, dist)[0][:, 0]
    params = np.r_[9000.0, 9050.0, 1100.0, 500.0, dist[:5], dist[12:], rvec, tvec]
    assert np.allclose(project_parameters(params, points)[0], expect, atol=1e-9)
    assert len(PARAMETER_NAMES) == len(params)


def test_analytic_jacobian_matches_central_differences():
    rng = np.random.default_rng(1)
    points = rng.uniform([-0.3, -0.3, 0.9], [0.3, 0.3, 1.1], (100, 3))
    params = np.r_[9000.0, 9050.0, 1100.0, 500.0, -0.2, 0.5, 1e-3, -2e-3, 3.0, 0.02, -0.03]
    params = np.r_[params, 0.1, 0.6, -0.2, 0.01, 0.02, 0.05]
    _, _, jac = project_parameters(params, points, jacobian=True)
    for i in range(len(params)):
        h = 1e-6 * max(1.0, abs(params[i]))
        e = np.zeros(len(params))
        e[i] = h
        num = project_parameters(params + e, points)[0] - project_parameters(params - e, points)[0]
        num /= 2 * h
        assert np.allclose(jac[:, :, i], num, rtol=1e-6, atol=1e-6 * np.abs(num).max()), i


def test_a_known_opencv_camera_is_recovered_exactly(known):
    cal, truth = known
    assert_recovered(cal, *truth)
    assert cal.model.name == "k1,k2,p1,p2"
    assert set(cal.parameters()) == {
        "fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "rx", "ry", "rz", "tx", "ty", "tz"
    }  # fmt: skip
    assert cal.start in cal.start_rms and cal.rms == min(cal.start_rms.values())
    assert cal.n_points == 13 * 441


def test_a_principal_point_off_the_image_is_still_recovered():
    # OpenCV refuses such a guess ("Principal point must be within the image"); the
    # scipy polish of the other starts must get there anyway.
    k, dist, rvec, tvec = opencv_camera(cx=2600.0)
    obs = opencv_observations(k, dist, rvec, tvec)
    cal = calibrate_pinhole(obs, SIZE, focal_px=50e-3 / 5.5e-6)
    assert_recovered(cal, k, dist, rvec, tvec)
    world = np.concatenate(
        [np.column_stack([o.world_xy, np.full(len(o.pixels), o.z)]) for o in obs]
    )
    pixels = np.concatenate([o.pixels for o in obs])
    with pytest.raises(cv2.error, match=r"[Pp]rincipal point"):
        cv2.calibrateCamera(
            [world.astype(np.float32)],
            [pixels.astype(np.float32)],
            SIZE,
            k,
            dist,
            flags=cv2.CALIB_USE_INTRINSIC_GUESS,
        )


def test_k1_only_model_and_no_focal_guess():
    k, dist, rvec, tvec = opencv_camera(dist=(-0.12, 0.0, 0.0, 0.0, 0.0))
    cal = calibrate_pinhole(
        opencv_observations(k, dist, rvec, tvec), SIZE, model=PinholeModel(("k1",))
    )
    assert_recovered(cal, k, dist, rvec, tvec)
    assert cal.model.name == "k1"


@settings(max_examples=40)
@given(x=st.floats(0, 2047), y=st.floats(0, 1087), depth=st.floats(0.8, 1.2))
def test_project_inverts_pixel_to_ray(known, x, y, depth):
    cal, _ = known
    ray = cal.pixel_to_ray(np.array([[x, y]]))
    assert ray.valid[0]
    point = ray.origins + depth * ray.directions
    assert np.abs(cal.project(point) - [[x, y]]).max() <= 1e-6


def test_not_imaged_is_nan(known):
    cal, _ = known
    behind = 2 * cal.centre - np.zeros(3)  # beyond the camera, on the far side
    off = cal.centre + 1.0 * cal.rotation[2] + 0.5 * cal.rotation[0]  # far off the image
    xy = cal.project(np.array([[0.0, 0.0, 0.0], behind, off, [np.nan, 0.0, 0.0]]))
    assert np.isfinite(xy[0]).all() and np.isnan(xy[1:]).all()
    rays = cal.pixel_to_ray(np.array([[1024.0, 544.0], [-10.0, 5.0], [5.0, 2000.0]]))
    assert rays.valid.tolist() == [True, False, False]
    with pytest.raises(ValueError, match=r"\(N, 3\)"):
        cal.project(np.zeros((3, 2)))


def test_bad_input_is_a_clear_error():
    with pytest.raises(ValueError, match="p1 and p2"):
        PinholeModel(("k1", "p1"))
    with pytest.raises(ValueError, match="distinct names"):
        PinholeModel(("k1", "k9"))
    flat = [PlaneObservation(0.0, np.random.default_rng(0).uniform(0, 100, (50, 2)),
                             DESIGN.nominal_xy[:50])]  # fmt: skip
    with pytest.raises(ValueError, match="non-coplanar"):
        calibrate_pinhole(flat, SIZE, focal_px=9000.0)


# -- the simulated rigs: the Table 1 metric against the model-free calibration -------


def table1(cals, dots, plate):
    """d_X, d_Y, d_Z, d (m): every noisy dot triangulated from both cameras.

    The Table 1 metric of docs/calibration.md §7.
    """
    errors = table1_errors(cals, dots, DESIGN.indices, true_positions(plate))
    assert errors.coverage == 1.0
    return np.r_[errors.components, errors.d]


def noisy_dots(rig, plate):
    """0.05 px dot-centre noise; the per-camera observations and the identified dots."""
    dots = synthetic_plane_dots(rig.cameras, plate, noise_px=0.05, rng=0)
    return [[d.observation() for d in cam] for cam in dots], dots


def pinhole_vs_model_free(rig_name):
    rig = load_rig(rig_name)
    plate = build_plate(DESIGN, Z, rng=0)
    obs, dots = noisy_dots(rig, plate)
    guesses = [c.lens.focal_length / c.lens.pixel_pitch for c in rig.cameras]
    free = [
        calibrate_model_free(o, c.lens.sensor_size) for o, c in zip(obs, rig.cameras, strict=True)
    ]
    pin = [
        calibrate_pinhole(o, c.lens.sensor_size, focal_px=f)
        for o, c, f in zip(obs, rig.cameras, guesses, strict=True)
    ]
    return table1(pin, dots, plate) / table1(free, dots, plate), pin


def test_conventional_rig_pinhole_matches_model_free():
    # docs/calibration.md §8: windows normal to the cameras and no Scheimpflug: the full pinhole
    # equals the model-free calibration (measured: d ratio 1.001, every component ≤ 1.003).
    ratio, pin = pinhole_vs_model_free("conventional")
    assert np.all(ratio < 1.1), ratio
    assert all(p.rms < 0.08 for p in pin)  # the 0.05 px/axis noise alone gives 0.071 px


def test_paper_stereo_pinhole_gap():
    # Scheimpflug + 8° diagonal window obliquity: a zero-skew, refraction-free pinhole
    # cannot express the mapping. Measured (seed 0): d ratio 1.38 (d_X 1.26, d_Y 1.54,
    # d_Z 1.38); docs/calibration.md §8 expects ~1.0–1.3 for in-plane and more for diagonal tilt.
    ratio, pin = pinhole_vs_model_free("paper-stereo")
    assert np.all(ratio > 1.1), ratio
    assert np.all(ratio < 3.0), ratio
    assert all(p.rms > 0.08 for p in pin)  # model error on top of the noise


@pytest.mark.slow
def test_paper_stereo_tilted_model_closes_the_gap():
    # OpenCV's tilted-sensor model absorbs the Scheimpflug tilt and most of the oblique
    # window here (measured: d ratio 1.009). About 15 s per camera.
    rig = load_rig("paper-stereo")
    plate = build_plate(DESIGN, Z, rng=0)
    obs, dots = noisy_dots(rig, plate)
    model = PinholeModel(("k1", "k2", "p1", "p2"), tilted=True)
    pin = [
        calibrate_pinhole(o, c.lens.sensor_size, model=model, focal_px=9091.0)
        for o, c in zip(obs, rig.cameras, strict=True)
    ]
    free = [
        calibrate_model_free(o, c.lens.sensor_size) for o, c in zip(obs, rig.cameras, strict=True)
    ]
    ratio = table1(pin, dots, plate) / table1(free, dots, plate)
    assert np.all(ratio < 1.1), ratio
