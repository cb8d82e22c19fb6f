"""Tanks: the icosahedron's inradius and stereo window faces, the box, and the flat
window of a wall against tracing through the tank's meshes."""

import numpy as np
import pytest

from simulator.optics import Camera, look_at_camera
from simulator.optics.lens import Lens
from simulator.optics.mesh_interfaces import MeshCamera
from simulator.rigs import load_rig
from simulator.tank import (
    CIRCUM_OVER_IN,
    WINDOW_AZIMUTH,
    box_tank,
    face_plane,
    icosahedral_tank,
    sight_face,
    tank_surfaces,
    wall_window,
)


def window_normal(sign):
    return np.array([sign * np.sin(WINDOW_AZIMUTH), 0.0, np.cos(WINDOW_AZIMUTH)])


def test_window_azimuth_is_the_paper_stereo_angle():
    assert np.degrees(WINDOW_AZIMUTH) == pytest.approx(35.26, abs=0.005)


@pytest.mark.parametrize("inradius", [0.15, 0.4])
def test_icosahedron_has_the_requested_inradius_and_is_closed(inradius):
    tank = icosahedral_tank(inradius)
    assert len(tank.vertices) == 12 and len(tank.faces) == 20
    assert tank.is_watertight and tank.is_winding_consistent and tank.is_volume
    offsets = np.einsum("ij,ij->i", tank.face_normals, tank.vertices[tank.faces[:, 0]])
    np.testing.assert_allclose(offsets, inradius, rtol=1e-14)  # every face, outward normals
    np.testing.assert_allclose(np.linalg.norm(tank.vertices, axis=1), CIRCUM_OVER_IN * inradius)
    np.testing.assert_allclose(tank.centroid, 0.0, atol=1e-15)
    # Regular: all 30 edges equal.
    lengths = np.linalg.norm(np.diff(tank.vertices[tank.edges_unique], axis=1)[:, 0], axis=1)
    np.testing.assert_allclose(lengths, lengths[0], rtol=1e-13)


def test_two_faces_look_at_plus_minus_35_degrees_in_the_xz_plane():
    tank = icosahedral_tank(0.15)
    normals = []
    for sign in (-1, 1):
        normal, offset = face_plane(tank, sight_face(tank, window_normal(sign), np.zeros(3)))
        np.testing.assert_allclose(normal, window_normal(sign), atol=1e-14)
        assert offset == pytest.approx(0.15, rel=1e-14)
        normals.append(normal)
    angle = np.degrees(np.arccos(normals[0] @ normals[1]))
    assert angle == pytest.approx(70.53, abs=0.005)
    # Mirror symmetric about X = 0: the two windows are equivalent.
    mirrored = tank.vertices * [-1.0, 1.0, 1.0]
    distances = np.linalg.norm(mirrored[:, None] - tank.vertices[None], axis=2).min(axis=1)
    assert distances.max() < 1e-14


def test_rig_cameras_look_through_the_window_faces():
    rig = load_rig("paper-stereo")
    tank = icosahedral_tank(rig.tank.inradius)
    for sign, camera in zip((-1, 1), rig.cameras, strict=True):  # cam1 at −35°, cam2 at +35°
        index = sight_face(tank, camera.center, np.zeros(3))
        np.testing.assert_allclose(tank.face_normals[index], window_normal(sign), atol=1e-14)


def _assert_flat_window_equals_meshes(camera, stack, surfaces):
    """Rays of a camera through the flat window ``stack`` equal those traced through
    the tank meshes ``surfaces`` (an independent refraction code)."""
    flat = Camera(camera.center, camera.rotation, camera.lens, stack)
    meshes = MeshCamera.from_camera(camera, surfaces)
    u, v = np.meshgrid(np.linspace(20, 140, 7), np.linspace(20, 100, 5))
    xy = np.column_stack([u.ravel(), v.ravel()])
    expected, got = flat.pixel_to_ray(xy), meshes.pixel_to_ray(xy)
    assert got.valid.all()
    np.testing.assert_allclose(got.origins, expected.origins, atol=1e-12)
    np.testing.assert_allclose(got.directions, expected.directions, atol=1e-13)


LENS = Lens(focal_length=0.05, pixel_pitch=20e-6, sensor_size=(160, 120))


def test_face_window_equals_the_tank_meshes_for_a_camera_through_that_face():
    direction = window_normal(1)
    camera = look_at_camera(np.zeros(3), LENS, distance=0.8, azimuth=WINDOW_AZIMUTH)
    tank = icosahedral_tank(0.15)
    face = sight_face(tank, camera.center, np.zeros(3))
    np.testing.assert_allclose(tank.face_normals[face], direction, atol=1e-14)
    stack = wall_window(tank, face, 0.015)
    np.testing.assert_allclose(stack.normal, -direction, atol=1e-14)
    np.testing.assert_allclose(stack.offsets, [-0.165, -0.15], rtol=1e-14)
    _assert_flat_window_equals_meshes(camera, stack, tank_surfaces(tank, icosahedral_tank(0.165)))


def test_a_camera_sees_through_the_box_wall_its_line_of_sight_crosses():
    size = np.array([0.3, 0.2, 0.24])
    tank = box_tank(size)
    assert tank.is_watertight and len(tank.faces) == 12
    # Azimuth 30°, elevation 10°, 0.8 m from the centre: the line of sight crosses the
    # +Z wall (at s = 0.82 along it) after leaving the +X and +Y half-spaces (0.62, 0.28).
    camera = look_at_camera(
        np.zeros(3), LENS, distance=0.8, azimuth=np.deg2rad(30.0), elevation=np.deg2rad(10.0)
    )
    face = sight_face(tank, camera.center, np.zeros(3))
    normal, offset = face_plane(tank, face)
    np.testing.assert_allclose(normal, [0.0, 0.0, 1.0], atol=1e-15)
    assert offset == pytest.approx(0.12, rel=1e-14)
    stack = wall_window(tank, face, 0.01)
    np.testing.assert_allclose(stack.offsets, [-0.13, -0.12], rtol=1e-14)
    _assert_flat_window_equals_meshes(camera, stack, tank_surfaces(tank, box_tank(size + 0.02)))
    # The same direction from farther out in X crosses the +X wall first.
    assert np.allclose(
        face_plane(tank, sight_face(tank, [0.9, 0.0, 0.3], np.zeros(3)))[0], [1.0, 0.0, 0.0]
    )
    with pytest.raises(ValueError, match="inside the tank"):
        sight_face(tank, [0.0, 0.0, 0.05], np.zeros(3))
    with pytest.raises(ValueError, match="not inside the tank"):
        sight_face(tank, camera.center, [0.0, 0.0, 0.2])
    with pytest.raises(ValueError, match="box size"):
        box_tank([0.3, 0.2])


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), "0.1"])
def test_bad_inradius_is_rejected(bad):
    with pytest.raises(ValueError, match="inradius"):
        icosahedral_tank(bad)
