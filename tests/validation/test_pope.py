"""Pope's spectrum written apart from the simulator, and the spectrum claim built on it."""

import numpy as np
import pytest

from simulator.presets import flow_preset
from simulator.spectra import PopeSpectrum
from validation.claims import ClaimContext, run_claims
from validation.truth.pope import energy_and_dissipation, pope_energy


def test_a_power_law_integrates_to_its_closed_form():
    # On [1, 1000]: ∫k^{-5/3} = (3/2)(1 − 1000^{-2/3}), 2ν∫k^{1/3} = 2ν(3/4)(1000^{4/3} − 1).
    energy, dissipation = energy_and_dissipation(lambda k: k ** (-5 / 3), 1.0, 1e3, nu=0.5)
    assert energy == pytest.approx(1.5 * (1 - 1e3 ** (-2 / 3)), rel=1e-12)
    assert dissipation == pytest.approx(0.75 * (1e3 ** (4 / 3) - 1), rel=1e-12)


def test_the_formula_is_kolmogorov_s_in_the_inertial_range():
    p = flow_preset("lem-10hz").parameters
    k = 30 / p.L_int  # far above 1/L, far below 1/η: f_L, f_η ≈ 1
    value = pope_energy(k, u_rms=p.u_rms, epsilon=p.epsilon, nu=p.nu, c_l=6.78, c_eta=0.40)
    assert value / (1.5 * p.epsilon ** (2 / 3) * k ** (-5 / 3)) == pytest.approx(1, abs=0.05)


def test_the_simulator_s_spectrum_is_pope_s():
    p = flow_preset("lem-10hz").parameters
    spectrum = PopeSpectrum(p)
    k = np.geomspace(spectrum.k_min, spectrum.k_max, 50)
    formula = pope_energy(
        k, u_rms=p.u_rms, epsilon=p.epsilon, nu=p.nu, c_l=spectrum.c_L, c_eta=spectrum.c_eta
    )
    np.testing.assert_allclose(spectrum.energy(k), formula, rtol=1e-12)
    (result,) = run_claims(ClaimContext("quick"), ids=["flow.pope_spectrum"])
    assert result.passed
