"""The spot kernel against an independent evaluation of pixel-integrated Gaussians."""

import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from scipy.special import erf

from ptv.reconstruct._spots import add_spots


def _numpy_spots(shape, x, y, flux, sx, sy):
    """Σ_p flux_p ½[erf((i+½−x)/√2σx) − erf((i−½−x)/√2σx)] · ½[…y…] on the whole image."""
    rows, cols = shape
    i = np.arange(cols)
    j = np.arange(rows)
    out = np.zeros(shape)
    for xp, yp, f, a, b in zip(x, y, flux, sx, sy, strict=True):
        fx = 0.5 * (erf((i + 0.5 - xp) / (np.sqrt(2) * a)) - erf((i - 0.5 - xp) / (np.sqrt(2) * a)))
        fy = 0.5 * (erf((j + 0.5 - yp) / (np.sqrt(2) * b)) - erf((j - 0.5 - yp) / (np.sqrt(2) * b)))
        out += f * np.outer(fy, fx)
    return out


def _splat(shape, x, y, flux, sx, sy, rho, radius_sigmas=6.0):
    image = np.zeros(shape)
    add_spots(
        image,
        shape[0],
        shape[1],
        *(np.asarray(v, float) for v in (x, y, flux, sx, sy, rho)),
        radius_sigmas,
    )
    return image


def test_axis_aligned_spots_match_erf_products():
    rng = np.random.default_rng(0)
    n, shape = 60, (40, 50)
    x, y = rng.uniform(-2, 52, n), rng.uniform(-2, 42, n)  # some centres off the image
    flux = rng.uniform(-500, 3000, n)  # negative flux subtracts
    sx, sy = rng.uniform(0.4, 1.6, n), rng.uniform(0.4, 1.6, n)
    ours = _splat(shape, x, y, flux, sx, sy, np.zeros(n))
    theirs = _numpy_spots(shape, x, y, flux, sx, sy)
    # the 6σ window drops < 2e-9 of each spot
    assert np.max(np.abs(ours - theirs)) < 1e-6 * np.abs(flux).max()


def test_rotated_spot_matches_supersampled_integral():
    """ρ ≠ 0: 4-point quadrature per row against 40 × 40 samples per pixel."""
    x0, y0, sx, sy, rho = 10.3, 9.8, 1.1, 0.7, 0.6
    shape = (20, 21)
    ours = _splat(shape, [x0], [y0], [1.0], [sx], [sy], [rho])
    k = 40
    u = (np.arange(k) + 0.5) / k - 0.5
    cov = np.array([[sx**2, rho * sx * sy], [rho * sx * sy, sy**2]])
    inv = np.linalg.inv(cov)
    norm = 1 / (2 * np.pi * np.sqrt(np.linalg.det(cov)))
    jj, ii = np.mgrid[0 : shape[0], 0 : shape[1]]
    sub_y = jj[..., None, None] + u[None, None, :, None] - y0
    sub_x = ii[..., None, None] + u[None, None, None, :] - x0
    q = inv[0, 0] * sub_x**2 + 2 * inv[0, 1] * sub_x * sub_y + inv[1, 1] * sub_y**2
    theirs = (norm * np.exp(-0.5 * q)).mean(axis=(2, 3))
    assert abs(ours.sum() - 1) < 1e-6
    # midpoint sampling of 1/40 px has an error of ~(1/40)²/24 of the curvature
    assert np.max(np.abs(ours - theirs)) < 2e-5


@given(
    x=st.floats(20, 28),
    y=st.floats(20, 28),
    sx=st.floats(0.4, 2.0),
    sy=st.floats(0.4, 2.0),
    rho=st.floats(-0.8, 0.8),
    shift=st.tuples(st.integers(-5, 5), st.integers(-5, 5)),
)
def test_spot_keeps_its_light_and_moves_with_its_centre(x, y, sx, sy, rho, shift):
    """A spot holds its flux, and moving its centre by whole pixels moves the image
    (its window, 6σ around the nearest pixel, inside the image)."""
    rho = 0.0 if abs(rho) < 1e-3 else rho
    shape = (48, 48)
    a = _splat(shape, [x], [y], [1.0], [sx], [sy], [rho])
    b = _splat(shape, [x + shift[0]], [y + shift[1]], [1.0], [sx], [sy], [rho])
    assert abs(a.sum() - 1) < 1e-6
    assert np.allclose(np.roll(a, (shift[1], shift[0]), axis=(0, 1)), b, atol=1e-12)


def test_residual_of_the_simulators_own_spots_is_zero():
    """The simulator's renderer (an independent implementation) against ours."""
    from ptv.reconstruct import OpticalTransferFunction, residual_image
    from simulator.render.particle_images import render_particles

    rng = np.random.default_rng(7)
    xy = rng.uniform(5, 95, (80, 2))
    electrons = rng.uniform(1000, 5000, 80)
    rendered = render_particles(xy, 0.8, electrons, shape=(100, 100)).image
    otf = OpticalTransferFunction.uniform((100, 100), 0.8, intensity=1.0)
    residual = residual_image(rendered, otf, xy, electrons, background=0.0, radius_sigmas=6.0)
    assert np.max(np.abs(residual)) < 1e-5 * electrons.max()
