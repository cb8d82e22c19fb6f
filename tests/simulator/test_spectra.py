"""Spectra: energy and dissipation match (u', ε, ν); Pope's constants; the K41 band."""

import numpy as np
import pytest

from simulator.spectra import KolmogorovBandSpectrum, PopeSpectrum, discretise
from simulator.turbulence import TurbulenceParameters

PRESET_FLOWS = [(0.15, 0.09), (0.19, 0.17), (0.24, 0.33)]


@pytest.mark.parametrize(("u", "eps"), PRESET_FLOWS)
def test_pope_energy_and_dissipation_match_within_half_percent(u, eps):
    p = TurbulenceParameters(u, eps)
    s = PopeSpectrum(p)
    assert s.kinetic_energy() == pytest.approx(p.k_t, rel=5e-3)
    assert s.dissipation() == pytest.approx(p.epsilon, rel=5e-3)
    modes = discretise(s, 200)
    assert modes.energy.sum() == pytest.approx(p.k_t, rel=5e-3)
    assert 2 * p.nu * np.sum(modes.k**2 * modes.energy) == pytest.approx(p.epsilon, rel=5e-3)


@pytest.mark.parametrize(
    ("u", "eps", "c_l"), [(0.15, 0.09, 6.135), (0.19, 0.17, 6.221), (0.24, 0.33, 6.289)]
)
def test_pope_constants_match_published_values(u, eps, c_l):
    # docs/flow.md §2.1: c_L = 6.135 / 6.221 / 6.289, c_eta = 0.403 at these R_lambda.
    s = PopeSpectrum(TurbulenceParameters(u, eps))
    assert s.c_L == pytest.approx(c_l, abs=2e-3)
    assert s.c_eta == pytest.approx(0.403, abs=1.5e-3)


def test_pope_constants_tend_to_high_reynolds_limit():
    s = PopeSpectrum(TurbulenceParameters(1.0, 0.01))  # R_lambda ≈ 3.9e4
    assert s.c_L == pytest.approx(6.78, abs=0.02)
    assert s.c_eta == pytest.approx(0.40, abs=0.005)


@pytest.mark.parametrize(("u", "eps"), PRESET_FLOWS)
def test_k41_band_cutoff_dissipates_epsilon(u, eps):
    p = TurbulenceParameters(u, eps)
    s = KolmogorovBandSpectrum(p)
    c_k = 1.5
    assert s.k_max * p.eta == pytest.approx((2 / (3 * c_k)) ** 0.75, rel=2e-3)
    k = np.geomspace(s.k_min, s.k_max, 200001)
    assert np.trapezoid(s.energy(k), k) == pytest.approx(p.k_t, rel=1e-6)
    assert 2 * p.nu * np.trapezoid(k**2 * s.energy(k), k) == pytest.approx(p.epsilon, rel=1e-6)
    assert s.energy(np.array([0.5 * s.k_min, 2 * s.k_max])).tolist() == [0.0, 0.0]


def test_discretisation_is_geometric_with_trapezoid_weights():
    s = KolmogorovBandSpectrum(TurbulenceParameters(0.19, 0.17))
    m = discretise(s, 50)
    ratio = m.k[1:] / m.k[:-1]
    assert np.allclose(ratio, ratio[0], rtol=1e-12)
    assert m.k[0] == s.k_min and m.k[-1] == s.k_max
    assert m.dk.sum() == pytest.approx(s.k_max - s.k_min, rel=1e-12)


@pytest.mark.parametrize("n", [0, 1, 2.5, -3])
def test_fewer_than_two_modes_is_an_error(n):
    s = KolmogorovBandSpectrum(TurbulenceParameters(0.19, 0.17))
    with pytest.raises(ValueError, match="n_modes"):
        discretise(s, n)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"u_rms": 0.1, "epsilon": 0.0}, "epsilon"),
        ({"u_rms": 0.1, "epsilon": -1.0}, "epsilon"),
        ({"u_rms": 0.1, "epsilon": 0.1, "nu": 0.0}, "nu"),
        ({"u_rms": 0.1, "epsilon": 0.1, "nu": -1e-6}, "nu"),
        ({"u_rms": float("nan"), "epsilon": 0.1}, "u_rms"),
    ],
)
def test_bad_parameters_name_the_field(kwargs, name):
    with pytest.raises(ValueError, match=name):
        TurbulenceParameters(**kwargs)
