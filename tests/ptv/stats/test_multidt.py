"""Multi-Δt line fits against numpy's least squares, the formulas of docs/statistics.md §3.2
and Monte Carlo truth."""

import numpy as np
import pytest

from ptv.stats.multidt import (
    fit_multi_dt,
    fit_multi_dt_bootstrap,
    gls_line,
    largest_dt,
    select_dt,
    smallest_and_largest_dt,
    usable_bootstrap_bins,
    wls_line,
)

# Table 4-like Δt set (10 Hz row, s) and a 6th value: unequal spacing on purpose.
DT = np.array([0.096, 0.19, 0.29, 0.38, 0.50, 0.62]) * 1e-3
S_TRUE = 0.02  # m²/s², a velocity second moment
N_TRUE = 4 * (15e-6) ** 2  # m², 4σ² for 15 µm noise


def sigmas(rng, b, k):
    """Unequal, realistic errors of y: a fraction of y itself plus a floor."""
    y = S_TRUE * DT**2 + N_TRUE
    return y * rng.uniform(0.01, 0.05, (b, k))


def test_wls_equals_weighted_lstsq_and_the_physics_formulas():
    rng = np.random.default_rng(0)
    b, k = 7, DT.size
    x = DT**2 * rng.uniform(0.8, 1.2, (b, k))
    y = rng.normal(1e-9, 3e-10, (b, k))
    sigma = rng.uniform(1e-11, 5e-11, (b, k))
    fit = wls_line(x, y, sigma)
    for i in range(b):
        w = 1 / sigma[i] ** 2
        design = np.stack([x[i], np.ones(k)], axis=1)
        sw = np.sqrt(w)[:, None]
        coef, *_ = np.linalg.lstsq(design * sw, y[i] * sw[:, 0], rcond=None)
        cov = np.linalg.inv(design.T @ (design * w[:, None]))
        assert np.allclose([fit.c1[i], fit.c2[i]], coef, rtol=1e-9)
        assert np.isclose(fit.se_c1[i] ** 2, cov[0, 0], rtol=1e-9)
        assert np.isclose(fit.se_c2[i] ** 2, cov[1, 1], rtol=1e-9)
        assert np.isclose(fit.cov_c1c2[i], cov[0, 1], rtol=1e-9)
        # docs/statistics.md §3.2 closed forms, literally.
        s, sx, sxx = w.sum(), (w * x[i]).sum(), (w * x[i] ** 2).sum()
        sy, sxy = (w * y[i]).sum(), (w * x[i] * y[i]).sum()
        delta = s * sxx - sx**2
        assert np.isclose(fit.c1[i], (s * sxy - sx * sy) / delta, rtol=1e-7)
        assert np.isclose(fit.c2[i], (sxx * sy - sx * sxy) / delta, rtol=1e-7)
        assert np.isclose(fit.se_c1[i] ** 2, s / delta, rtol=1e-7)
        assert np.isclose(fit.se_c2[i] ** 2, sxx / delta, rtol=1e-7)
        assert np.isclose(fit.cov_c1c2[i], -sx / delta, rtol=1e-7)
        r = y[i] - coef[0] * x[i] - coef[1]
        assert np.isclose(fit.chi2_dof[i], (w * r**2).sum() / (k - 2), rtol=1e-9)


def test_wls_is_unbiased_and_its_errors_match_the_scatter():
    # Every bin is an independent repetition of the same experiment.
    rng = np.random.default_rng(1)
    b, k = 20000, DT.size
    sigma = sigmas(rng, b, k)
    y = S_TRUE * DT**2 + N_TRUE + sigma * rng.standard_normal((b, k))
    fit = fit_multi_dt(DT, y, sigma=sigma)
    pull1 = (fit.c1 - S_TRUE) / fit.se_c1
    pull2 = (fit.c2 - N_TRUE) / fit.se_c2
    tol = 4 / np.sqrt(b)
    assert abs(pull1.mean()) < tol and abs(pull2.mean()) < tol
    assert abs(pull1.std() - 1) < 0.03 and abs(pull2.std() - 1) < 0.03
    # The fitted covariance of (c1, c2) matches their empirical correlation.
    rho_fit = np.mean(fit.cov_c1c2 / (fit.se_c1 * fit.se_c2))
    assert abs(np.corrcoef(pull1, pull2)[0, 1] - rho_fit) < 0.03
    # χ²/(n − 2) averages to 1 for a correct linear model and correct σ.
    assert abs(fit.chi2_dof.mean() - 1) < 0.03
    assert fit.n_points == k and fit.method == "wls"


