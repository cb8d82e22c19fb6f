"""Model-free calibration against exact refractive cameras and its polynomial identity."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ptv.calibration.model_free import PlaneObservation, calibrate_model_free
from ptv.calibration.polynomial import fit_polynomial2d
from ptv.triangulate import triangulate
from simulator.rigs import load_rig
from simulator.target import PlateDesign, build_plate, traverse_positions
from validation.truth.calibration_errors import synthetic_plane_dots

DESIGN = PlateDesign()
Z = traverse_positions()


def observations(camera, plate, z, *, noise=0.0, rng=None):
    """The camera's plane observations: exact dot projections plus Gaussian noise (px)."""
    assert np.array_equal(z, plate.z_nominal)
    dots = synthetic_plane_dots([camera], plate, noise_px=noise, rng=rng)[0]
    return [d.observation() for d in dots]


@pytest.fixture(scope="module")
def rig():
    return load_rig("paper-stereo")


@pytest.fixture(scope="module")
def calibrations(rig):
    plate = build_plate(DESIGN, Z, rng=0)
    return [
        calibrate_model_free(observations(c, plate, Z), c.lens.sensor_size) for c in rig.cameras
    ]


def random_points(n, rng):
    return np.column_stack(
        [rng.uniform(-0.04, 0.04, n), rng.uniform(-0.04, 0.04, n), rng.uniform(-5e-3, 5e-3, n)]
    )


def test_exact_dots_give_a_negligible_model_error(rig, calibrations):
    # Flat refraction maps each pixel to an exact line: with noise-free dots only the cubic
    # plane fits limit the model; their residuals are < 0.02 px, i.e. < 2 µm.
    for cal in calibrations:
        assert max(p.residual_px.max() for p in cal.planes) < 0.02
    points = random_points(500, np.random.default_rng(1))
    tri = triangulate(calibrations, [c.project(points) for c in rig.cameras])
    assert np.nanmax(np.linalg.norm(tri.points - points, axis=1)) < 2e-6


def test_project_agrees_with_the_true_camera(rig, calibrations):
    points = random_points(500, np.random.default_rng(2))
    for cal, cam in zip(calibrations, rig.cameras, strict=True):
        assert np.nanmax(np.abs(cal.project(points) - cam.project(points))) < 0.02


@settings(max_examples=30)
@given(x=st.floats(300, 1700), y=st.floats(100, 1000), z=st.floats(-6e-3, 6e-3))
def test_project_inverts_pixel_to_ray(calibrations, x, y, z):
    cal = calibrations[0]
    ray = cal.pixel_to_ray(np.array([[x, y]]))
    if not ray.valid[0]:
        return  # outside the calibrated area: NaN, as it must be
    s = (z - ray.origins[0, 2]) / ray.directions[0, 2]
    point = ray.origins + s * ray.directions
    assert np.allclose(cal.project(point), [[x, y]], atol=1e-6)


def test_line_parameters_are_the_exact_cubic_combination_of_the_plane_maps(calibrations):
    # docs/calibration.md §3: with global cubic T_j, X₀ = mean_j T_j and a = Σ dz_j T_j / Σ dz_j²
    # are themselves cubic polynomials; the bicubic spline must reproduce them.
    cal = calibrations[1]
    z = np.array([p.z for p in cal.planes])
    dz = z - z.mean()
    pixels = np.random.default_rng(3).uniform([50, 50], [1990, 1030], (300, 2))
    maps = np.stack([p.to_world(pixels) for p in cal.planes])
    x0 = maps.mean(axis=0)
    slope = np.einsum("j,jnc->nc", dz, maps) / np.sum(dz**2)
    line = cal.line_at(pixels)
    assert np.allclose(line[:, :2], x0, atol=1e-12)
    assert np.allclose(line[:, 2:], slope, atol=1e-12)


def test_pixels_outside_the_dots_are_nan_not_extrapolated(calibrations):
    cal = calibrations[0]
    rays = cal.pixel_to_ray(np.array([[5.0, 5.0], [1024.0, 544.0]]))
    assert rays.valid.tolist() == [False, True]
    far = cal.project(np.array([[0.3, 0.0, 0.0]]))
    assert np.isnan(far).all()


