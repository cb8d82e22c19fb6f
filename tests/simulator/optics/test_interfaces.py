"""Flat interfaces: Snell's law at every plane, TIR, back-projection, validation."""

import numpy as np
import pytest

from simulator.optics.interfaces import (
    FlatInterfaces,
    back_project,
    flat_window,
    refract,
    trace,
)


def _unit(v):
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _random_directions(rng, n, normal, max_angle):
    """Unit directions within max_angle of ``normal``."""
    theta = rng.uniform(0, max_angle, n)
    phi = rng.uniform(0, 2 * np.pi, n)
    a = _unit(np.cross(normal, [0.3, 1.0, 0.2]))
    b = np.cross(normal, a)
    return (np.cos(theta)[:, None] * normal + np.sin(theta)[:, None]
            * (np.cos(phi)[:, None] * a + np.sin(phi)[:, None] * b))


def test_snell_and_coplanarity_at_every_interface():
    rng = np.random.default_rng(1)
    normal = _unit([0.2, -0.1, 1.0])
    stack = FlatInterfaces(normal, [0.3, 0.31, 0.312], [1.0, 1.52, 1.40, 1.333])
    d0 = _random_directions(rng, 500, normal, np.radians(60))
    origins = np.zeros((500, 3))
    path = trace(origins, d0, stack)
    assert not path.tir.any()
    for k in range(stack.n_interfaces):
        d1, d2 = path.directions[k], path.directions[k + 1]
        n1, n2 = stack.indices[k], stack.indices[k + 1]
        # the hit point lies on plane k
        np.testing.assert_allclose(path.points[k + 1] @ normal, stack.offsets[k], atol=1e-15)
        sin1 = np.linalg.norm(np.cross(d1, normal), axis=1)
        sin2 = np.linalg.norm(np.cross(d2, normal), axis=1)
        np.testing.assert_allclose(n1 * sin1, n2 * sin2, atol=1e-14)
        coplanar = np.einsum("ij,ij->i", np.cross(d1, normal), d2)
        np.testing.assert_allclose(coplanar, 0.0, atol=1e-14)
        np.testing.assert_allclose(np.linalg.norm(d2, axis=1), 1.0, atol=1e-14)
        assert np.all(d2 @ normal > 0)  # transmitted, not reflected


def test_normal_incidence_is_undeviated_and_equal_indices_change_nothing():
    normal = _unit([1.0, 2.0, 3.0])
    t, tir = refract(normal[None, :], normal, 1.0, 1.5)
    np.testing.assert_allclose(t[0], normal, atol=1e-15)
    d = _unit(np.array([[0.3, 0.1, 1.0], [-0.5, 0.2, 0.7]]))
    t, tir = refract(d, normal, 1.333, 1.333)
    np.testing.assert_allclose(t, d, atol=1e-15)
    assert not tir.any()


def test_total_internal_reflection_beyond_the_critical_angle():
    normal = np.array([0.0, 0.0, 1.0])
    critical = np.arcsin(1.0 / 1.333)
    angles = np.array([critical - 1e-6, critical + 1e-6, np.radians(80)])
    d = np.column_stack([np.sin(angles), np.zeros(3), np.cos(angles)])
    t, tir = refract(d, normal, 1.333, 1.0)
    assert tir.tolist() == [False, True, True]
    assert np.isfinite(t[0]).all() and np.isnan(t[1:]).all()
    # through a stack water | air the ray is NaN
    stack = FlatInterfaces(normal, [0.1], [1.333, 1.0])
    rays = back_project(np.zeros((3, 3)), d, stack)
    assert rays.valid.tolist() == [True, False, False]


def test_back_projection_through_a_slab_shifts_but_keeps_direction_in_same_medium():
    """air | glass | air: the exit ray is parallel to the entry ray, displaced by the
    textbook lateral shift t sin(θ−θ') / cos θ'."""
    normal = np.array([0.0, 0.0, 1.0])
    thickness, n_glass = 0.02, 1.52
    stack = FlatInterfaces(normal, [0.5, 0.5 + thickness], [1.0, n_glass, 1.0])
    theta = np.radians(np.array([0.0, 10.0, 35.0, 60.0]))
    d = np.column_stack([np.sin(theta), np.zeros(4), np.cos(theta)])
    rays = back_project(np.zeros((4, 3)), d, stack)
    np.testing.assert_allclose(rays.directions, d, atol=1e-15)
    theta_g = np.arcsin(np.sin(theta) / n_glass)
    expected_shift = thickness * np.sin(theta - theta_g) / np.cos(theta_g)
    exit_points = rays.origins
    straight = d * ((0.5 + thickness) / d[:, 2])[:, None]  # where the unrefracted ray would be
    offset = np.linalg.norm(np.cross(exit_points - straight, d), axis=1)
    np.testing.assert_allclose(offset, expected_shift, atol=1e-15)


def test_rays_moving_away_or_starting_beyond_are_invalid():
    stack = flat_window([0, 0, 1.0], 0.5, 0.01)
    origins = np.array([[0, 0, 0.0], [0, 0, 0.6], [0, 0, 0.0]])
    dirs = np.array([[0, 0, -1.0], [0, 0, 1.0], [0, 0, 1.0]])
    rays = back_project(origins, dirs, stack)
    assert rays.valid.tolist() == [False, False, True]
    np.testing.assert_allclose(rays.origins[2], [0, 0, 0.51])


@pytest.mark.parametrize(
    ("args", "kwargs", "match"),
    [
        (([0, 0, 2.0], 0.5, 0.01), {}, "unit vector"),
        (([0, 0, 0.0], 0.5, 0.01), {}, "zero vector"),
        (([0, 0, np.nan], 0.5, 0.01), {}, "finite 3-vector"),
        (([0, 0, 1.0], 0.5, -0.01), {}, "thickness.*-0.01"),
        (([0, 0, 1.0], np.inf, 0.01), {}, "distance"),
        (([0, 0, 1.0], 0.5, 0.01), {"n_glass": 0.0}, "n_glass"),
        (([0, 0, 1.0], 0.5, 0.01), {"n_water": -1.333}, "n_water"),
    ],
)
def test_bad_window_inputs_raise_naming_the_value(args, kwargs, match):
    with pytest.raises(ValueError, match=match):
        flat_window(*args, **kwargs)


def test_bad_stack_inputs_raise():
    with pytest.raises(ValueError, match="non-decreasing"):
        FlatInterfaces([0, 0, 1.0], [0.5, 0.4], [1, 1.5, 1.3])
    with pytest.raises(ValueError, match="3 refractive indices"):
        FlatInterfaces([0, 0, 1.0], [0.5, 0.6], [1, 1.5])
    with pytest.raises(ValueError, match=r"indices must be finite and > 0"):
        FlatInterfaces([0, 0, 1.0], [0.5], [1, 0])
