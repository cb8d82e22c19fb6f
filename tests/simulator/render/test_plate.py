"""Plate images by ray casting: centroids, dot areas, diameters, marks, options, bad input."""

import dataclasses

import numpy as np
import pytest
from scipy import ndimage

from simulator.optics.camera import Camera
from simulator.optics.interfaces import FlatInterfaces
from simulator.optics.lens import Lens
from simulator.optics.placement import WindowSpec, look_at_camera
from simulator.optics.scheimpflug import focus_on_plane
from simulator.render._raycast import cast_rays
from simulator.render.plate import PlateImage, render_plate
from simulator.render.sensor import Sensor
from simulator.target import REALISTIC, Imperfections, PlateDesign, build_plate

Z_PLANES = np.array([-3e-3, -1e-3, 1e-3, 3e-3])
FULL = 4000.0


def _window_camera(sensor_size=(2048, 1088)):
    """The benchmark rig: 50 mm, mild distortion, 35° off Z, 10° oblique window, Scheimpflug."""
    lens = Lens(0.05, 5.5e-6, sensor_size=sensor_size, k1=-0.08, k2=0.3, p1=2e-4, p2=-1e-4)
    window = WindowSpec(0.3, 0.015, np.radians(10.0), np.pi / 4)
    camera = look_at_camera([0.0, 0.0, 0.0], lens, distance=0.9, azimuth=np.radians(35.0),
                            window=window)
    return focus_on_plane(camera)


def _pinhole_camera(azimuth_deg, *, distance=0.9, sensor_size=(640, 480)):
    lens = Lens(0.05, 5.5e-6, sensor_size=sensor_size)
    return look_at_camera([0.0, 0.0, 0.0], lens, distance=distance,
                          azimuth=np.radians(azimuth_deg))


@pytest.fixture(scope="module")
def realistic_plate():
    return build_plate(PlateDesign(), Z_PLANES, imperfections=REALISTIC, rng=7)


@pytest.fixture(scope="module")
def ideal_plate():
    return build_plate(PlateDesign(), Z_PLANES, rng=7)


@pytest.fixture(scope="module")
def window_image(realistic_plate):
    """Full-size 2048 × 1088 image through the oblique window, realistic plate."""
    camera = _window_camera()
    return camera, render_plate(realistic_plate, camera, 1, full_brightness=FULL)


def _blobs(image, threshold=0.0):
    """Connected components above ``threshold``: (centroid (N, 2) px, light (N,), area px)."""
    labels, n = ndimage.label(image > threshold)
    index = np.arange(1, n + 1)
    cy_cx = np.array(ndimage.center_of_mass(image, labels, index))
    light = ndimage.sum(image, labels, index)
    area = ndimage.sum(np.ones_like(image), labels, index)
    touches = np.zeros(n, dtype=bool)
    for edge in (labels[0], labels[-1], labels[:, 0], labels[:, -1]):
        touches[np.unique(edge[edge > 0]) - 1] = True
    return cy_cx[:, ::-1], light, area, touches


def _match(measured, truth):
    """Index into ``truth`` of the nearest truth point of every measured point."""
    finite = np.flatnonzero(np.isfinite(truth[:, 0]))
    d = np.linalg.norm(measured[:, None, :] - truth[None, finite, :], axis=2)
    return finite[np.argmin(d, axis=1)], np.min(d, axis=1)


def _jacobian(camera, plate, plane, uv, step=1e-4):
    """∂(x, y)/∂(u, v) of the image of plate points, px/m, shape (N, 2, 2), central differences."""
    jac = np.empty((len(uv), 2, 2))
    for axis in range(2):
        du = np.zeros(2)
        du[axis] = step
        plus = camera.project(plate.plate_to_world(plane, uv + du))
        minus = camera.project(plate.plate_to_world(plane, uv - du))
        jac[:, :, axis] = (plus - minus) / (2 * step)
    return jac