def test_chi2_flags_a_cubic_term():
    rng = np.random.default_rng(2)
    b, k = 2000, DT.size
    sigma = sigmas(rng, b, k)
    # A Δt³ term as large as S2·Δt² at Δt_max/2 (strong curvature).
    beta = -S_TRUE / (DT.max() / 2)
    y = S_TRUE * DT**2 + beta * DT**3 + N_TRUE + sigma * rng.standard_normal((b, k))
    fit = fit_multi_dt(DT, y, sigma=sigma)
    assert np.median(fit.chi2_dof) > 20
    # Without the cubic term the same data are consistent with a line.
    fit0 = fit_multi_dt(DT, y - beta * DT**3, sigma=sigma)
    assert np.median(fit0.chi2_dof) < 1.5


def test_gls_equals_wls_for_a_diagonal_covariance():
    rng = np.random.default_rng(3)
    b, k = 50, DT.size
    sigma = sigmas(rng, b, k)
    y = S_TRUE * DT**2 + N_TRUE + sigma * rng.standard_normal((b, k))
    cov = np.zeros((b, k, k))
    cov[:, np.arange(k), np.arange(k)] = sigma**2
    w, g = fit_multi_dt(DT, y, sigma=sigma), fit_multi_dt(DT, y, cov=cov)
    for name in ("c1", "c2", "se_c1", "se_c2", "cov_c1c2", "chi2_dof"):
        assert np.allclose(getattr(w, name), getattr(g, name), rtol=1e-8), name
    assert g.method == "gls"


def test_gls_matches_the_textbook_formula_and_the_scatter_with_correlated_errors():
    rng = np.random.default_rng(4)
    b, k = 20000, DT.size
    sig = 0.03 * (S_TRUE * DT**2 + N_TRUE)
    rho = 0.7  # shared noise, as in skip-frame data
    cov = np.outer(sig, sig) * (rho + (1 - rho) * np.eye(k))
    y = S_TRUE * DT**2 + N_TRUE + rng.standard_normal((b, k)) @ np.linalg.cholesky(cov).T
    fit = gls_line(DT**2, y, cov)
    design = np.stack([DT**2, np.ones(k)], axis=1)
    ci = np.linalg.inv(cov)
    m = np.linalg.inv(design.T @ ci @ design)
    coef = (m @ design.T @ ci @ y[:3].T).T
    assert np.allclose(np.stack([fit.c1[:3], fit.c2[:3]], 1), coef, rtol=1e-8)
    assert np.allclose(fit.se_c1, np.sqrt(m[0, 0]), rtol=1e-8)
    pull = (fit.c1 - S_TRUE) / fit.se_c1
    assert abs(pull.mean()) < 4 / np.sqrt(b)
    assert abs(pull.std() - 1) < 0.03
    assert abs(fit.chi2_dof.mean() - 1) < 0.03
    # WLS that ignores the correlation understates its error (pull std ≈ 1.27 here):
    # the test can tell them apart.
    wls = fit_multi_dt(DT, y, sigma=np.broadcast_to(sig, y.shape))
    assert ((wls.c1 - S_TRUE) / wls.se_c1).std() > 1.15


def test_bootstrap_fit_with_known_replicate_spread_matches_analytic_errors():
    rng = np.random.default_rng(5)
    b, k, r = 300, DT.size, 2000
    sigma = sigmas(rng, b, k)
    y = S_TRUE * DT**2 + N_TRUE + sigma * rng.standard_normal((b, k))
    y_boot = y + sigma * rng.standard_normal((r, b, k))  # parametric replicates
    fit = fit_multi_dt_bootstrap(DT, y, y_boot)
    ref = fit_multi_dt(DT, y, sigma=sigma)
    assert np.allclose(fit.c1, ref.c1, rtol=0.05, atol=3 * ref.se_c1.max() * 0.05)
    ratio = fit.se_c1 / ref.se_c1
    assert abs(np.median(ratio) - 1) < 0.03 and np.all(np.abs(ratio - 1) < 0.15)
    assert fit.c1_boot.shape == (r, b) and fit.method == "wls-bootstrap"
    gfit = fit_multi_dt_bootstrap(DT, y, y_boot, gls=True)
    assert abs(np.median(gfit.se_c1 / ref.se_c1) - 1) < 0.05
    assert gfit.method == "gls-bootstrap"
    assert usable_bootstrap_bins(DT, y_boot, gls=True).all()


