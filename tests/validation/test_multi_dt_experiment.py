"""The band-limited spectrum of claim #10 and the injected Δt³ term of claim #23."""

import numpy as np
import pytest

from ptv.bins import LogBins
from ptv.stats.structure import time_resolved_sums
from simulator.presets import flow_preset
from simulator.spectra import C_KOLMOGOROV, KolmogorovBandSpectrum
from simulator.truth import longitudinal_structure_function
from validation.studies.multi_dt_experiment import add_dt3_term, band_limited_spectrum

PARAMETERS = flow_preset("lem-10hz").parameters


def test_band_cut_at_two_pi_over_eta_has_the_k41_range_of_physics_1_2():
    p = PARAMETERS
    spectrum = band_limited_spectrum(p)
    assert spectrum.k_max * p.eta == pytest.approx(2 * np.pi, rel=1e-4)
    assert 2200 < spectrum.k_max / spectrum.k_min < 3400
    r = np.geomspace(20 * p.eta, 0.2 * p.L_int, 60)
    dll = longitudinal_structure_function(spectrum, r)
    slope = np.gradient(np.log(dll), np.log(r))
    assert 0.64 < slope.min() and slope.max() < 0.72  # docs/flow.md §2.4: 0.65–0.71
    assert np.max(dll / (p.epsilon * r) ** (2 / 3)) == pytest.approx(1.91, abs=0.01)


def test_dissipation_matched_cutoff_is_the_k41_band_spectrum():
    spectrum = band_limited_spectrum(PARAMETERS, cutoff=(2 / (3 * C_KOLMOGOROV)) ** 0.75)
    reference = KolmogorovBandSpectrum(PARAMETERS)
    assert spectrum.support == pytest.approx(reference.support, rel=1e-12)


@pytest.mark.parametrize("cutoff", [0.0, -1.0, np.inf, np.nan])
def test_band_cutoff_must_be_positive_and_finite(cutoff):
    with pytest.raises(ValueError, match="cutoff"):
        band_limited_spectrum(PARAMETERS, cutoff=cutoff)


def test_dt3_term_shifts_every_pair_q_by_beta_dt_cubed():
    rng = np.random.default_rng(0)
    dt = np.array([1e-4, 2e-4, 5e-4])
    snapshots = [
        (rng.uniform(0, 0.01, (40, 3)), rng.normal(0, 1e-5, (40, dt.size, 3))) for _ in range(3)
    ]
    sums = time_resolved_sums(snapshots, LogBins(1e-3, 1e-2, 4))
    beta = -0.1
    shifted = add_dt3_term(sums, dt, beta)
    n = sums.count
    np.testing.assert_array_equal(shifted.count, n)
    np.testing.assert_allclose(shifted.sum_q / n, sums.sum_q / n + beta * dt**3, rtol=1e-12)
    # q → q + c leaves the variance of q per snapshot and bin unchanged.
    variance = sums.sum_q2 / n - (sums.sum_q / n) ** 2
    shifted_variance = shifted.sum_q2 / n - (shifted.sum_q / n) ** 2
    np.testing.assert_allclose(shifted_variance, variance, rtol=1e-9, atol=1e-30)