def _disc_quadrature(camera, plate, plane, k, *, n_r=24, n_t=192):
    """Light-weighted image centroid and ∫ b dA (px²) of dot k by forward projection.

    The disc is cut into polar cells whose corners are projected with ``camera.project``
    (Newton forward refraction; independent of the renderer's back-projection); each
    projected cell is a polygon with its exact area and centroid, weighted by the
    back-light brightness at the cell."""
    # the outer polygon gets the disc's exact area
    radius = 0.5 * plate.design.diameters[k] * np.sqrt((2 * np.pi / n_t) / np.sin(2 * np.pi / n_t))
    r = radius * np.linspace(0.0, 1.0, n_r + 1)
    t = np.linspace(0.0, 2 * np.pi, n_t + 1)
    rr, tt = np.meshgrid(r, t, indexing="ij")
    uv = plate.dot_xy[k] + np.stack([rr * np.cos(tt), rr * np.sin(tt)], axis=-1)
    xy = camera.project(plate.plate_to_world(plane, uv.reshape(-1, 2))).reshape(
        n_r + 1, n_t + 1, 2
    )
    quads = np.stack([xy[:-1, :-1], xy[1:, :-1], xy[1:, 1:], xy[:-1, 1:]], axis=2)
    x, y = quads[..., 0], quads[..., 1]
    x1, y1 = np.roll(x, -1, axis=2), np.roll(y, -1, axis=2)
    cross = x * y1 - x1 * y
    area = 0.5 * cross.sum(axis=2)
    cx = ((x + x1) * cross).sum(axis=2) / (6 * area)
    cy = ((y + y1) * cross).sum(axis=2) / (6 * area)
    uv_mid = 0.25 * (uv[:-1, :-1] + uv[1:, :-1] + uv[1:, 1:] + uv[:-1, 1:])
    weight = np.abs(area) * plate.brightness(uv_mid)
    total = weight.sum()
    return np.array([(weight * cx).sum(), (weight * cy).sum()]) / total, total


# -- the compiled ray caster ------------------------------------------------------------


def _tir_camera():
    """A camera in water looking into air through two layers: oblique pixels are totally
    internally reflected."""
    normal = np.array([0.4, 0.05, 1.0])
    stack = FlatInterfaces(normal / np.linalg.norm(normal), [0.05, 0.06, 0.08],
                           [1.333, 1.7, 1.2, 1.0])
    lens = Lens(0.008, 5.5e-6, k1=-0.2, k2=0.05, p1=1e-3, tau_x=0.03, tau_y=-0.02)
    return Camera(np.zeros(3), np.eye(3), lens, stack)


@pytest.mark.parametrize(
    "camera",
    [_pinhole_camera(20.0), _window_camera((400, 300)), _tir_camera()],
    ids=["air", "window", "three-layers-tir"],
)
def test_cast_rays_is_pixel_to_ray(camera):
    rng = np.random.default_rng(3)
    width, height = camera.lens.sensor_size
    xy = rng.uniform([-40.0, -40.0], [width + 40.0, height + 40.0], size=(4000, 2))
    origins, directions = cast_rays(camera, xy[:, 0], xy[:, 1])
    rays = camera.pixel_to_ray(xy)
    np.testing.assert_array_equal(np.isnan(origins[:, 0]), ~rays.valid)
    np.testing.assert_allclose(origins, rays.origins, rtol=0, atol=1e-13)
    np.testing.assert_allclose(directions, rays.directions, rtol=0, atol=1e-13)
    if camera.interfaces is not None and camera.interfaces.n_interfaces == 3:
        assert 0 < rays.valid.sum() < len(xy)  # total internal reflection is exercised


# -- the image and its truth --------------------------------------------------------------


def test_image_is_float64_electrons_of_the_sensor_shape(window_image):
    _, result = window_image
    assert isinstance(result, PlateImage)
    assert result.image.dtype == np.float64 and result.shape == (1088, 2048)
    assert result.image.min() == 0.0  # opaque plate: a black background
    # bright dots: a pixel inside a dot records FULL × the local back-light brightness
    assert result.image.max() == pytest.approx(FULL * 1.25, rel=0.1)
    digital = Sensor(read_noise=0.0).record(result.image, noise=False)
    assert digital.dtype == np.uint16 and digital.shape == (1088, 2048)
    assert result.on_sensor.sum() > 100 and result.visible.sum() >= result.on_sensor.sum()


