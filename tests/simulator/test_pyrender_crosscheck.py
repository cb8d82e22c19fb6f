"""pyrender as an independent second renderer for a camera without refraction.

~30 spheres ~3 px across are rasterised by OpenGL (flat shading, 8 × 8 supersampling)
at the camera's exact intrinsics; their intensity-weighted centroids must agree with
``Camera.project`` of the centres and with the centroids of the analytic renderer's
spots to 0.1 px RMS. This checks pose, axis and pixel-centre conventions of the
projection independently of our own code.
"""

import numpy as np
import pytest
from scipy import ndimage

from simulator.optics import Lens, look_at_camera
from simulator.pyrender_view import check_plain_pinhole, opengl_pose, render_spheres
from simulator.render.particle_images import render_particles
from simulator.rigs import load_rig

SENSOR = (320, 240)


def plain_camera():
    # Off-centre principal point: catches a half-pixel or a flipped-axis convention error.
    lens = Lens(
        focal_length=0.05, pixel_pitch=20e-6, sensor_size=SENSOR, principal_point=(171.3, 108.6)
    )
    return look_at_camera(np.zeros(3), lens, distance=1.0, azimuth=0.4, elevation=0.15)


def blob_centroids(image):
    """Intensity-weighted centroids (x, y) of the connected spots of an image, px."""
    labels, n = ndimage.label(image > 0)
    centres = ndimage.center_of_mass(image, labels, range(1, n + 1))
    return np.array(centres)[:, ::-1]


def match(found, expected):
    """Distance from each expected position to the nearest found centroid, px."""
    distances = np.linalg.norm(expected[:, None, :] - found[None, :, :], axis=2)
    assert len(set(distances.argmin(axis=1))) == len(expected)  # one-to-one
    return distances.min(axis=1)


def test_pyrender_spheres_land_where_project_and_the_analytic_renderer_put_them():
    camera = plain_camera()
    rng = np.random.default_rng(2024)
    # A jittered 6 × 5 grid over the sensor (spots well apart), at depths 0.9–1.1 m.
    u, v = np.meshgrid(np.linspace(0.1, 0.9, 6), np.linspace(0.12, 0.88, 5))
    targets = np.column_stack([u.ravel() * SENSOR[0], v.ravel() * SENSOR[1]])
    targets += rng.uniform(-4.0, 4.0, targets.shape)
    rays = camera.pixel_to_ray(targets)
    centres = rays.point_at(rng.uniform(0.9, 1.1, len(targets)))
    # Radius for an image ~3 px across at 1 m.
    radius = 1.5 / camera.lens.fx * 1.0
    projected = camera.project(centres)
    assert np.isfinite(projected).all()

    gl = render_spheres(camera, centres, radius, supersample=8)
    assert gl.shape == (SENSOR[1], SENSOR[0])
    gl_centroids = blob_centroids(gl)
    assert len(gl_centroids) == len(centres)
    # Each spot is a disc ~3 px across: area π r² in px² (depth varies by ±10 %).
    assert gl.sum() / len(centres) == pytest.approx(np.pi * 1.5**2, rel=0.1)
    error_project = match(gl_centroids, projected)
    assert np.sqrt(np.mean(error_project**2)) <= 0.1

    analytic = render_particles(projected, 0.7, 1000.0, shape=(SENSOR[1], SENSOR[0])).image
    analytic_centroids = blob_centroids(np.where(analytic > 1e-3, analytic, 0.0))
    assert len(analytic_centroids) == len(centres)
    error_renderers = match(gl_centroids, analytic_centroids)
    assert np.sqrt(np.mean(error_renderers**2)) <= 0.1


def test_opengl_pose_maps_the_optical_axis_to_minus_z():
    camera = plain_camera()
    pose = opengl_pose(camera.center, camera.rotation)
    np.testing.assert_allclose(pose[:3, :3] @ [0.0, 0.0, -1.0], camera.axis, atol=1e-15)
    np.testing.assert_allclose(pose[:3, :3] @ [0.0, 1.0, 0.0], -camera.rotation[1], atol=1e-15)
    np.testing.assert_allclose(pose[:3, 3], camera.center)


def test_refracting_or_distorted_cameras_are_refused():
    camera = load_rig("paper-stereo").cameras[0]
    with pytest.raises(ValueError, match="refract"):
        check_plain_pinhole(camera)
    with pytest.raises(ValueError, match="distortion"):
        render_spheres(camera, np.zeros((1, 3)), 1e-3)
