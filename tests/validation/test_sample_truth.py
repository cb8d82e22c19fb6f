"""Ensemble sample-truth S2 from exact KS velocities equals the exact D_LL."""

import numpy as np
import pytest

from ptv.bins import LogBins
from simulator.particles import ANALYSIS_VOLUME, KSFlow, follow_snapshots
from simulator.presets import flow_preset
from simulator.spectra import KolmogorovBandSpectrum, PopeSpectrum
from simulator.truth import longitudinal_structure_function
from validation.truth.sample import sample_structure_function

PARAMS = flow_preset("lem-10hz").parameters


@pytest.mark.parametrize("kind", [PopeSpectrum, KolmogorovBandSpectrum])
def test_ensemble_sample_truth_matches_exact_dll_within_3_percent(kind):
    spectrum = kind(PARAMS)
    bins = LogBins(10 * PARAMS.eta, PARAMS.L_int / 2, 12)
    sample = follow_snapshots(
        KSFlow(spectrum),
        np.array([0.0]),
        particles=1500,
        snapshots=300,
        region=ANALYSIS_VOLUME,
        rng=1,
    )
    x, u = sample.positions[:, 0], sample.velocity[:, 0]
    halves = [
        sample_structure_function(x[s], u[s], bins, region=ANALYSIS_VOLUME)
        for s in (slice(0, 150), slice(150, 300))
    ]
    total = halves[0] + halves[1]
    exact = longitudinal_structure_function(spectrum, total.mean_separation)
    rel = total.mean[:, 0] / exact - 1
    # The two independent halves bound the sampling error: the test has the power to
    # see a 3 % bias (standard error well below it).
    stderr = np.abs(halves[0].mean[:, 0] - halves[1].mean[:, 0]) / 2 / exact
    assert stderr.max() < 0.015
    assert np.abs(rel).max() < 0.03, rel


@pytest.mark.slow
def test_ensemble_sample_truth_matches_exact_dll_at_full_size():
    spectrum = PopeSpectrum(PARAMS)
    bins = LogBins(10 * PARAMS.eta, PARAMS.L_int / 2, 24)
    sample = follow_snapshots(
        KSFlow(spectrum),
        np.array([0.0]),
        particles=2000,
        snapshots=1500,
        region=ANALYSIS_VOLUME,
        rng=2,
    )
    total = sample_structure_function(
        sample.positions[:, 0], sample.velocity[:, 0], bins, region=ANALYSIS_VOLUME
    )
    exact = longitudinal_structure_function(spectrum, total.mean_separation)
    assert np.abs(total.mean[:, 0] / exact - 1).max() < 0.01
