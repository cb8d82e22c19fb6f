"""Forward refraction (Newton): against the closed-form quartic, exact tracing and
two-ray virtual images."""

import numpy as np
import pytest

from simulator.optics.forward import solve_chief_rays, virtual_image_distances
from simulator.optics.interfaces import FlatInterfaces, flat_window, trace


def _unit(v):
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _distance_to_traced_ray(center, directions, stack, points):
    path = trace(np.broadcast_to(center, directions.shape), directions, stack)
    origin, d = path.points[-1], path.directions[-1]
    return np.linalg.norm(np.cross(points - origin, d), axis=1)


def _points_behind(rng, n, stack, depth=(0.001, 0.6), lateral=1.0):
    normal = stack.normal
    a = _unit(np.cross(normal, [0.3, 1.0, 0.2]))
    b = np.cross(normal, a)
    u, v = rng.uniform(-lateral, lateral, (2, n))
    h = stack.offsets[-1] + rng.uniform(*depth, n)
    return h[:, None] * normal + u[:, None] * a + v[:, None] * b


def test_single_interface_matches_the_quartic():
    """(n_a² − n_w²) x²(ρ−x)² + n_a² h_w² x² − n_w² h_a² (ρ−x)² = 0 (docs/optics.md §4.3)."""
    n_a, n_w, h_a = 1.0, 1.333, 0.4
    stack = FlatInterfaces([0, 0, 1.0], [h_a], [n_a, n_w])
    rng = np.random.default_rng(3)
    rho = rng.uniform(0.0, 1.5, 40)
    h_w = rng.uniform(0.01, 0.5, 40)
    points = np.column_stack([rho, np.zeros(40), h_a + h_w])
    chief = solve_chief_rays(np.zeros(3), points, stack)
    assert chief.valid.all()
    x_newton = h_a * chief.directions[:, 0] / chief.directions[:, 2]
    for i in range(40):
        r, hw = rho[i], h_w[i]
        # expand in x: A x²(ρ−x)² + B x² − C (ρ−x)²
        a_, b_, c_ = n_a**2 - n_w**2, (n_a * hw) ** 2, (n_w * h_a) ** 2
        poly = (a_ * np.polynomial.Polynomial([0, 0, 1]) * np.polynomial.Polynomial([r, -1]) ** 2
                + b_ * np.polynomial.Polynomial([0, 0, 1])
                - c_ * np.polynomial.Polynomial([r, -1]) ** 2)
        roots = poly.roots()
        real = roots[(abs(roots.imag) < 1e-9) & (roots.real >= -1e-12) & (roots.real <= r + 1e-12)]
        assert len(real) >= 1
        x_true = real.real[np.argmin(abs(real.real - x_newton[i]))]
        assert x_newton[i] == pytest.approx(x_true, abs=1e-11)


@pytest.mark.parametrize(
    ("indices", "tolerance"),
    [
        ([1.0, 1.49, 1.333], 1e-12),
        ([1.0, 1.52, 1.1, 1.333], 1e-12),
        # near-grazing rays in air: x(s) is steep near s_max, s is exact to 1e-12
        ([1.333, 1.52, 1.0], 1e-9),
        ([1.0, 1.0, 1.0], 1e-12),
    ],
    ids=["air-pmma-water", "four-media", "water-glass-air", "homogeneous"],
)
def test_traced_ray_from_the_solution_passes_through_the_point(indices, tolerance):
    rng = np.random.default_rng(4)
    normal = _unit([0.1, 0.25, 1.0])
    offsets = 0.3 + np.cumsum(np.r_[0.0, rng.uniform(0.0, 0.03, len(indices) - 2)])
    stack = FlatInterfaces(normal, offsets, indices)
    points = _points_behind(rng, 2000, stack)
    center = np.array([0.01, -0.02, 0.0])
    chief = solve_chief_rays(center, points, stack)
    assert chief.valid.all()
    np.testing.assert_allclose(np.linalg.norm(chief.directions, axis=1), 1.0, atol=1e-14)
    distance = _distance_to_traced_ray(center, chief.directions, stack, points)
    assert np.max(distance) < tolerance


