"""Particle frames of a rig camera: positions, spot sizes and brightness from the optics."""

import numpy as np
import pytest

from simulator.optics import defocus_blur
from simulator.render.camera_frames import (
    ParticleLighting,
    local_magnification,
    record_particles,
    rig_lighting,
)
from simulator.render.sensor import Sensor
from simulator.render.spot import LaserSheet
from simulator.rigs import load_rig

NOISELESS = Sensor(read_noise=0.0, offset=0.0, gain=1.0, bit_depth=16, full_well=60000)


@pytest.fixture(scope="module")
def camera():
    return load_rig("paper-stereo").cameras[0]


def test_spots_sit_at_the_projected_centres_with_the_optics_size_and_sheet_brightness(camera):
    rng = np.random.default_rng(0)
    lighting = ParticleLighting()
    positions = np.column_stack(
        [rng.uniform(-0.04, 0.04, 60), rng.uniform(-0.04, 0.04, 60), rng.uniform(-4e-3, 4e-3, 60)]
    )
    frame = record_particles(camera, positions, lighting=lighting, sensor=NOISELESS, rng=1)
    assert np.allclose(frame.xy, camera.project(positions))
    # d_τ² = (M d_p)² + (2.44 f# (M+1) λ)² + blur², σ = d_τ/4 (e⁻² convention), in px.
    m = local_magnification(camera, positions)
    pitch, f_number = camera.lens.pixel_pitch, camera.lens.f_number
    m_ref = np.median(m)
    d = np.sqrt(
        (m * lighting.particle_diameter / pitch) ** 2
        + (2.44 * f_number * (m_ref + 1) * lighting.wavelength / pitch) ** 2
        + defocus_blur(camera, positions) ** 2
    )
    assert np.allclose(frame.sigma, d / 4, rtol=1e-9)
    w = lighting.sheet.half_width
    assert np.allclose(frame.electrons, 6000.0 * np.exp(-2 * positions[:, 2] ** 2 / w**2))
    # Total recorded light equals the expected electrons (gain 1, no read noise, no
    # offset) within the shot noise of the total, Poisson: σ = √N, five of them allowed.
    total = frame.electrons.sum()
    assert frame.image.sum() == pytest.approx(total, abs=5 * np.sqrt(total))


def test_a_polydisperse_seeding_scales_each_tracers_light_and_nothing_else(camera):
    positions = np.array([[0.0, 0.0, 0.0], [2e-3, 1e-3, 1e-3], [-2e-3, 0.0, -1e-3]])
    lighting = ParticleLighting()
    alike = record_particles(camera, positions, lighting=lighting, sensor=NOISELESS, rng=1)
    brightness = np.array([0.5, 1.0, 1.5])
    spread = record_particles(
        camera, positions, lighting=lighting, sensor=NOISELESS, rng=1, brightness=brightness
    )
    assert np.allclose(spread.electrons, brightness * alike.electrons, rtol=1e-12)
    assert np.array_equal(spread.xy, alike.xy) and np.array_equal(spread.sigma, alike.sigma)
    for bad in (np.ones(2), np.array([1.0, -0.1, 1.0]), np.array([1.0, np.nan, 1.0])):
        with pytest.raises(ValueError, match="brightness"):
            record_particles(camera, positions, lighting=lighting, sensor=NOISELESS, brightness=bad)


def test_magnification_matches_a_tenth_of_a_millimetre_per_pixel(camera):
    m = local_magnification(camera, np.zeros((1, 3)))
    assert m[0] * 1e-4 / camera.lens.pixel_pitch == pytest.approx(1.0, rel=0.05)


def test_particles_outside_the_lit_sheet_are_dark(camera):
    lighting = ParticleLighting()
    z = np.array([0.0, 2.1 * lighting.sheet.half_width])
    frame = record_particles(
        camera, np.column_stack([[0.0, 0.0], [0.0, 0.0], z]), lighting=lighting, sensor=NOISELESS
    )
    assert frame.visible.tolist() == [True, False]