def test_image_centroids_agree_with_the_truth_centroid(window_image):
    """Component centroids measured on the noise-free image: 0.05 px RMS is the brief;
    a sharp 20-px disc on 4 × 4 supersampling does much better."""
    _, result = window_image
    measured, _, _, touches = _blobs(result.image)
    measured = measured[~touches]
    k, dist = _match(measured, result.centroid)
    assert dist.max() < 0.5  # every blob found its own dot
    ok = result.on_sensor[k]
    assert ok.sum() > 100
    error = measured[ok] - result.centroid[k[ok]]
    rms = np.sqrt(np.mean(np.sum(error**2, axis=1)))
    assert rms < 0.05  # the brief
    assert rms < 0.003  # measured 0.0007 px


def test_image_centroids_miss_the_projected_centre_by_the_disc_bias(window_image):
    camera, result = window_image
    measured, _, _, touches = _blobs(result.image)
    k, _ = _match(measured[~touches], result.centroid)
    ok = result.on_sensor[k]
    measured = measured[~touches][ok]
    k = k[ok]
    bias = result.bias[k]
    # documented magnitude: ≈ R² f_px sin θ cos θ / Z² ≈ 0.006 px for a 2-mm dot, 0.014 px
    # for a 3.2-mm mark, plus ≈ 0.005 px from the uneven back-light; refraction and the
    # bowed plate change it by a factor of order one
    radius = 0.5 * result.diameters[k]
    scale = radius**2 * camera.lens.fx * np.sin(np.radians(35)) * np.cos(np.radians(35)) / 0.9**2
    assert np.all(np.linalg.norm(bias, axis=1) < 3 * scale + 0.015)
    assert np.median(np.linalg.norm(bias, axis=1)) > 0.2 * np.median(scale)  # not zero
    residual = np.linalg.norm(measured - result.projected[k] - bias, axis=1)
    raw = np.linalg.norm(measured - result.projected[k], axis=1)
    assert np.sqrt(np.mean(residual**2)) < 0.01
    assert np.sqrt(np.mean(raw**2)) < 0.01 + np.sqrt(np.mean(np.sum(bias**2, axis=1)))


def test_truth_centroid_and_light_match_a_forward_projected_quadrature(window_image,
                                                                       realistic_plate):
    """Independent check through ``camera.project`` (Newton forward refraction), with the
    realistic plate's tilt, bow, dot scatter and uneven back-light."""
    camera, result = window_image
    marks = list(result.marks.values())
    rng = np.random.default_rng(0)
    others = rng.choice(np.flatnonzero(result.on_sensor), 5, replace=False).tolist()
    for k in marks + others:
        assert result.on_sensor[k]
        centroid, light = _disc_quadrature(camera, realistic_plate, 1, k)
        np.testing.assert_allclose(result.centroid[k], centroid, atol=2e-4)  # 4e-5 measured
        assert result.electrons[k] / FULL == pytest.approx(light, rel=2e-4)


def test_total_light_is_brightness_times_the_jacobian_area(window_image, realistic_plate):
    camera, result = window_image
    width, height = camera.lens.sensor_size
    far = (
        result.on_sensor
        & (np.abs(result.projected[:, 0] - width / 2) < width / 2 - 40)
        & (np.abs(result.projected[:, 1] - height / 2) < height / 2 - 40)
    )
    assert far.sum() > 100
    uv = realistic_plate.dot_xy[far]
    area = np.pi * (0.5 * result.diameters[far]) ** 2 * np.abs(
        np.linalg.det(_jacobian(camera, realistic_plate, 1, uv))
    )
    expected = FULL * realistic_plate.brightness(uv) * area
    ratio = result.electrons[far] / expected
    assert np.max(np.abs(ratio - 1)) < 3e-3
    assert abs(np.mean(ratio) - 1) < 5e-4
    # the image holds the light of the truth
    assert result.image.sum() == pytest.approx(result.electrons.sum(), rel=1e-12)


