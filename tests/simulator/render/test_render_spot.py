"""Spot size and brightness against the formulas of docs/imaging.md §1–2."""

import math

import numpy as np
import pytest

from simulator.render.spot import (
    LaserSheet,
    SpotOptics,
    defocus_diameter,
    diffraction_diameter,
    gaussian_sigma,
    geometric_diameter,
    image_diameter,
    mie_scale,
    particle_electrons,
)

# The paper-like example of docs/imaging.md §1: 100 µm/px object side on a 5.5 µm sensor.
PITCH = 5.5e-6
M = 0.055
FNUM = 8.0
LAMBDA = 532e-9


def test_diffraction_diameter_paper_example():
    d = diffraction_diameter(f_number=FNUM, magnification=M, wavelength=LAMBDA)
    assert d == pytest.approx(2.44 * 8.0 * 1.055 * 532e-9, rel=1e-15)
    assert d / PITCH == pytest.approx(1.99, abs=0.01)  # "d_diff ≈ 2.0 px"


def test_image_diameter_paper_example_is_three_pixels():
    d_p = 2.3 * PITCH / M  # M d_p = 2.3 px
    optics = SpotOptics(magnification=M, f_number=FNUM, wavelength=LAMBDA, pixel_pitch=PITCH)
    d_tau_px = float(optics.diameter(d_p)) / PITCH
    assert d_tau_px == pytest.approx(math.hypot(2.3, 2.44 * 8 * 1.055 * 532e-9 / PITCH))
    assert d_tau_px == pytest.approx(3.05, abs=0.02)  # "d_τ ≈ 3 px"
    assert float(optics.sigma_px(d_p)) == pytest.approx(d_tau_px / 4)


def test_diameters_add_in_quadrature():
    d_p = np.array([0.0, 50e-6, 200e-6])
    dz = np.array([1e-3, -2e-3, 0.0])
    geo = M * d_p
    diff = 2.44 * FNUM * (1 + M) * LAMBDA
    blur = M**2 * np.abs(dz) / (FNUM * (1 + M))
    np.testing.assert_allclose(geometric_diameter(d_p, magnification=M), geo, rtol=1e-15)
    np.testing.assert_allclose(
        defocus_diameter(dz, f_number=FNUM, magnification=M), blur, rtol=1e-15
    )
    got = image_diameter(d_p, magnification=M, f_number=FNUM, wavelength=LAMBDA, defocus=dz)
    np.testing.assert_allclose(got, np.sqrt(geo**2 + diff**2 + blur**2), rtol=1e-14)


def test_gaussian_sigma_conventions():
    d = np.array([3.0, 4.0])
    np.testing.assert_allclose(gaussian_sigma(d), d / 4)
    np.testing.assert_allclose(gaussian_sigma(d, convention="e2"), d / 4)
    # Adrian: exp(−4β² r²/d²) with β² = 3.67 equals exp(−r²/(2σ²)).
    sigma = gaussian_sigma(d, convention="airy")
    np.testing.assert_allclose(1 / (2 * sigma**2), 4 * 3.67 / d**2, rtol=1e-14)
    np.testing.assert_allclose(d / sigma, 5.42, atol=0.005)


def test_airy_convention_in_spot_optics():
    e2 = SpotOptics(magnification=M, f_number=FNUM)
    airy = SpotOptics(magnification=M, f_number=FNUM, convention="airy")
    ratio = float(airy.sigma_px(10e-6)) / float(e2.sigma_px(10e-6))
    assert ratio == pytest.approx(4 / 5.4185, rel=1e-4)


def test_laser_sheet_profile():
    sheet = LaserSheet(center=0.02, half_width=5e-3)
    z = 0.02 + np.array([0.0, 5e-3, -5e-3, 2.5e-3, 1.0])
    np.testing.assert_allclose(
        sheet.relative_intensity(z),
        [1.0, np.exp(-2), np.exp(-2), np.exp(-0.5), 0.0],
        rtol=1e-14,
        atol=1e-300,
    )


def test_top_hat_sheet_is_uniform_through_its_slab_and_dark_outside():
    sheet = LaserSheet(center=0.02, half_width=15e-3, profile="top-hat")
    z = 0.02 + np.array([0.0, 14.9e-3, -14.9e-3, 15.1e-3, -15.1e-3, -0.1])
    np.testing.assert_array_equal(sheet.relative_intensity(z), [1, 1, 1, 0, 0, 0])
    edges = LaserSheet(half_width=15e-3, profile="top-hat").relative_intensity([-15e-3, 15e-3])
    np.testing.assert_array_equal(edges, [1, 1])  # the slab's faces are lit
    ne = particle_electrons(
        [20e-6, 10e-6, 10e-6],
        [0.02, 0.034, 0.036],
        sheet=sheet,
        electrons_at_reference=1000.0,
        reference_diameter=10e-6,
    )
    np.testing.assert_array_equal(ne, [4000.0, 1000.0, 0.0])


def test_mie_scaling_and_electrons():
    np.testing.assert_allclose(mie_scale([10e-6, 20e-6], reference_diameter=10e-6), [1, 4])
    sheet = LaserSheet(half_width=5e-3)
    ne = particle_electrons(
        [20e-6, 10e-6],
        [0.0, 5e-3],
        sheet=sheet,
        electrons_at_reference=1000.0,
        reference_diameter=10e-6,
    )
    np.testing.assert_allclose(ne, [4000.0, 1000.0 * np.exp(-2)], rtol=1e-14)


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: diffraction_diameter(f_number=0, magnification=M, wavelength=LAMBDA), "f_number"),
        (
            lambda: diffraction_diameter(f_number=8, magnification=-1, wavelength=LAMBDA),
            "magnification",
        ),
        (
            lambda: diffraction_diameter(f_number=8, magnification=M, wavelength=np.nan),
            "wavelength",
        ),
        (lambda: geometric_diameter([1e-6, -1e-6], magnification=M), "particle_diameter"),
        (lambda: geometric_diameter([np.nan], magnification=M), "particle_diameter"),
        (lambda: defocus_diameter(np.inf, f_number=8, magnification=M), "defocus"),
        (lambda: gaussian_sigma(3.0, convention="fwhm"), "convention"),
        (lambda: gaussian_sigma(-3.0), "diameter"),
        (lambda: mie_scale(1e-6, reference_diameter=0.0), "reference_diameter"),
        (lambda: SpotOptics(magnification=M, f_number=8, pixel_pitch=0), "pixel_pitch"),
        (lambda: SpotOptics(magnification=M, f_number=8, convention="x"), "convention"),
        (lambda: LaserSheet(half_width=-1e-3), "half_width"),
        (lambda: LaserSheet(profile="uniform"), "profile"),
        (lambda: LaserSheet().relative_intensity([0.0, np.nan]), "z"),
        (
            lambda: particle_electrons(
                1e-6, 0.0, sheet=LaserSheet(), electrons_at_reference=-1, reference_diameter=1e-6
            ),
            "electrons_at_reference",
        ),
    ],
)
def test_bad_inputs_raise(call, match):
    with pytest.raises(ValueError, match=match):
        call()