def test_bad_positions_are_rejected(camera):
    with pytest.raises(ValueError, match="positions"):
        record_particles(camera, np.zeros((3, 2)), lighting=ParticleLighting(), sensor=NOISELESS)
    with pytest.raises(ValueError, match="particle_diameter"):
        ParticleLighting(particle_diameter=0.0)


def test_a_lit_particle_outside_the_view_is_invisible_and_the_others_are_drawn(camera):
    lighting = ParticleLighting()
    # One particle at the sheet centre, one 1 m off to the side: lit, outside every view.
    positions = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    frame = record_particles(camera, positions, lighting=lighting, sensor=NOISELESS, rng=0)
    assert frame.visible.tolist() == [True, False]
    assert np.isnan(frame.xy[1]).all() and np.isnan(frame.sigma[1])
    assert np.isfinite(frame.sigma[0])


def test_magnification_is_defined_up_to_the_sensor_edge(camera):
    """A particle imaged within a pixel of the edge (its step along Y leaves the sensor on
    one side) gets the one-sided difference: finite, and within 0.1 % of its neighbour's
    a millimetre inside (the magnification varies smoothly over the view)."""
    inside, outside = 0.0, 0.2
    for _ in range(60):  # the largest Y still imaged, by bisection
        middle = 0.5 * (inside + outside)
        seen = np.isfinite(camera.project(np.array([[0.0, middle, 0.0]]))).all()
        inside, outside = (middle, outside) if seen else (inside, middle)
    points = np.array([[0.0, inside, 0.0], [0.0, inside - 1e-3, 0.0]])
    edge, near = local_magnification(camera, points)
    assert np.isfinite(edge) and abs(edge / near - 1) < 1e-3


def test_a_rig_with_the_default_sheet_keeps_the_lighting_as_it_is():
    """No profile in the rig file: the scenario's lighting itself, so every existing rig
    renders bit-for-bit as before."""
    lighting = ParticleLighting(particle_diameter=50e-6, electrons_at_reference=3000.0)
    for name in ("paper-stereo", "box-4cam"):
        rig = load_rig(name)
        assert rig.sheet_profile == "gaussian"
        assert rig_lighting(lighting, rig) is lighting


def test_a_top_hat_rig_lights_its_whole_depth_uniformly_and_nothing_beyond():
    rig = load_rig("lpt-challenge-small")
    lighting = rig_lighting(ParticleLighting(particle_diameter=20e-6), rig)
    half = 0.5 * rig.sheet.size[2]
    assert lighting.sheet == LaserSheet(center=0.0, half_width=half, profile="top-hat")
    assert lighting.particle_diameter == 20e-6 and lighting.cutoff == 2.0
    # Across the 30 mm depth every particle gets the reference electrons; beyond it
    # (though within the Gaussian's cutoff of 2 half-widths) none, and it is not visible.
    z = np.array([0.0, 0.7 * half, -half, half, 1.05 * half, -1.5 * half])
    positions = np.column_stack([np.zeros_like(z), np.zeros_like(z), z])
    frame = record_particles(rig.cameras[0], positions, lighting=lighting, sensor=NOISELESS)
    np.testing.assert_array_equal(frame.electrons, [6000.0] * 4 + [0.0] * 2)
    assert frame.visible.tolist() == [True] * 4 + [False] * 2
    assert np.isnan(frame.xy[4:]).all()


def test_a_cutoff_inside_the_top_hat_slab_still_darkens():
    lighting = ParticleLighting(sheet=LaserSheet(half_width=10e-3, profile="top-hat"), cutoff=0.5)
    lit = lighting.lit(np.array([0.0, 4.9e-3, 5.1e-3, 9e-3]))
    np.testing.assert_array_equal(lit, [True, True, False, False])