def test_marks_image_where_project_puts_them(window_image, realistic_plate):
    camera, result = window_image
    measured, _, area, touches = _blobs(result.image)
    biggest = np.argsort(area)[-3:]
    assert not touches[biggest].any()
    marks = result.marks
    centres = camera.project(realistic_plate.dot_centres(1)[list(marks.values())])
    k, dist = _match(measured[biggest], centres)
    assert sorted(k.tolist()) == [0, 1, 2]
    assert dist.max() < 0.05  # the disc bias of a 3.2 mm mark is ≈ 0.02 px here
    smaller = np.delete(area, biggest)
    assert area[biggest].min() > 2.0 * smaller[~np.delete(touches, biggest)].max()


def test_perpendicular_view_without_refraction_gives_circles_of_the_expected_diameter(
    ideal_plate,
):
    distance = 0.7
    camera = _pinhole_camera(0.0, distance=distance)
    z = ideal_plate.poses[2].z_actual  # the plate is at Z = 1 mm, the camera looks from +Z
    result = render_plate(ideal_plate, camera, 2, full_brightness=FULL)
    expected = ideal_plate.design.diameters * camera.lens.fx / (distance - z)
    labels, _ = ndimage.label(result.image > 0)
    y, x = np.indices(result.image.shape)
    seen = []
    for box_index, box in enumerate(ndimage.find_objects(labels)):
        patch = np.where(labels[box] == box_index + 1, result.image[box], 0.0)
        if box[0].start == 0 or box[1].start == 0 or box[0].stop == 480 or box[1].stop == 640:
            continue
        w = patch / patch.sum()
        xs, ys = x[box], y[box]
        mx, my = (w * xs).sum(), (w * ys).sum()
        var_x, var_y = (w * (xs - mx) ** 2).sum(), (w * (ys - my) ** 2).sum()
        cov = (w * (xs - mx) * (ys - my)).sum()
        k, _ = _match(np.array([[mx, my]]), result.centroid)
        seen.append(k[0])
        # a uniform disc of diameter d: variance d²/16 per axis, no covariance; the
        # pixelisation adds ≈ 1/12 px² only on the edge pixels (≪ 1 %)
        assert 4 * np.sqrt(var_x) == pytest.approx(expected[k[0]], rel=3e-3)
        assert 4 * np.sqrt(var_y) == pytest.approx(expected[k[0]], rel=3e-3)
        assert abs(cov) < 1e-3 * var_x
        # area from the light: no brightness gradient on the ideal plate
        diameter = 2 * np.sqrt(patch.sum() / FULL / np.pi)
        assert diameter == pytest.approx(expected[k[0]], rel=1e-3)
    seen = np.array(seen)
    assert len(seen) > 50
    marks = np.isin(seen, list(result.marks.values()))
    assert marks.sum() == 3  # all marks in view, and larger (checked above by diameter)
    # no perspective, no refraction: the centroid is the projected centre
    np.testing.assert_allclose(result.bias[seen], 0.0, atol=2e-3)


def test_oblique_pinhole_bias_is_minus_r_squared_l_c(ideal_plate):
    """bias ≈ −R² L ∇ln Z (module docstring), L and Z from ``project`` and the pose."""
    camera = _pinhole_camera(40.0)
    result = render_plate(ideal_plate, camera, 0, full_brightness=FULL)
    k = np.flatnonzero(result.on_sensor)
    assert len(k) > 20
    uv = ideal_plate.dot_xy[k]
    jac = _jacobian(camera, ideal_plate, 0, uv)
    step = 1e-4
    grad = np.empty((len(k), 2))
    for axis in range(2):
        du = np.zeros(2)
        du[axis] = step
        depth = [
            (ideal_plate.plate_to_world(0, uv + sign * du) - camera.center) @ camera.axis
            for sign in (1, -1)
        ]
        grad[:, axis] = (np.log(depth[0]) - np.log(depth[1])) / (2 * step)
    radius = 0.5 * result.diameters[k]
    predicted = -(radius**2)[:, None] * np.einsum("nij,nj->ni", jac, grad)
    assert np.median(np.linalg.norm(predicted, axis=1)) > 0.004
    np.testing.assert_allclose(result.bias[k], predicted, atol=3e-4)  # 6e-5 measured


