"""Thin-lens focus: Scheimpflug tilt vs tan θ_i = M tan θ_o, defocus blur vs Gauss/Adrian."""

import numpy as np
import pytest

from simulator.optics.lens import Lens
from simulator.optics.placement import WindowSpec, look_at_camera
from simulator.optics.scheimpflug import (
    defocus_blur,
    focus_on_plane,
    scheimpflug_focus,
    thin_lens_image_distance,
)

F, PITCH = 0.05, 5.5e-6


def _sheet_grid(half=0.15, n=61):
    g = np.linspace(-half, half, n)
    x, y = np.meshgrid(g, g)
    return np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])


def _tilt_angle(focus):
    """Angle between the sensor normal and the optical axis (OpenCV R = R_y R_x)."""
    return np.arccos(np.cos(focus.tau_x) * np.cos(focus.tau_y))


@pytest.mark.parametrize("view_deg", [20.0, 35.0, 45.0])
def test_tilt_in_air_obeys_the_scheimpflug_rule(view_deg):
    distance = 0.8
    cam = look_at_camera([0, 0, 0], Lens(F, PITCH), distance=distance,
                         azimuth=np.radians(view_deg))
    focus = scheimpflug_focus(cam)
    s_i = F * distance / (distance - F)
    assert focus.image_distance == pytest.approx(s_i, rel=1e-12)
    assert focus.focus_distance == pytest.approx(distance, rel=1e-12)
    magnification = s_i / distance
    expected = np.arctan(magnification * np.tan(np.radians(view_deg)))
    assert _tilt_angle(focus) == pytest.approx(expected, rel=1e-10)
    assert focus.tau_x == pytest.approx(0.0, abs=1e-12)  # tilt about the image y axis only
    assert focus.rms_residual < 1e-14  # a thin lens images a plane onto a plane


def test_tilt_through_a_perpendicular_window_matches_the_paraxial_rule():
    """tan θ_o,app = (n_a/n_w) tan θ_o and M from the apparent distance (docs/optics.md §3)."""
    view = np.radians(35)
    h_w, t_g, distance = 0.3, 0.015, 0.9
    cam = look_at_camera([0, 0, 0], Lens(F, PITCH), distance=distance, azimuth=view,
                         window=WindowSpec(h_w, t_g))
    focus = scheimpflug_focus(cam)
    apparent = distance - h_w - t_g + t_g / 1.49 + h_w / 1.333
    s_i = F * apparent / (apparent - F)
    assert focus.image_distance == pytest.approx(s_i, rel=1e-3)
    expected = np.arctan(s_i / apparent * np.tan(view) / 1.333)
    assert _tilt_angle(focus) == pytest.approx(expected, rel=0.02)


@pytest.mark.parametrize("view_deg", [30.0, 45.0])
def test_scheimpflug_tilt_focuses_the_sheet_and_no_tilt_does_not(view_deg):
    """f/4, 50 mm, ~0.085 mm/px object-side pixel, perpendicular window."""
    lens = Lens(F, PITCH, f_number=4.0)
    cam = look_at_camera([0, 0, 0], lens, distance=0.9, azimuth=np.radians(view_deg),
                         window=WindowSpec(0.3, 0.015))
    sheet = _sheet_grid()
    tilted = focus_on_plane(cam, tilt=True)
    flat = focus_on_plane(cam, tilt=False)
    object_pixel = PITCH / (tilted.lens.image_distance / tilted.lens.focus_distance)
    assert 0.07e-3 < object_pixel < 0.11e-3
    seen = np.isfinite(tilted.project(sheet)).all(axis=1)
    seen_flat = np.isfinite(flat.project(sheet)).all(axis=1)
    assert seen.sum() > 500 and seen_flat.sum() > 500
    blur_tilted = defocus_blur(tilted, sheet[seen])
    blur_flat = defocus_blur(flat, sheet[seen_flat])
    assert np.max(blur_tilted) <= 1.0
    x_seen = sheet[seen_flat, 0]
    edges = np.abs(x_seen) > 0.8 * np.max(np.abs(x_seen))
    assert np.min(blur_flat[edges]) > 2.0
    # the conventional camera is sharp where its axis meets the sheet
    assert defocus_blur(flat, np.zeros((1, 3)))[0] < 1e-6


def test_axial_blur_matches_gauss_and_adrian():
    lens = Lens(F, PITCH, f_number=8.0)
    s_o = 0.8
    cam = focus_on_plane(look_at_camera([0, 0, 0], lens, distance=s_o, azimuth=0.0),
                         tilt=False)
    assert cam.lens.image_distance == pytest.approx(F * s_o / (s_o - F), rel=1e-12)
    dz = np.array([-0.01, -0.001, 0.001, 0.01])
    points = np.column_stack([np.zeros(4), np.zeros(4), -dz])  # camera looks along −Z
    blur = defocus_blur(cam, points) * PITCH
    s_i = cam.lens.image_distance
    z_i = F * (s_o + dz) / (s_o + dz - F)
    exact = (F / 8.0) * np.abs(s_i - z_i) / z_i
    np.testing.assert_allclose(blur, exact, rtol=1e-9)
    m = s_i / s_o
    adrian = m**2 * np.abs(dz) / (8.0 * (1 + m))
    np.testing.assert_allclose(blur, adrian, rtol=0.02)


def test_axial_blur_through_a_window_uses_the_apparent_depth():
    lens = Lens(F, PITCH, f_number=8.0)
    cam = focus_on_plane(
        look_at_camera([0, 0, 0], lens, distance=0.9, azimuth=0.0, window=WindowSpec(0.3)),
        tilt=False,
    )
    dz = 0.003
    blur = defocus_blur(cam, np.array([[0, 0, -dz]]))[0] * PITCH
    m = cam.lens.image_distance / cam.lens.focus_distance
    adrian_apparent = m**2 * (dz / 1.333) / (8.0 * (1 + m))
    assert blur == pytest.approx(adrian_apparent, rel=0.02)


def test_thin_lens_image_distance():
    assert thin_lens_image_distance(0.05, 1.0) == pytest.approx(0.05 / 0.95)
    assert np.isnan(thin_lens_image_distance(0.05, 0.04))


def test_bad_plane_inputs_raise():
    cam = look_at_camera([0, 0, 0], Lens(F, PITCH), distance=0.8, azimuth=0.3)
    with pytest.raises(ValueError, match="plane_normal"):
        scheimpflug_focus(cam, plane_normal=(0, 0, 0))
    with pytest.raises(ValueError, match="plane_point"):
        scheimpflug_focus(cam, plane_point=(0, np.nan, 0))
    with pytest.raises(ValueError, match=r"need >= 3"):
        scheimpflug_focus(cam, plane_point=(0, 0, 5.0))  # behind the camera
