"""References that share no code with the stack: brute-force S2, D_LL, the ε deficit."""

import numpy as np
import pytest

from ptv.bins import LogBins
from ptv.stats.dissipation import dissipation_profile, plateau_epsilon
from ptv.stats.pairs import pair_sums
from simulator.presets import flow_preset
from simulator.spectra import PopeSpectrum
from simulator.truth import longitudinal_structure_function
from validation.studies.multi_dt_experiment import band_limited_spectrum
from validation.truth.independent import (
    brute_force_s2,
    exact_dll,
    log_edges,
    plateau_epsilon_reference,
    subsample_sums,
)

PARAMETERS = flow_preset("lem-10hz").parameters


def _snapshots(rng, count, particles=400):
    """Uniform particles in a slab with random velocities: S2 = 2 in every bin."""
    return [
        (rng.uniform(-0.02, 0.02, (particles, 3)) * [1, 1, 0.1], rng.normal(size=(particles, 3)))
        for _ in range(count)
    ]


def test_brute_force_sums_are_those_of_the_stack_on_the_same_groups():
    # A cross-check of two codes written apart (the claims use only the brute force).
    rng = np.random.default_rng(0)
    ((x, u),) = _snapshots(rng, 1)
    edges = log_edges(1e-3, 2e-2, 6)
    count, sum_q, sum_r, n = subsample_sums(
        x, u, edges, per_group=150, groups=2, rng=np.random.default_rng(1)
    )
    order = np.random.default_rng(1).permutation(len(x))[:300].reshape(2, 150)
    assert n == 150
    for g, rows in enumerate(order):
        stack = pair_sums(x[rows], u[rows], LogBins(1e-3, 2e-2, 6))
        np.testing.assert_array_equal(count[g], stack.count)
        np.testing.assert_allclose(sum_q[g], stack.sum_q[:, 0], rtol=1e-10)
        np.testing.assert_allclose(sum_r[g], stack.sum_r, rtol=1e-10)


def test_the_subsampling_error_is_the_scatter_of_independent_subsamples():
    rng = np.random.default_rng(2)
    edges = log_edges(2e-3, 2e-2, 4)
    runs = [brute_force_s2(_snapshots(rng, 20), edges, per_group=100, rng=rng) for _ in range(30)]
    s2 = np.array([run.s2 for run in runs])
    se = np.mean([run.se_s2() for run in runs], axis=0)
    assert np.all(np.abs(s2.mean(axis=0) - 2) < 4 * se / np.sqrt(len(runs)))
    # 30 replicates give the scatter within ±26 % (2 standard errors of an SD).
    np.testing.assert_allclose(s2.std(axis=0, ddof=1) / se, 1, atol=0.3)
    ratio, error = runs[0].mean_ratio(1.03 * runs[0].s2)
    assert ratio == pytest.approx(1.03) and 0 < error < 0.05


def test_too_few_groups_or_bad_edges_are_refused():
    rng = np.random.default_rng(3)
    with pytest.raises(ValueError, match="groups"):
        brute_force_s2(_snapshots(rng, 2), log_edges(1e-3, 1e-2, 3), groups=1)
    with pytest.raises(ValueError, match="edges"):
        brute_force_s2(_snapshots(rng, 2), np.array([1e-3, 1e-3, 2e-3]))


@pytest.mark.parametrize("spectrum", [PopeSpectrum(PARAMETERS), band_limited_spectrum(PARAMETERS)])
def test_the_quadrature_agrees_with_the_simulators_d_ll(spectrum):
    r = np.geomspace(10 * PARAMETERS.eta, PARAMETERS.L_int, 25)
    np.testing.assert_allclose(
        exact_dll(spectrum, r), longitudinal_structure_function(spectrum, r), rtol=1e-6
    )


def test_the_plateau_reference_is_the_stacks_estimator_on_the_exact_d_ll():
    spectrum = PopeSpectrum(PARAMETERS)
    r = np.geomspace(1e-3, 30e-3, 20)
    dll = longitudinal_structure_function(spectrum, r)

    def quadrature(x):
        return exact_dll(spectrum, x)

    for method in ("max", "mean"):
        stack = plateau_epsilon(
            dissipation_profile(r, dll), r_min=2e-3, r_max=20e-3, method=method
        ).epsilon
        reference = plateau_epsilon_reference(quadrature, r, r_range=(2e-3, 20e-3), method=method)
        assert reference == pytest.approx(stack, rel=1e-6)
    deficit = plateau_epsilon_reference(quadrature, r, r_range=(2e-3, 20e-3)) / PARAMETERS.epsilon
    assert 0.75 < deficit < 0.82  # docs/flow.md §2.4: the plateau is 0.78–0.81 ε
    low_c2 = plateau_epsilon_reference(quadrature, r, r_range=(2e-3, 20e-3), kolmogorov_c2=1.5)
    assert low_c2 / (deficit * PARAMETERS.epsilon) == pytest.approx((2 / 1.5) ** 1.5)


def test_the_modal_reference_equals_the_simulators_modal_dll():
    """Two sums over a DNS's modes written apart: the simulator's (its own series for
    small kr) and the reference's (SciPy's spherical Bessel function)."""
    from simulator.dns.field_statistics import modal_dll as simulator_dll
    from validation.truth.independent import modal_dll

    rng = np.random.default_rng(4)
    k = np.sqrt(np.arange(1, 400)) * 125.0
    energy = rng.uniform(0, 1e-6, len(k))
    r = np.geomspace(1e-4, 2.5e-2, 30)
    assert np.allclose(modal_dll(k, energy, r), simulator_dll(k, energy, r), rtol=1e-9)