# -- options -----------------------------------------------------------------------------


@pytest.mark.parametrize("supersampling", [3, 4])
def test_adaptive_supersampling_equals_supersampling_every_pixel(realistic_plate,
                                                                 supersampling):
    camera = _window_camera((320, 240))
    fast = render_plate(realistic_plate, camera, 2, supersampling=supersampling)
    slow = render_plate(realistic_plate, camera, 2, supersampling=supersampling,
                        adaptive=False)
    # interior pixels take the centre's brightness instead of the sub-sample mean
    np.testing.assert_allclose(fast.image, slow.image, rtol=1e-7, atol=0)
    seen = fast.visible
    np.testing.assert_array_equal(seen, slow.visible)
    np.testing.assert_allclose(fast.centroid[seen], slow.centroid[seen], atol=1e-4)
    np.testing.assert_allclose(fast.electrons, slow.electrons, rtol=1e-7)


def test_supersampling_converges(ideal_plate):
    camera = _pinhole_camera(30.0, sensor_size=(320, 240))
    fine = render_plate(ideal_plate, camera, 1, supersampling=8)
    seen = fine.on_sensor
    errors = {}
    for antialias in (False, True):
        for s in (1, 2, 4):
            result = render_plate(ideal_plate, camera, 1, supersampling=s, antialias=antialias)
            errors[antialias, s] = np.abs(result.centroid[seen] - fine.centroid[seen]).max()
            if s == 1 and not antialias:  # one point sample per pixel: all or nothing
                assert set(np.unique(result.image)) == {0.0, 4000.0}
    assert errors[False, 1] > errors[False, 2] > errors[False, 4] > 1e-3
    assert errors[True, 1] < 0.01 and errors[True, 4] < 2e-4  # area coverage: far better
    assert errors[True, 4] < 0.02 * errors[False, 4]


def test_soft_edge_and_defocus_keep_light_and_centroids(ideal_plate):
    camera = _window_camera((480, 360))
    sharp = render_plate(ideal_plate, camera, 0)
    soft = render_plate(ideal_plate, camera, 0, edge_width=0.2e-3)
    ok = sharp.on_sensor & soft.on_sensor
    # a linear ramp of width w adds π w²/12 to a disc's area
    radius = 0.5 * sharp.diameters[ok]
    np.testing.assert_allclose(soft.electrons[ok] / sharp.electrons[ok],
                               1 + 0.2e-3**2 / 12 / radius**2, rtol=5e-4)
    np.testing.assert_allclose(soft.centroid[ok], sharp.centroid[ok], atol=3e-3)
    assert np.count_nonzero(soft.image) > np.count_nonzero(sharp.image)
    # 20 mm off the focused sheet: a blur disc of about two pixels (σ = d/4)
    far = build_plate(PlateDesign(), [0.0, 0.02])
    blurred = render_plate(far, camera, 1, defocus=True)
    reference = render_plate(far, camera, 1)
    sigma = blurred.blur_sigma[blurred.on_sensor]
    assert 0.3 < sigma.min() and sigma.max() < 3.0
    assert np.all(reference.blur_sigma == 0.0)
    assert np.count_nonzero(blurred.image) > 1.1 * np.count_nonzero(reference.image)
    assert blurred.image.sum() < reference.image.sum()  # some light blurred off the sensor
    measured, light, _, touches = _blobs(blurred.image)
    k, _ = _match(measured[~touches], blurred.centroid)
    ok = blurred.on_sensor[k]
    assert ok.sum() > 30
    # the blur keeps each dot's light and centroid
    np.testing.assert_allclose(light[~touches][ok], blurred.electrons[k[ok]], rtol=1e-9)
    np.testing.assert_array_equal(blurred.electrons, reference.electrons)
    error = measured[~touches][ok] - blurred.centroid[k[ok]]
    assert np.sqrt(np.mean(np.sum(error**2, axis=1))) < 0.005