def test_grazing_geometry_converges():
    stack = flat_window([0, 0, 1.0], 0.05, 0.02)
    rho = np.array([0.0, 1e-9, 0.5, 5.0, 50.0])
    points = np.column_stack([rho, np.zeros(5), np.full(5, 0.5)])
    chief = solve_chief_rays(np.zeros(3), points, stack)
    assert chief.valid.all()
    np.testing.assert_allclose(chief.directions[0], [0, 0, 1.0])
    assert np.max(_distance_to_traced_ray(np.zeros(3), chief.directions, stack, points)) < 1e-10


def test_points_on_the_camera_side_are_invalid_and_camera_must_be_in_front():
    stack = flat_window([0, 0, 1.0], 0.3, 0.02)
    points = np.array([[0, 0, 0.2], [0.1, 0, 0.31], [0.1, 0, 0.5]])  # air, glass, water
    chief = solve_chief_rays(np.zeros(3), points, stack)
    assert chief.valid.tolist() == [False, False, True]
    assert np.isnan(chief.directions[:2]).all()
    with pytest.raises(ValueError, match="camera side"):
        solve_chief_rays(np.array([0, 0, 0.4]), points, stack)


def _two_ray_image(center, offset, points, stack):
    """Virtual image of a point by the closest approach of two air rays from C ± offset."""
    out = []
    for sign in (1.0, -1.0):
        c = center + sign * offset
        d = solve_chief_rays(c, points[None, :], stack).directions[0]
        out.append((c, d))
    (c1, d1), (c2, d2) = out
    w = c1 - c2
    a, b, cc, d_, e = d1 @ d1, d1 @ d2, d2 @ d2, d1 @ w, d2 @ w
    s = (b * e - cc * d_) / (a * cc - b * b)
    t = (a * e - b * d_) / (a * cc - b * b)
    return 0.5 * (c1 + s * d1 + c2 + t * d2)


def test_sagittal_and_tangential_images_match_two_ray_intersections():
    normal = np.array([0.0, 0.0, 1.0])
    stack = FlatInterfaces(normal, [0.4, 0.415], [1.0, 1.49, 1.333])
    center = np.zeros(3)
    points = np.array([[0.0, 0.0, 0.7], [0.15, 0.0, 0.7], [0.3, 0.1, 0.6], [0.6, -0.2, 0.5]])
    chief = solve_chief_rays(center, points, stack)
    sag, tan = virtual_image_distances(chief, stack)
    delta = 1e-5
    for i, p in enumerate(points):
        d = chief.directions[i]
        across = np.cross(normal, d)
        if np.linalg.norm(across) < 1e-12:  # on the normal: any two perpendicular offsets
            sagittal_dir, meridional = np.array([0.0, 1.0, 0.0]), np.array([1.0, 0.0, 0.0])
        else:
            sagittal_dir = _unit(across)  # ⊥ to the plane (d, n̂)
            meridional = _unit(np.cross(across, d))  # ⊥ d, in the plane (d, n̂)
        v_t = _two_ray_image(center, delta * meridional, p, stack)
        v_s = _two_ray_image(center, delta * sagittal_dir, p, stack)
        assert np.linalg.norm(v_t - center) == pytest.approx(tan[i], rel=1e-6)
        assert np.linalg.norm(v_s - center) == pytest.approx(sag[i], rel=1e-6)
    # at normal incidence both equal the paraxial apparent depth
    apparent = 0.4 + 0.015 / 1.49 + (0.7 - 0.415) / 1.333
    assert sag[0] == pytest.approx(apparent, rel=1e-12)
    assert tan[0] == pytest.approx(apparent, rel=1e-12)
