"""Exact two-point statistics of a gridded periodic field, against closed forms and
against plain loops that share no code with the module."""

from math import pi

import numpy as np
import pytest
import scipy.fft
from scipy.special import spherical_jn

from simulator.dns.field_statistics import (
    WEIGHTS,
    _family_moments,
    direction_increments,
    forcing_flux,
    modal_correlation,
    modal_dll,
    modal_dll_slope,
    shell_energies,
)
from simulator.dns.grid import Grid

GRID = Grid(32, 2 * pi)


def single_modes() -> np.ndarray:
    """u = 2 ŷ cos(3x) + 1 x̂ sin(5z): two transverse modes of known energies (2 and 0.25)."""
    x = GRID.coordinates()
    xx, _, zz = np.meshgrid(x, x, x, indexing="ij")
    u = np.zeros((3, *GRID.shape))
    u[1] = 2.0 * np.cos(3 * xx)
    u[0] = 1.0 * np.sin(5 * zz)
    return u


def test_shells_hold_each_mode_with_its_energy():
    uh = scipy.fft.rfftn(single_modes(), axes=(1, 2, 3))
    k, e = shell_energies(uh, GRID)
    # ½⟨u²⟩: ½·(2²/2) = 1 at |k| = 3 and ½·(1²/2) = 0.25 at |k| = 5, nothing elsewhere
    assert np.allclose(e[np.isclose(k, 3.0)], 1.0, rtol=1e-12)
    assert np.allclose(e[np.isclose(k, 5.0)], 0.25, rtol=1e-12)
    assert e.sum() == pytest.approx(1.25, rel=1e-12)
    assert np.all(np.diff(k) > 0) and k[0] == pytest.approx(1.0)
    kb, eb = shell_energies(uh, GRID, band=4.0)
    assert kb.max() <= 4.0 and eb.sum() == pytest.approx(1.0, rel=1e-12)


def test_direction_averaged_dll_of_modes_is_the_isotropic_closed_form():
    # A mode A cos(k·x), A ⊥ k, averaged over directions: |A|² [1/3 − j₁(kr)/(kr)].
    uh = scipy.fft.rfftn(single_modes(), axes=(1, 2, 3))
    k, e = shell_energies(uh, GRID)
    r = np.array([1e-4, 0.05, 0.3, 1.0, 2.5])

    def kernel(x):
        return 1.0 / 3.0 - spherical_jn(1, x) / x

    expected = 4.0 * kernel(3 * r) + 1.0 * kernel(5 * r)
    assert np.allclose(modal_dll(k, e, r), expected, rtol=1e-9, atol=1e-14)
    # B_LL = u'² − D_LL/2, u'² = (2/3)E
    assert np.allclose(modal_correlation(k, e, r), (2 / 3) * e.sum() - expected / 2, rtol=1e-9)
    # the slope against a centred difference of the closed form
    h = 1e-6
    slope = (4.0 * (kernel(3 * (r + h)) - kernel(3 * (r - h))) + kernel(5 * (r + h))) / (2 * h)
    slope -= kernel(5 * (r - h)) / (2 * h)
    assert np.allclose(modal_dll_slope(k, e, r[1:]), slope[1:], rtol=1e-6)


def test_one_direction_equals_a_plain_loop():
    rng = np.random.default_rng(2)
    u = rng.standard_normal((3, *GRID.shape))
    a = rng.standard_normal((3, *GRID.shape))
    shifts = np.array([1, 4, 16])
    step = (1, -1, 1)
    got = _family_moments(u, a, step, shifts)
    e = np.array(step) / np.sqrt(3)
    n = GRID.n
    i, j, k = np.meshgrid(np.arange(n), np.arange(n), np.arange(n), indexing="ij")
    for row, m in enumerate(shifts):
        shifted = ((i + m) % n, (j - m) % n, (k + m) % n)
        du = u[:, shifted[0], shifted[1], shifted[2]] - u
        da = a[:, shifted[0], shifted[1], shifted[2]] - a
        longitudinal = np.einsum("c,cxyz->xyz", e, du)
        assert got["s2"][row] == pytest.approx(np.mean(longitudinal**2), rel=1e-12)
        assert got["s3"][row] == pytest.approx(np.mean(longitudinal**3), rel=1e-9, abs=1e-12)
        assert got["du_da"][row] == pytest.approx(np.mean((du * da).sum(axis=0)), rel=1e-12)
        dal = np.einsum("c,cxyz->xyz", e, da)
        assert got["dul_dal"][row] == pytest.approx(np.mean(longitudinal * dal), rel=1e-12)


def test_the_direction_average_is_isotropic_where_the_axes_are_not():
    # A mode ŷ cos(x) has no longitudinal increment along any axis, but its direction
    # average is |A|² G(kr). The Lebedev rule is exact for the quartic leading term; the
    # diagonal directions, sampled only from √2 and √3 grid spacings, are carried back to
    # one spacing at constant S2/r², which errs by (kr)²(|d|² − 1)/28: at kr = 0.2, under
    # 0.3 % (a wrong weight or direction errs by tens of per cent).
    assert sum(WEIGHTS) == pytest.approx(1.0)
    x = GRID.coordinates()
    u = np.zeros((3, *GRID.shape))
    u[1] = 2.0 * np.cos(x)[:, None, None]
    got = direction_increments(u, np.array([1, 2]))
    r = GRID.spacing * np.array([1, 2])
    expected = 4.0 * (1 / 3 - spherical_jn(1, r) / r)
    assert got["s2"] == pytest.approx(expected, rel=3e-3)


def test_forcing_flux_is_four_fifths_epsilon_r_at_small_r():
    # F_LL(0) = 2ε/3, so (6/r⁴)∫₀^r y⁴ F_LL dy → (6/5)(2ε/3) r = (4/5)εr as kr → 0; the
    # next term of g is −x²/30: a relative correction of −(5/7)(kr)²/10 for one shell.
    k, e = np.array([2.0]), np.array([0.7])
    r = np.array([1e-3, 1e-2])
    got = forcing_flux(k, e, epsilon=0.3, r=r)
    expected = 0.8 * 0.3 * r * (1 - (5 / 7) * (k[0] * r) ** 2 / 10)
    assert np.allclose(got, expected, rtol=1e-7)
