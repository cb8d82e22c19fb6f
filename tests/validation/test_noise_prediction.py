"""The noise terms predicted for the multi-Δt fit from the measured noise."""

import numpy as np

from ptv.stats.pairs import LogBins
from validation.run.checks import predicted_noise

BINS = LogBins(1e-4, 1e-2, 4)
BOX = (0.07, 0.07, 0.008)
DT = [1e-4, 2e-4, 3e-4]


def test_white_isotropic_noise_gives_twice_the_displacement_variance():
    """σ_ΔX² per component constant in Δt: c2 = 2 Σ σ² ⟨e_i²⟩ = 2σ² whatever the bin."""
    sigma = 3e-6
    got = predicted_noise({"dt": DT, "displacement_noise_m": [[sigma] * 3] * 3}, BINS, BOX)
    np.testing.assert_allclose(got.c2, 2 * sigma**2, rtol=1e-9)
    np.testing.assert_allclose(got.c2_low, got.c2)
    # c1 is the slope of a constant against Δt²: zero up to the rounding of the fit,
    # ~1e-16 of the noise's own slope scale c2/Δt_min² (a bug would give order 1 of it).
    np.testing.assert_allclose(got.c1_noise, 0.0, atol=1e-12 * 2 * sigma**2 / DT[0] ** 2)


def test_pair_noise_is_fitted_per_bin_against_dt_squared():
    """Pair noise q_k(r) = a(r) + b(r)·Δt_k²: c2 = a, the Δt² part b goes to c1."""
    a = np.array([1e-11, 2e-11, 3e-11, 4e-11])
    b = np.array([0.0, 1e-4, 2e-4, 0.0])
    per_pair = a + b * np.square(DT)[:, None]
    per_pair[1, 3] = np.nan  # a bin without pairs at one Δt
    per_pair = [[None if np.isnan(v) else v for v in row] for row in per_pair]
    doc = {"dt": DT, "pair_noise_m2": per_pair, "displacement_noise_m": [[1.0] * 3] * 3}
    got = predicted_noise(doc, BINS, BOX)
    np.testing.assert_allclose(got.c2[:3], a[:3], rtol=1e-6)
    np.testing.assert_allclose(got.c1_noise[:3], b[:3], rtol=1e-6, atol=1e-12)
    assert np.isnan(got.c2[3])
    assert np.all(got.c2_low[:3] <= got.c2[:3] * (1 + 1e-9))
