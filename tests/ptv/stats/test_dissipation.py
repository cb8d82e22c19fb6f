"""ε estimators against the inertial-range law, the paper's formula and Table 3."""

import numpy as np
import pytest

from ptv.settings import DEFAULT_C2
from ptv.stats.dissipation import (
    dissipation_profile,
    epsilon_estimate,
    epsilon_paper_caption,
    plateau_epsilon,
    turbulence_scales,
)

R = np.geomspace(1e-3, 3e-2, 15)  # m


def test_estimator_over_paper_formula_is_c2_to_the_minus_three_halves():
    s2 = 2.0 * (0.17 * R) ** (2 / 3)
    ratio = epsilon_estimate(s2, R) / epsilon_paper_caption(s2, R)
    assert DEFAULT_C2 == 2.0
    assert np.allclose(ratio, 1 / 2.83, rtol=0.01)  # claim 12
    assert np.allclose(ratio, 2.0**-1.5, rtol=1e-12)
    for c2 in (1.97, 2.1):
        r = epsilon_estimate(s2, R, kolmogorov_c2=c2) / epsilon_paper_caption(s2, R)
        assert np.allclose(r, c2**-1.5, rtol=1e-12)


@pytest.mark.parametrize("c2", [1.97, 2.0, 2.1])
@pytest.mark.parametrize("eps", [0.09, 0.17, 0.33])
def test_estimator_inverts_the_inertial_range_law_exactly(c2, eps):
    s2 = c2 * (eps * R) ** (2 / 3)
    assert np.allclose(epsilon_estimate(s2, R, kolmogorov_c2=c2), eps, rtol=1e-12)


def test_error_propagation_and_bootstrap_replicates():
    rng = np.random.default_rng(0)
    eps = 0.17
    s2 = DEFAULT_C2 * (eps * R) ** (2 / 3)
    se = 0.01 * s2
    prof = dissipation_profile(R, s2, se_s2=se)
    assert np.allclose(prof.se_epsilon / prof.epsilon, 0.015, rtol=1e-12)
    assert np.allclose(prof.epsilon_paper_caption, DEFAULT_C2**1.5 * prof.epsilon)
    # Monte Carlo: δε/ε = 1.5 δS2/S2 for small errors.
    draws = s2 * (1 + 0.01 * rng.standard_normal((20000, R.size)))
    mc = dissipation_profile(R, s2, s2_boot=draws)
    assert np.allclose(mc.epsilon_boot.std(axis=0) / prof.epsilon, 0.015, rtol=0.03)
    # An uncertain C2 adds 1.5 δC2/C2 in quadrature: ±5 % of C2 → ±7.5 % of ε.
    withc = dissipation_profile(R, s2, se_s2=0 * se, se_kolmogorov_c2=0.05 * DEFAULT_C2)
    assert np.allclose(withc.se_epsilon / withc.epsilon, 0.075)


def test_negative_or_missing_s2_gives_nan_without_warnings():
    s2 = np.array([-1e-4, np.nan, 1e-3])
    r = np.array([1e-3, 2e-3, 3e-3])
    eps = epsilon_estimate(s2, r)
    assert np.isnan(eps[0]) and np.isnan(eps[1]) and np.isfinite(eps[2])
    assert np.isnan(epsilon_paper_caption(s2, r)[0])


def test_plateau_mean_and_max():
    eps = 0.17
    bump = 1 + 0.1 * np.exp(-(np.log(R / 5e-3) ** 2))  # ε(r) peaks at 5 mm
    s2 = DEFAULT_C2 * (eps * bump * R) ** (2 / 3)
    prof = dissipation_profile(R, s2, se_s2=0.01 * s2)
    inside = (R >= 2e-3) & (R <= 1e-2)
    mean = plateau_epsilon(prof, r_min=2e-3, r_max=1e-2)
    assert np.isclose(mean.epsilon, np.mean(eps * bump[inside]), rtol=1e-12)
    assert mean.n_bins == inside.sum() and mean.method == "mean"
    assert np.isclose(
        mean.se_epsilon, 0.015 * np.sqrt(np.sum((eps * bump[inside]) ** 2)) / inside.sum()
    )
    assert np.isclose(mean.epsilon_paper_caption, DEFAULT_C2**1.5 * mean.epsilon)
    top = plateau_epsilon(prof, r_min=2e-3, r_max=1e-2, method="max")
    i = np.argmax(np.where(inside, bump, 0))
    assert np.isclose(top.epsilon, eps * bump[i]) and top.r_at_max == R[i]
    # With bootstrap replicates the plateau error is their spread.
    rng = np.random.default_rng(1)
    draws = s2 * (1 + 0.01 * rng.standard_normal((4000, R.size)))
    boot = dissipation_profile(R, s2, s2_boot=draws)
    pm = plateau_epsilon(boot, r_min=2e-3, r_max=1e-2)
    assert np.isclose(pm.se_epsilon, mean.se_epsilon, rtol=0.05)


def test_turbulence_scales_reproduce_table_3():
    # docs/flow.md §4, recomputed from the printed u′ and ε with ν = 1e-6.
    s8 = turbulence_scales(0.15, 0.09)
    assert np.isclose(s8.eta, 57.7e-6, rtol=2e-3)
    assert np.isclose(s8.tau_eta, 3.33e-3, rtol=2e-3)
    assert np.isclose(s8.re_lambda, 290.5, rtol=2e-3)
    assert np.isclose(s8.l_int, 3.75e-2, rtol=2e-3)
    assert np.isclose(turbulence_scales(0.19, 0.17).re_lambda, 339.1, rtol=2e-3)
    assert np.isclose(turbulence_scales(0.17, 0.17).re_lambda, 271.5, rtol=2e-3)
    s12 = turbulence_scales(0.24, 0.33)
    assert np.isclose(s12.l_int / s12.eta, s12.re_lambda**1.5 / 15**0.75, rtol=1e-12)


def test_bad_input_is_rejected():
    with pytest.raises(ValueError, match="r must be > 0"):
        epsilon_estimate(np.ones(2), np.array([1e-3, 0.0]))
    with pytest.raises(ValueError, match="kolmogorov_c2"):
        epsilon_estimate(np.ones(2), np.ones(2), kolmogorov_c2=0.0)
    with pytest.raises(ValueError, match="matching shapes"):
        epsilon_estimate(np.ones(2), np.ones(3))
    with pytest.raises(ValueError, match="equal length"):
        dissipation_profile(np.ones(3), np.ones(2))
    with pytest.raises(ValueError, match="s2_boot"):
        dissipation_profile(R, R, s2_boot=np.ones((4, 3)))
    prof = dissipation_profile(R, R)
    with pytest.raises(ValueError, match="no bin"):
        plateau_epsilon(prof, r_min=1.0, r_max=2.0)
    with pytest.raises(ValueError, match="r_min < r_max"):
        plateau_epsilon(prof, r_min=2e-3, r_max=1e-3)
    with pytest.raises(ValueError, match="method"):
        plateau_epsilon(prof, r_min=1e-3, r_max=2e-3, method="median")
    with pytest.raises(ValueError, match="epsilon must be finite"):
        turbulence_scales(0.1, np.nan)