def test_subsets_of_dt():
    assert largest_dt(DT, 3).tolist() == [3, 4, 5]
    assert smallest_and_largest_dt(DT).tolist() == [0, 5]
    shuffled = DT[[4, 0, 5, 2, 1, 3]]
    assert sorted(shuffled[largest_dt(shuffled, 3)]) == sorted(DT[3:])
    assert set(shuffled[smallest_and_largest_dt(shuffled)]) == {DT[0], DT[5]}
    rng = np.random.default_rng(6)
    sigma = sigmas(rng, 4, DT.size)
    y = S_TRUE * DT**2 + N_TRUE + sigma * rng.standard_normal(sigma.shape)
    idx = largest_dt(DT, 3)
    sub = fit_multi_dt(DT, y, sigma=sigma, use=idx)
    ref = wls_line(DT[idx] ** 2, y[:, idx], sigma[:, idx])
    assert np.allclose(sub.c1, ref.c1) and sub.n_points == 3
    mask = np.zeros(DT.size, bool)
    mask[idx] = True
    assert np.allclose(fit_multi_dt(DT, y, sigma=sigma, use=mask).c1, ref.c1)
    # Two Δt: the line passes through both points; Var c1 = (σ1² + σ2²)/(x2 − x1)².
    two = fit_multi_dt(DT, y, sigma=sigma, use=smallest_and_largest_dt(DT))
    x1, x2 = DT[0] ** 2, DT[-1] ** 2
    assert np.allclose(two.c1, (y[:, -1] - y[:, 0]) / (x2 - x1), rtol=1e-9)
    assert np.allclose(
        two.se_c1**2, (sigma[:, 0] ** 2 + sigma[:, -1] ** 2) / (x2 - x1) ** 2, rtol=1e-9
    )
    assert np.all(np.isnan(two.chi2_dof))
    assert select_dt(np.array([-1, 0]), DT).tolist() == [0, 5]


def test_bad_input_is_rejected_with_a_clear_message():
    y = np.ones((3, 2))
    s = np.ones((3, 2))
    with pytest.raises(ValueError, match="at least 2 distinct Δt"):
        fit_multi_dt(np.array([1e-3]), np.ones((3, 1)), sigma=np.ones((3, 1)))
    with pytest.raises(ValueError, match="at least 2 distinct Δt"):
        fit_multi_dt(np.array([1e-3, 1e-3]), y, sigma=s)
    with pytest.raises(ValueError, match="fewer than 2 distinct"):
        fit_multi_dt(DT, np.ones((3, 6)), sigma=np.ones((3, 6)), use=[2])
    with pytest.raises(ValueError, match="NaN"):
        fit_multi_dt(DT[:2], np.array([[1.0, np.nan]]), sigma=np.ones((1, 2)))
    with pytest.raises(ValueError, match="NaN"):
        fit_multi_dt(np.array([1e-3, np.nan]), y, sigma=s)
    with pytest.raises(ValueError, match="columns"):
        fit_multi_dt(DT, y, sigma=s)
    with pytest.raises(ValueError, match="shape of y"):
        fit_multi_dt(DT[:2], y, sigma=np.ones((2, 2)))
    with pytest.raises(ValueError, match="sigma must be > 0"):
        wls_line(DT[:2] ** 2, y, np.zeros((3, 2)))
    with pytest.raises(ValueError, match="exactly one"):
        fit_multi_dt(DT[:2], y)
    with pytest.raises(ValueError, match="empty"):
        wls_line(DT[:2] ** 2, np.ones((0, 2)), np.ones((0, 2)))
    with pytest.raises(ValueError, match="positive definite"):
        gls_line(DT[:2] ** 2, y, np.ones((3, 2, 2)))
    with pytest.raises(ValueError, match="cov must have shape"):
        gls_line(DT[:2] ** 2, y, np.ones((3, 3, 3)))
    with pytest.raises(ValueError, match="y_boot must have shape"):
        fit_multi_dt_bootstrap(DT[:2], y, np.ones((10, 3, 3)))
    with pytest.raises(ValueError, match="NaN"):
        fit_multi_dt_bootstrap(DT[:2], y, np.full((10, 3, 2), np.nan))
    with pytest.raises(ValueError, match="zero bootstrap spread"):
        fit_multi_dt_bootstrap(DT[:2], y, np.ones((10, 3, 2)))
    with pytest.raises(ValueError, match="n must be"):
        largest_dt(DT, 1)
