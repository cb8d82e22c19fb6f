"""The noise terms predicted for the multi-Δt fit from the measured noise."""

import json

import numpy as np
import pytest

from ptv.bins import LogBins
from ptv.stats.multidt import wls_line
from validation.run.checks import C2_MARGIN, _c2_check, c2_margin
from validation.score.noise_prediction import NoisePrediction, predicted_noise

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


def test_the_exact_positions_c2_is_taken_off_before_the_noise_comparison():
    """The fit's intercept holds the flow's own terms beyond Δt² besides the noise. On
    slow-4cam (Δt = 0.04–0.2 τ_η, noise small against S2) the exact positions' c2 was
    ~7e-12 m² beside a noise term of ~24e-12 m² at r > 10 mm: c2 alone read 1.2–1.3× the
    noise prediction. Built here from a Δt⁴ term of that size: c2 alone fails the
    comparison, c2 less the exact positions' c2 meets it."""
    dt = np.array([1.265, 2.530, 3.795, 5.060, 6.325]) * 1e-3  # slow-4cam's Δt, s
    x = dt**2
    bins = 6
    noise, truncation, c1 = 24e-12, 7e-12, 7e-4  # m², m², m²/s²
    # The Δt⁴ coefficient whose straight-line fit over these Δt has the intercept above.
    unit = wls_line(x, x**2, np.ones_like(x)).c2[0]
    quartic = truncation / unit
    exact = np.tile(c1 * x + quartic * x**2, (bins, 1))
    sigma = np.ones_like(exact)
    c2_exact = wls_line(x, exact, sigma).c2
    c2_detected = wls_line(x, exact + noise, sigma).c2
    np.testing.assert_allclose(c2_exact, truncation, rtol=1e-6)
    prediction = NoisePrediction(np.full(bins, noise), np.full(bins, noise), np.zeros(bins))
    sel = np.ones(bins, dtype=bool)
    alone = _c2_check(c2_detected[sel], prediction, sel, None)
    less = _c2_check(c2_detected[sel], prediction, sel, (c2_exact, np.zeros(bins)))
    assert alone["median_over_prediction"] == pytest.approx(1 + truncation / noise)
    assert not alone["consistent"]
    assert less["median_over_prediction"] == pytest.approx(1.0)
    assert less["consistent"]
    np.testing.assert_allclose(less["noise_free_m2"], truncation, rtol=1e-6)


def test_the_c2_margin_follows_the_error_of_the_median_where_it_is_larger():
    """Nine bins each 3 % uncertain, moving together (their pairs share the particles):
    the median is as uncertain as one, 0.03, so the margin is z times that (z = 3.29
    standard errors by default, two-sided 0.1 %); bins 1 % uncertain keep the 5 % floor."""
    assert c2_margin(np.full(9, 0.03)) == pytest.approx(3.2905 * 0.03, rel=1e-4)
    assert c2_margin(np.full(9, 0.02), 2.0) == C2_MARGIN
    assert c2_margin(np.array([0.02, 0.03, 0.04]), 4.0) == pytest.approx(0.12)
    assert c2_margin(np.full(9, 0.01)) == C2_MARGIN
    assert c2_margin(np.full(3, np.nan)) == C2_MARGIN


def test_bins_without_a_prediction_are_left_out_of_the_comparison_and_written_as_null():
    """Dense images: the truth-paired detections leave some bins without pairs at some
    Δt, so their prediction is NaN. The comparison takes the other bins, and the entry
    stays valid JSON (no NaN)."""
    bins = 5
    noise = np.array([24e-12, np.nan, 24e-12, np.nan, 24e-12])
    prediction = NoisePrediction(noise, noise, np.zeros(bins))
    sel = np.ones(bins, dtype=bool)
    c2 = np.array([24e-12, 1.0, 24e-12, 1.0, 24e-12])  # the unpredicted bins far off
    entry = _c2_check(c2, prediction, sel, None)
    assert entry["median_over_prediction"] == pytest.approx(1.0)
    assert entry["consistent"]
    assert entry["prediction_m2"][1] is None and entry["prediction_m2"][3] is None
    json.dumps(entry, allow_nan=False)
    unknown = NoisePrediction(np.full(bins, np.nan), np.full(bins, np.nan), np.zeros(bins))
    assert "consistent" not in _c2_check(c2, unknown, sel, None)