def test_dot_centre_noise_sets_the_table1_error_but_hardly_the_model(rig):
    # docs/calibration.md §8: on the Table 1 metric (each noisy dot triangulated from both
    # cameras) d ≈ 160 µm per pixel of dot-centre noise: 0.05 px → about 8 µm. The model
    # itself averages the noise over 441 dots × 13 planes: its error at random points
    # stays far below.
    plate = build_plate(DESIGN, Z, rng=0)
    obs = [observations(c, plate, Z, noise=0.05, rng=i) for i, c in enumerate(rig.cameras)]
    cals = [
        calibrate_model_free(o, c.lens.sensor_size) for o, c in zip(obs, rig.cameras, strict=True)
    ]
    d = []
    for j in range(len(Z)):
        truth = plate.dot_centres(j)
        seen = [np.isfinite(c.project(truth)).all(axis=1) for c in rig.cameras]
        both = seen[0] & seen[1]
        pixels = [o[j].pixels[both[s_]] for o, s_ in zip(obs, seen, strict=True)]
        tri = triangulate(cals, pixels)
        d.append(np.linalg.norm(tri.points - truth[both], axis=1))
    d = np.concatenate(d)
    assert np.isfinite(d).all()  # the dots themselves are inside the calibrated area
    table1_d = d.mean()
    assert 4e-6 < table1_d < 12e-6
    points = random_points(2000, np.random.default_rng(4))
    tri = triangulate(cals, [c.project(points) for c in rig.cameras])
    assert np.nanmean(np.linalg.norm(tri.points - points, axis=1)) < 0.25 * table1_d


def test_fewer_than_two_planes_or_repeated_z_are_errors(rig):
    plate = build_plate(DESIGN, Z, rng=0)
    obs = observations(rig.cameras[0], plate, Z)
    with pytest.raises(ValueError, match="at least two"):
        calibrate_model_free(obs[:1], (2048, 1088))
    with pytest.raises(ValueError, match="distinct"):
        calibrate_model_free([obs[0], obs[0]], (2048, 1088))


def test_polynomial_fit_reproduces_a_cubic_exactly():
    rng = np.random.default_rng(5)
    src = rng.uniform(-3, 7, (50, 2))
    x, y = src.T
    dst = np.column_stack([1 + x - 2 * y + 0.3 * x**2 * y - 0.1 * y**3, 2 - x * y + 0.05 * x**3])
    poly = fit_polynomial2d(src, dst, degree=3)
    probe = rng.uniform(-3, 7, (20, 2))
    px, py = probe.T
    expect = np.column_stack(
        [1 + px - 2 * py + 0.3 * px**2 * py - 0.1 * py**3, 2 - px * py + 0.05 * px**3]
    )
    assert np.allclose(poly(probe), expect, atol=1e-10)
    h = 1e-6
    ex, ey = np.array([h, 0.0]), np.array([0.0, h])
    num = np.stack(
        [
            (poly(probe + ex) - poly(probe - ex)) / (2 * h),
            (poly(probe + ey) - poly(probe - ey)) / (2 * h),
        ],
        axis=-1,
    )
    assert np.allclose(poly.jacobian(probe), num, atol=1e-6)
    with pytest.raises(ValueError, match="at least 10 points"):
        fit_polynomial2d(src[:9], dst[:9])


def curved_observations(curvature, z, *, scale=1e-4, slope=(0.3, -0.1)):
    """Dots seen through a medium whose rays bend: X = s(x − cx) + a dz + c dz² (exact)."""
    out = []
    centre = np.array([1024.0, 544.0])
    for zj in z:
        xy_world = DESIGN.nominal_xy
        bend = np.array(slope) * zj + curvature * zj**2  # z_ref = 0 for a centred traverse
        pixels = (xy_world - bend) / scale + centre
        out.append(PlaneObservation(zj, pixels, xy_world))
    return out


def test_curved_rays_follow_a_quadratic_ray_field_exactly(tmp_path):
    from ptv.calibration.io import load_calibrations, save_calibrations

    curvature = np.array([3.0, -2.0])  # 1/m: 108 µm and 72 µm of bending at the ends
    obs = curved_observations(curvature, Z)
    straight = calibrate_model_free(obs, (2048, 1088))
    curved = calibrate_model_free(obs, (2048, 1088), curved=True)
    assert curved.ray_degree == 2 and straight.ray_degree == 1
    # A straight fit leaves the bending as residual; the quadratic one none.
    assert straight.line_rms.max() > 10e-6 and curved.line_rms.max() < 1e-9
    rng = np.random.default_rng(6)
    pixels = rng.uniform([700, 250], [1350, 850], (200, 2))
    z = rng.uniform(-6e-3, 6e-3, 200)
    truth = (pixels - [1024.0, 544.0]) * 1e-4 + np.outer(z, [0.3, -0.1]) + np.outer(z**2, curvature)
    along = curved.position_at(pixels, z)
    assert np.allclose(along[:, :2], truth, atol=1e-10)
    assert np.allclose(curved.project(along), pixels, atol=1e-6)
    back = load_calibrations(save_calibrations(tmp_path / "c.h5", {"cam": curved}))["cam"]
    assert np.array_equal(back.position_at(pixels, z), along)


def test_curved_rays_need_three_planes():
    with pytest.raises(ValueError, match="three calibration planes"):
        calibrate_model_free(curved_observations(np.zeros(2), Z[:2]), (2048, 1088), curved=True)
