"""Refraction through mesh interfaces: equal to the planar formulas, Snell on curved glass."""

import numpy as np
import pytest
import trimesh

from simulator.optics import Lens, look_at_camera
from simulator.optics.interfaces import N_PMMA, N_WATER, back_project
from simulator.optics.mesh_interfaces import (
    MeshCamera,
    MeshInterfaces,
    MeshSurface,
    back_project_meshes,
    flat_window_meshes,
    plane_mesh,
    trace_meshes,
)
from simulator.rigs import load_rig

RIG = load_rig("paper-stereo")


def pixel_sample(lens, n, seed):
    w, h = lens.sensor_size
    return np.random.default_rng(seed).uniform([-0.5, -0.5], [w - 0.5, h - 0.5], (n, 2))


def angle_between(a, b):
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.einsum("ij,ij->i", a, b))


def glass_box(stack, centre, size=1.0):
    """The glass of a flat window as one closed thin box (a single mesh)."""
    n = stack.normal
    u = np.cross(n, [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(n, u)
    transform = np.eye(4)
    transform[:3, :3] = np.column_stack([u, v, n])
    mid = 0.5 * (stack.offsets[0] + stack.offsets[1])
    transform[:3, 3] = centre + (mid - n @ centre) * n
    return trimesh.creation.box(extents=(size, size, stack.thicknesses[0]), transform=transform)


@pytest.mark.parametrize("index", [0, 1])
def test_flat_window_as_two_planar_meshes_equals_the_planar_formulas(index):
    camera = RIG.cameras[index]
    meshes = MeshCamera.from_camera(camera, flat_window_meshes(camera.interfaces, centre=[0, 0, 0]))
    xy = pixel_sample(camera.lens, 4000, index)
    expected, got = camera.pixel_to_ray(xy), meshes.pixel_to_ray(xy)
    assert expected.valid.all() and got.valid.all()
    assert np.abs(got.origins - expected.origins).max() <= 1e-9
    assert angle_between(got.directions, expected.directions).max() <= 1e-12
    # The same through the bare functions.
    dirs = camera.pixel_directions(xy)
    origins = np.broadcast_to(camera.center, dirs.shape)
    flat = back_project(origins, dirs, camera.interfaces)
    mesh = back_project_meshes(origins, dirs, meshes.interfaces)
    assert np.abs(mesh.origins - flat.origins).max() <= 1e-9
    assert angle_between(mesh.directions, flat.directions).max() <= 1e-12


def test_flat_window_as_one_closed_glass_box_equals_the_planar_formulas():
    camera = RIG.cameras[1]
    stack = camera.interfaces
    box = glass_box(stack, np.zeros(3))
    interfaces = MeshInterfaces(
        (MeshSurface(box, stack.indices[0], stack.indices[1]),
         MeshSurface(box, stack.indices[1], stack.indices[2]))
    )  # fmt: skip
    meshes = MeshCamera.from_camera(camera, interfaces)
    xy = pixel_sample(camera.lens, 3000, 7)
    expected, got = camera.pixel_to_ray(xy), meshes.pixel_to_ray(xy)
    assert got.valid.all()
    assert np.abs(got.origins - expected.origins).max() <= 1e-9
    assert angle_between(got.directions, expected.directions).max() <= 1e-12


def test_project_through_meshes_equals_the_flat_newton_projection():
    camera = RIG.cameras[0]
    meshes = MeshCamera.from_camera(camera, flat_window_meshes(camera.interfaces, centre=[0, 0, 0]))
    points = np.random.default_rng(3).uniform([-0.05, -0.05, -0.005], [0.05, 0.05, 0.005], (300, 3))
    expected = camera.project(points)
    expected = expected[0] if isinstance(expected, tuple) else expected
    got = meshes.project(points)
    assert np.isfinite(got).all()
    assert np.abs(got - expected).max() <= 1e-6


def cylindrical_window(radius_in=0.15, thickness=0.012, sections=180):
    """A cylindrical glass wall (axis along Y through the origin) seen from +Z."""
    rotate = trimesh.transformations.rotation_matrix(np.pi / 2, [1.0, 0.0, 0.0])
    outer = trimesh.creation.cylinder(radius_in + thickness, 0.5, sections=sections)
    inner = trimesh.creation.cylinder(radius_in, 0.5, sections=sections)
    outer.apply_transform(rotate)
    inner.apply_transform(rotate)
    return MeshInterfaces((MeshSurface(outer, 1.0, N_PMMA), MeshSurface(inner, N_PMMA, N_WATER)))


def test_curved_window_obeys_snell_and_coplanarity_at_every_hit():
    lens = Lens(focal_length=0.035, pixel_pitch=10e-6, sensor_size=(400, 300))
    camera = look_at_camera([0.0, 0.0, 0.0], lens, distance=0.7, azimuth=0.3, elevation=0.1)
    meshes = MeshCamera(camera, cylindrical_window())
    xy = pixel_sample(lens, 2000, 11)
    path = meshes.trace(xy)
    assert not path.missed.any() and not path.tir.any()
    indices = meshes.interfaces.indices
    n_faces = set()
    for k in range(2):
        d_in, d_out, normal = path.directions[k], path.directions[k + 1], path.normals[k]
        assert (np.einsum("ij,ij->i", normal, d_in) < 0).all()  # normal faces the incoming ray
        sin_in = np.linalg.norm(np.cross(normal, d_in), axis=1)
        sin_out = np.linalg.norm(np.cross(normal, d_out), axis=1)
        np.testing.assert_allclose(indices[k] * sin_in, indices[k + 1] * sin_out, atol=1e-12)
        coplanar = np.einsum("ij,ij->i", np.cross(d_in, d_out), normal)
        assert np.abs(coplanar).max() < 1e-13
        assert (np.einsum("ij,ij->i", normal, d_out) < 0).all()  # transmitted, not reflected
        # The hit point lies on its triangle's plane and on the incoming ray.
        surface = meshes.interfaces.surfaces[k]
        tri = surface.mesh.vertices[surface.mesh.faces[path.faces[k]]]
        on_plane = np.einsum("ij,ij->i", normal, path.points[k + 1] - tri[:, 0])
        assert np.abs(on_plane).max() < 1e-14
        along = path.points[k + 1] - path.points[k]
        assert np.linalg.norm(np.cross(along, d_in), axis=1).max() < 1e-14
        n_faces.add(len(np.unique(path.faces[k])))
        # The wall is curved: the rays really bend, by different amounts across the field.
        bend = angle_between(d_in, d_out)
        assert bend.max() > 1e-2 and bend.std() > 1e-3
    assert min(n_faces) > 10  # many facets used
    # Projection: a faceted wall is a set of prisms, so a point in water can have several
    # images (one per facet); Newton finds one of them. Every pixel it returns must see
    # the point exactly.
    points = meshes.pixel_to_ray(xy[:300]).point_at(0.12)
    back = meshes.project(points)
    found = np.isfinite(back).all(axis=1)
    assert found.mean() > 0.75
    rays = meshes.pixel_to_ray(back[found])
    offset = points[found] - rays.origins
    miss = np.cross(offset, rays.directions)
    assert np.linalg.norm(miss, axis=1).max() < 1e-9


def test_misses_and_total_internal_reflection_are_nan():
    glass_air = MeshInterfaces(
        (MeshSurface(plane_mesh([0.0, 0.0, 1.0], 0.0, centre=[0, 0, 0], size=4.0), 1.5, 1.0),)
    )
    origins = np.array([[0.0, 0.0, -1.0]] * 3)
    steep, grazing = np.array([0.0, 0.1, 1.0]), np.array([0.0, 1.0, 1.0])  # 45° > critical 41.8°
    directions = np.array([steep / np.linalg.norm(steep), grazing / np.sqrt(2), [0.0, 0.0, -1.0]])
    path = trace_meshes(origins, directions, glass_air)
    assert path.tir.tolist() == [False, True, False]
    assert path.missed.tolist() == [False, False, True]
    rays = back_project_meshes(origins, directions, glass_air)
    assert rays.valid.tolist() == [True, False, False]
    np.testing.assert_allclose(rays.origins[0], [0.0, 0.1, 0.0], atol=1e-15)
    nan_row = trace_meshes(np.full((1, 3), np.nan), np.full((1, 3), np.nan), glass_air)
    assert np.isnan(nan_row.points[-1]).all() and not nan_row.missed.any()


def test_bad_stacks_are_rejected():
    square = plane_mesh([0.0, 0.0, 1.0], 0.0, centre=[0, 0, 0], size=1.0)
    with pytest.raises(ValueError, match="index"):
        MeshInterfaces((MeshSurface(square, 1.0, 1.5), MeshSurface(square, 1.33, 1.0)))
    with pytest.raises(ValueError, match="refractive index"):
        MeshSurface(square, 1.0, -1.5)
    with pytest.raises(ValueError, match="at least one"):
        MeshInterfaces(())
    with pytest.raises(ValueError, match="flat interfaces"):
        MeshCamera(RIG.cameras[0], MeshInterfaces((MeshSurface(square, 1.0, 1.33),)))