def test_full_brightness_scales_the_image(ideal_plate):
    camera = _pinhole_camera(10.0, sensor_size=(160, 120))
    one = render_plate(ideal_plate, camera, 0, full_brightness=1.0)
    many = render_plate(ideal_plate, camera, 0, full_brightness=2500.0)
    np.testing.assert_allclose(many.image, 2500.0 * one.image, rtol=1e-15)
    np.testing.assert_allclose(many.electrons, 2500.0 * one.electrons, rtol=1e-15)


# -- bad input ---------------------------------------------------------------------------


@pytest.mark.parametrize("plane", [-1, 4, 1.0, True, "0"])
def test_plane_out_of_range_is_an_error(ideal_plate, plane):
    with pytest.raises(ValueError, match=r"plane must be a traverse plane index from 0 to 3"):
        render_plate(ideal_plate, _pinhole_camera(0.0, sensor_size=(64, 48)), plane)


def test_a_camera_that_sees_no_dot_is_an_error(ideal_plate):
    away = look_at_camera([0.0, 0.5, 0.0], Lens(0.05, 5.5e-6, sensor_size=(64, 48)),
                          distance=0.9, azimuth=0.0)
    with pytest.raises(ValueError, match="sees no dot of the plate at plane 0"):
        render_plate(ideal_plate, away, 0)
    behind = Camera(np.array([0.0, 0.0, 0.9]), np.eye(3), Lens(0.05, 5.5e-6))  # looks at +Z
    with pytest.raises(ValueError, match="sees no dot"):
        render_plate(ideal_plate, behind, 0)


@pytest.mark.parametrize(
    ("option", "match"),
    [
        ({"supersampling": 0}, "supersampling"),
        ({"supersampling": 2.5}, "supersampling"),
        ({"full_brightness": -1.0}, "full_brightness"),
        ({"full_brightness": np.nan}, "full_brightness"),
        ({"edge_width": -1e-4}, "edge_width"),
        ({"edge_width": 2e-3}, "inside its own grid cell"),
        ({"antialias": "yes"}, "antialias"),
        ({"adaptive": None}, "adaptive"),
        ({"bow_iterations": -1}, "bow_iterations"),
        ({"defocus": 1}, "defocus"),
    ],
)
def test_bad_options_are_errors(ideal_plate, option, match):
    with pytest.raises(ValueError, match=match):
        render_plate(ideal_plate, _pinhole_camera(0.0, sensor_size=(64, 48)), 0, **option)


def test_bad_plate_or_camera_is_an_error(ideal_plate):
    camera = _pinhole_camera(0.0, sensor_size=(64, 48))
    with pytest.raises(ValueError, match="PhysicalPlate"):
        render_plate(PlateDesign(), camera, 0)
    with pytest.raises(ValueError, match="Camera"):
        render_plate(ideal_plate, "camera", 0)
    moved = ideal_plate.dot_xy.copy()
    moved[0] += [1.6e-3, 0.0]  # 1.6 mm off: the 1-mm radius dot leaves its 5-mm cell
    with pytest.raises(ValueError, match=r"dot \[-10, -10\].*own grid cell"):
        render_plate(dataclasses.replace(ideal_plate, dot_xy=moved), camera, 0)


def test_an_unsupported_surface_model_is_refused(ideal_plate):
    class Wavy(type(ideal_plate)):
        def surface_height(self, uv):
            return 1e-5 * np.sin(np.asarray(uv)[..., 0] * 100)

    wavy = Wavy(ideal_plate.design, Imperfections(), ideal_plate.dot_xy, ideal_plate.poses)
    with pytest.raises(ValueError, match="surface_height"):
        render_plate(wavy, _pinhole_camera(0.0, sensor_size=(64, 48)), 0)
