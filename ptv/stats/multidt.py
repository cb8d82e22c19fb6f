"""Straight-line fits y = c1·x + c2 for many bins at once: the multi-Δt noise removal.

A second moment of displacements measured at several Δt (docs/statistics.md §3) is, per bin,

    y(Δt) = c1·Δt² + c2,

with c1 the noise-free second moment of the velocity (S2 for pair increments, the
velocity variance for single points) and c2 the Δt-independent noise term. This module
fits that line in every bin at once (arrays of shape (B, K): B bins, K values of Δt):

- `wls_line`: weighted least squares with independent errors σ (closed forms of
  docs/statistics.md §3.2);
- `gls_line`: generalised least squares with a full K×K covariance per bin, for
  time-resolved (skip-frame) data whose estimates at different Δt share noise and
  samples;
- `fit_multi_dt`: the same with x = Δt² and an optional subset of the Δt;
- `fit_multi_dt_bootstrap`: weights (or covariance) and standard errors from bootstrap
  replicates of y, e.g. from `SnapshotSums.bootstrap_means` (resampled snapshots);
- `largest_dt`, `smallest_and_largest_dt`, `dt_subsets`: the paper's subset studies.

Every fit is linear in y, c = A·y with a (2, K) operator A per bin, so bootstrap
replicates are refitted with one contraction and no loop over bins.
"""

import logging
from dataclasses import dataclass

import numpy as np

__all__ = [
    "LineFit",
    "dt_subsets",
    "fit_multi_dt",
    "fit_multi_dt_bootstrap",
    "gls_line",
    "largest_dt",
    "select_dt",
    "smallest_and_largest_dt",
    "usable_bootstrap_bins",
    "wls_line",
]

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class LineFit:
    """Per-bin fit of y = c1·x + c2.

    Attributes
    ----------
    c1 : ndarray, shape (B,)
        Slope, units of y per unit of x (m²/s² for x = Δt² in s², y in m²).
    c2 : ndarray, shape (B,)
        Intercept, units of y (m² for displacement moments).
    se_c1, se_c2 : ndarray, shape (B,)
        Standard errors of c1 and c2 (same units as c1, c2).
    cov_c1c2 : ndarray, shape (B,)
        Covariance of c1 and c2, units of c1 × units of c2.
    chi2_dof : ndarray, shape (B,)
        χ²/(n − 2): of the weighted residuals (WLS), of rᵀΣ⁻¹r (GLS), or of the GLS line
        with the bootstrap covariance (bootstrap fits, see `fit_multi_dt_bootstrap`);
        NaN when n = 2.
    n_points : int
        Number n of x values used in the fit.
    method : str
        "wls", "gls", "wls-bootstrap" or "gls-bootstrap".
    c1_boot, c2_boot : ndarray, shape (R, B), or None
        The coefficients refitted on each of R bootstrap replicates (bootstrap fits
        only); their spread gives se_c1, se_c2 and cov_c1c2.
    """

    c1: np.ndarray
    c2: np.ndarray
    se_c1: np.ndarray
    se_c2: np.ndarray
    cov_c1c2: np.ndarray
    chi2_dof: np.ndarray
    n_points: int
    method: str
    c1_boot: np.ndarray | None = None
    c2_boot: np.ndarray | None = None


# ----------------------------------------------------------------------------- checks


def _as_2d(name: str, a: np.ndarray) -> np.ndarray:
    a = np.asarray(a, dtype=np.float64)
    if a.ndim == 1:
        a = a[None, :]
    if a.ndim != 2:
        raise ValueError(f"{name} must have shape (B, K) or (K,), got {a.shape}")
    if a.shape[0] == 0 or a.shape[1] == 0:
        raise ValueError(f"{name} is empty (shape {a.shape})")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} contains NaN or infinite values")
    return a


def _check_x(x: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    x = np.asarray(x, dtype=np.float64)
    if x.ndim == 1:
        x = x[None, :]
    if x.ndim != 2 or x.shape[1] != shape[1] or x.shape[0] not in (1, shape[0]):
        raise ValueError(f"x must have shape ({shape[1]},) or {shape}, got {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError("x contains NaN or infinite values")
    x = np.broadcast_to(x, shape)
    if shape[1] < 2:
        raise ValueError(f"a line needs at least 2 points per bin, got {shape[1]}")
    if np.any(np.ptp(x, axis=1) == 0):
        raise ValueError("x takes a single value in some bin: a line needs 2 distinct x")
    return x


def _check_dt(dt: np.ndarray) -> np.ndarray:
    dt = np.asarray(dt, dtype=np.float64)
    if dt.ndim != 1:
        raise ValueError(f"dt must be a 1-D array of Δt values, got shape {dt.shape}")
    if not np.all(np.isfinite(dt)) or np.any(dt <= 0):
        raise ValueError(f"dt must be finite (no NaN) and > 0, got {dt}")
    if np.unique(dt).size < 2:
        raise ValueError(f"the multi-Δt fit needs at least 2 distinct Δt values, got {dt}")
    return dt


def select_dt(use: np.ndarray | None, dt: np.ndarray) -> np.ndarray:
    """Indices of the Δt to fit, sorted, from None (all), a boolean mask or integers.

    Parameters
    ----------
    use : None, ndarray of bool, shape (K,), or ndarray of int
        The selection.
    dt : ndarray, shape (K,)
        Time separations, s.

    Returns
    -------
    ndarray of int, shape (n,)
        With at least 2 distinct Δt, else ValueError.
    """
    dt = _check_dt(dt)
    k = dt.size
    if use is None:
        return np.arange(k)
    u = np.asarray(use)
    if u.dtype == bool:
        if u.shape != (k,):
            raise ValueError(f"boolean `use` must have shape ({k},), got {u.shape}")
        idx = np.flatnonzero(u)
    elif np.issubdtype(u.dtype, np.integer):
        idx = np.unique(u.ravel())
        if idx.size and (idx.min() < -k or idx.max() >= k):
            raise ValueError(f"`use` indices {u} out of range for {k} Δt values")
        idx = np.unique(idx % k)
    else:
        raise ValueError(f"`use` must be a boolean mask or integer indices, got {u.dtype}")
    if np.unique(dt[idx]).size < 2:
        raise ValueError(
            f"the subset {idx.tolist()} has fewer than 2 distinct Δt values ({dt[idx]})"
        )
    return idx


# ---------------------------------------------------------------------- operators


def _wls_operator(x: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Linear operator A (B, 2, K) with (c1, c2) = A·y, and Cov(c) (B, 2, 2).

    The closed forms of docs/statistics.md §3.2 (S = Σw, S_x = Σwx, S_xx = Σwx², Δ = S·S_xx − S_x²,
    Var c1 = S/Δ, Var c2 = S_xx/Δ, Cov = −S_x/Δ), written with x centred on its
    weighted mean x̄ = S_x/S so that Δ = S·Σw(x − x̄)² does not cancel.
    """
    s = w.sum(axis=1)
    xbar = (w * x).sum(axis=1) / s
    xc = x - xbar[:, None]
    stt = (w * xc * xc).sum(axis=1)  # = Δ / S
    a1 = w * xc / stt[:, None]
    a2 = w / s[:, None] - xbar[:, None] * a1
    cov = np.empty((x.shape[0], 2, 2))
    cov[:, 0, 0] = 1.0 / stt  # S/Δ
    cov[:, 1, 1] = 1.0 / s + xbar**2 / stt  # S_xx/Δ
    cov[:, 0, 1] = cov[:, 1, 0] = -xbar / stt  # −S_x/Δ
    return np.stack([a1, a2], axis=1), cov


def _pd_mask(cov: np.ndarray) -> np.ndarray:
    """Bins whose covariance (B, K, K) is positive definite, judged scale-free on the
    correlation matrix (smallest eigenvalue > 1e-12), shape (B,) bool."""
    d = np.sqrt(np.clip(np.diagonal(cov, axis1=1, axis2=2), 0.0, None))
    ok = np.all(d > 0, axis=1)
    out = np.zeros(cov.shape[0], dtype=bool)
    if np.any(ok):
        corr = cov[ok] / (d[ok][:, :, None] * d[ok][:, None, :])
        out[ok] = np.linalg.eigvalsh(corr)[:, 0] > 1e-12
    return out


def _check_cov(cov: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    cov = np.asarray(cov, dtype=np.float64)
    b, k = shape
    if cov.ndim == 2:
        cov = cov[None]
    if cov.shape not in ((b, k, k), (1, k, k)):
        raise ValueError(f"cov must have shape ({b}, {k}, {k}), got {cov.shape}")
    if not np.all(np.isfinite(cov)):
        raise ValueError("cov contains NaN or infinite values")
    cov = np.broadcast_to(cov, (b, k, k))
    if not np.allclose(cov, np.swapaxes(cov, 1, 2), rtol=1e-10, atol=0.0):
        raise ValueError("cov is not symmetric")
    pd = _pd_mask(cov)
    if not np.all(pd):
        bad = np.flatnonzero(~pd)
        raise ValueError(f"cov is not positive definite in bins {bad[:10].tolist()}")
    return cov


def _gls_operator(x: np.ndarray, cov: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """GLS operator A = (XᵀΣ⁻¹X)⁻¹XᵀΣ⁻¹ (B, 2, K) and Cov(c) = (XᵀΣ⁻¹X)⁻¹ (B, 2, 2).

    x is centred and scaled per bin before solving, for conditioning, and the
    coefficients are mapped back exactly.
    """
    xbar = x.mean(axis=1)
    xs = np.ptp(x, axis=1)
    t = (x - xbar[:, None]) / xs[:, None]
    design = np.stack([t, np.ones_like(t)], axis=2)  # (B, K, 2)
    sinv_x = np.linalg.solve(cov, design)  # Σ⁻¹X
    m = np.einsum("bki,bkj->bij", design, sinv_x)
    m_inv = np.linalg.inv(m)
    a_t = np.einsum("bij,bkj->bik", m_inv, sinv_x)  # coefficients of (slope_t, intercept_t)
    # c1 = slope_t/xs, c2 = intercept_t − slope_t·x̄/xs.
    back = np.zeros((x.shape[0], 2, 2))
    back[:, 0, 0] = 1.0 / xs
    back[:, 1, 0] = -xbar / xs
    back[:, 1, 1] = 1.0
    a = np.einsum("bij,bjk->bik", back, a_t)
    c = np.einsum("bij,bjk,blk->bil", back, m_inv, back)
    return a, c


def _chi2_dof_diag(x, y, w, c1, c2) -> np.ndarray:
    n = x.shape[1]
    r = y - c1[:, None] * x - c2[:, None]
    chi2 = (w * r * r).sum(axis=1)
    return chi2 / (n - 2) if n > 2 else np.full(x.shape[0], np.nan)


def _chi2_dof_full(x, y, cov, c1, c2) -> np.ndarray:
    n = x.shape[1]
    r = y - c1[:, None] * x - c2[:, None]
    chi2 = np.einsum("bk,bk->b", r, np.linalg.solve(cov, r[:, :, None])[:, :, 0])
    return chi2 / (n - 2) if n > 2 else np.full(x.shape[0], np.nan)


def _result(a, cov_c, y, chi2_fn, method) -> LineFit:
    c = np.einsum("bik,bk->bi", a, y)
    return LineFit(
        c1=c[:, 0],
        c2=c[:, 1],
        se_c1=np.sqrt(cov_c[:, 0, 0]),
        se_c2=np.sqrt(cov_c[:, 1, 1]),
        cov_c1c2=cov_c[:, 0, 1].copy(),
        chi2_dof=chi2_fn(c[:, 0], c[:, 1]),
        n_points=y.shape[1],
        method=method,
    )


# ---------------------------------------------------------------------- public fits


def wls_line(x: np.ndarray, y: np.ndarray, sigma: np.ndarray) -> LineFit:
    """Weighted least-squares line y = c1·x + c2 in every bin.

    Parameters
    ----------
    x : ndarray, shape (K,) or (B, K)
        Abscissae (e.g. Δt², s²); at least 2 distinct values per bin.
    y : ndarray, shape (B, K) or (K,)
        Ordinates (e.g. ⟨q⟩, m²).
    sigma : ndarray, shape (B, K) or (K,)
        Standard errors of y, > 0; the weights are w = 1/σ².

    Returns
    -------
    LineFit
        c1, c2 and their covariance from the closed forms of docs/statistics.md §3.2, which take
        σ as exact (no rescaling by χ²); χ²/(n − 2) flags a bad model or bad σ.
    """
    y = _as_2d("y", y)
    sigma = _as_2d("sigma", sigma)
    if sigma.shape != y.shape:
        raise ValueError(f"sigma must have the shape of y {y.shape}, got {sigma.shape}")
    if np.any(sigma <= 0):
        raise ValueError("sigma must be > 0 everywhere (weights are 1/σ²)")
    x = _check_x(x, y.shape)
    w = 1.0 / sigma**2
    a, cov_c = _wls_operator(x, w)
    return _result(a, cov_c, y, lambda c1, c2: _chi2_dof_diag(x, y, w, c1, c2), "wls")


def gls_line(x: np.ndarray, y: np.ndarray, cov: np.ndarray) -> LineFit:
    """Generalised least-squares line y = c1·x + c2 with a full covariance per bin.

    c = (XᵀΣ⁻¹X)⁻¹XᵀΣ⁻¹y with X = [x, 1], Cov(c) = (XᵀΣ⁻¹X)⁻¹ and χ² = rᵀΣ⁻¹r.

    Parameters
    ----------
    x : ndarray, shape (K,) or (B, K)
        Abscissae, at least 2 distinct values per bin.
    y : ndarray, shape (B, K) or (K,)
        Ordinates.
    cov : ndarray, shape (B, K, K) or (K, K)
        Symmetric positive-definite covariance of y in each bin (units of y²).

    Returns
    -------
    LineFit
        With a diagonal cov this equals `wls_line` with σ = sqrt(diag cov).
    """
    y = _as_2d("y", y)
    x = _check_x(x, y.shape)
    cov = _check_cov(cov, y.shape)
    a, cov_c = _gls_operator(x, cov)
    return _result(a, cov_c, y, lambda c1, c2: _chi2_dof_full(x, y, cov, c1, c2), "gls")


def fit_multi_dt(
    dt: np.ndarray,
    y: np.ndarray,
    *,
    sigma: np.ndarray | None = None,
    cov: np.ndarray | None = None,
    use: np.ndarray | None = None,
) -> LineFit:
    """Fit y = c1·Δt² + c2 per bin (WLS with `sigma`, or GLS with `cov`).

    Parameters
    ----------
    dt : ndarray, shape (K,)
        Time separations Δt, s, > 0, at least 2 distinct.
    y : ndarray, shape (B, K)
        Second moments at each Δt (e.g. ⟨q⟩ per separation bin, m²).
    sigma : ndarray, shape (B, K), optional
        Standard errors of y (independent errors). Give exactly one of sigma, cov.
    cov : ndarray, shape (B, K, K), optional
        Full covariance of y per bin (correlated errors, time-resolved data).
    use : ndarray of bool, shape (K,), or of int, optional
        The Δt to fit (default all), e.g. `largest_dt(dt, 3)`; needs 2 distinct Δt.

    Returns
    -------
    LineFit
        c1 in units of y/s² (m²/s²), c2 in units of y.

    Examples
    --------
    One bin whose second moment is y = S2·Δt² + N with S2 = 0.5 m²/s² and a noise term
    N = 10⁻¹⁰ m²:

    >>> import numpy as np
    >>> import ptv
    >>> dt = np.array([1e-3, 2e-3, 4e-3])  # s
    >>> y = 0.5 * dt**2 + 1e-10  # m²
    >>> fit = ptv.fit_multi_dt(dt, y[None], sigma=np.full((1, 3), 1e-11))
    >>> fit.c1.round(9), (fit.c2 * 1e10).round(6)  # m²/s², 1e-10 m²
    (array([0.5]), array([1.]))
    >>> fit.se_c1 < 1e-5  # m²/s², from σ = 10⁻¹¹ m² on each y
    array([ True])
    """
    dt = _check_dt(dt)
    idx = select_dt(use, dt)
    y = _as_2d("y", y)
    if y.shape[1] != dt.size:
        raise ValueError(f"y has {y.shape[1]} columns but there are {dt.size} Δt values")
    if (sigma is None) == (cov is None):
        raise ValueError("give exactly one of sigma (WLS) or cov (GLS)")
    x = dt[idx] ** 2
    if sigma is not None:
        s = np.asarray(sigma, dtype=np.float64)
        s = s[None, :] if s.ndim == 1 else s
        if s.shape != y.shape:
            raise ValueError(f"sigma must have the shape of y {y.shape}, got {s.shape}")
        return wls_line(x, y[:, idx], s[:, idx])
    c = np.asarray(cov, dtype=np.float64)
    c = c[None] if c.ndim == 2 else c
    if c.shape != (y.shape[0], dt.size, dt.size):
        raise ValueError(f"cov must have shape ({y.shape[0]}, {dt.size}, {dt.size}), got {c.shape}")
    return gls_line(x, y[:, idx], c[:, idx][:, :, idx])


def fit_multi_dt_bootstrap(
    dt: np.ndarray,
    y: np.ndarray,
    y_boot: np.ndarray,
    *,
    gls: bool = False,
    use: np.ndarray | None = None,
) -> LineFit:
    """Fit y = c1·Δt² + c2 with errors taken from bootstrap replicates of y.

    The replicates (e.g. `SnapshotSums.bootstrap_means`, snapshots resampled with
    replacement) give the standard error of y at each Δt (WLS weights) or its full
    covariance (GLS). The nominal y and every replicate are fitted with the same
    operator; the standard errors and the covariance of (c1, c2) are the spread of the
    refitted coefficients, which includes correlations between the Δt that WLS ignores.

    χ²/(n − 2) is the goodness of fit of the straight line whichever estimator is used:
    the minimum of rᵀΣ⁻¹r (the GLS χ²) with Σ the bootstrap covariance of y, NaN where
    Σ is singular or R ≤ n. (A diagonal-weight χ² would be ≪ 1 for time-resolved data,
    whose Δt share most of their sampling error.) Σ estimated from M snapshots inflates
    χ² by roughly M/(M − n).

    Parameters
    ----------
    dt : ndarray, shape (K,)
        Time separations, s.
    y : ndarray, shape (B, K)
        Nominal second moments (all data).
    y_boot : ndarray, shape (R, B, K)
        Bootstrap replicates of y, R ≥ 2 (R ≥ K + 1 for GLS; a few hundred advised).
    gls : bool
        Use the bootstrap covariance (GLS) instead of the bootstrap σ (WLS).
    use : ndarray of bool or int, optional
        Subset of the Δt to fit.

    Returns
    -------
    LineFit
        method "wls-bootstrap" or "gls-bootstrap", with c1_boot, c2_boot (R, B).
    """
    dt = _check_dt(dt)
    idx = select_dt(use, dt)
    y = _as_2d("y", y)
    yb = np.asarray(y_boot, dtype=np.float64)
    if yb.ndim != 3 or yb.shape[1:] != y.shape:
        raise ValueError(f"y_boot must have shape (R, {y.shape[0]}, {y.shape[1]}), got {yb.shape}")
    if yb.shape[0] < 2:
        raise ValueError(f"need at least 2 bootstrap replicates, got {yb.shape[0]}")
    if not np.all(np.isfinite(yb)):
        raise ValueError("y_boot contains NaN or infinite values (empty bins in a replicate?)")
    if y.shape[1] != dt.size:
        raise ValueError(f"y has {y.shape[1]} columns but there are {dt.size} Δt values")
    ys, ybs = y[:, idx], yb[:, :, idx]
    n = idx.size
    x = np.broadcast_to(dt[idx] ** 2, ys.shape)
    dev = ybs - ybs.mean(axis=0)
    cov = np.einsum("rbk,rbl->bkl", dev, dev) / (yb.shape[0] - 1)
    pd = _pd_mask(cov) if yb.shape[0] > n else np.zeros(ys.shape[0], dtype=bool)
    if gls:
        if yb.shape[0] <= n:
            raise ValueError(f"GLS needs more bootstrap replicates ({yb.shape[0]}) than Δt ({n})")
        cov = _check_cov(cov, ys.shape)
        a, _ = _gls_operator(x, cov)
    else:
        sigma = np.sqrt((dev * dev).sum(axis=0) / (yb.shape[0] - 1))
        if np.any(sigma <= 0):
            bad = np.flatnonzero(np.any(sigma <= 0, axis=1))
            raise ValueError(f"zero bootstrap spread of y in bins {bad[:10].tolist()}")
        w = 1.0 / sigma**2
        a, _ = _wls_operator(x, w)
    c = np.einsum("bik,bk->bi", a, ys)
    cb = np.einsum("bik,rbk->rbi", a, ybs)
    cbd = cb - cb.mean(axis=0)
    cov_c = np.einsum("rbi,rbj->bij", cbd, cbd) / (yb.shape[0] - 1)
    chi2 = np.full(ys.shape[0], np.nan)
    if np.any(pd) and n > 2:
        ag, _ = _gls_operator(x[pd], cov[pd])
        cg = np.einsum("bik,bk->bi", ag, ys[pd])
        chi2[pd] = _chi2_dof_full(x[pd], ys[pd], cov[pd], cg[:, 0], cg[:, 1])
    return LineFit(
        c1=c[:, 0],
        c2=c[:, 1],
        se_c1=np.sqrt(cov_c[:, 0, 0]),
        se_c2=np.sqrt(cov_c[:, 1, 1]),
        cov_c1c2=cov_c[:, 0, 1].copy(),
        chi2_dof=chi2,
        n_points=n,
        method="gls-bootstrap" if gls else "wls-bootstrap",
        c1_boot=cb[:, :, 0],
        c2_boot=cb[:, :, 1],
    )


def usable_bootstrap_bins(
    dt: np.ndarray, y_boot: np.ndarray, *, gls: bool = False, use: np.ndarray | None = None
) -> np.ndarray:
    """Bins that `fit_multi_dt_bootstrap` can fit, shape (B,) bool.

    A bin is usable when every replicate is finite at the selected Δt, the bootstrap
    spread is > 0 at each, and (GLS) the bootstrap covariance is positive definite.

    Parameters
    ----------
    dt : ndarray, shape (K,)
        Time separations, s.
    y_boot : ndarray, shape (R, B, K)
        Bootstrap replicates.
    gls, use
        As in `fit_multi_dt_bootstrap`.
    """
    idx = select_dt(use, dt)
    yb = np.asarray(y_boot, dtype=np.float64)
    if yb.ndim != 3 or yb.shape[2] != np.size(dt):
        raise ValueError(f"y_boot must have shape (R, B, {np.size(dt)}), got {yb.shape}")
    yb = yb[:, :, idx]
    ok = np.all(np.isfinite(yb), axis=(0, 2))
    dev = np.where(ok[None, :, None], yb - yb.mean(axis=0), 0.0)
    var = (dev * dev).sum(axis=0)
    ok &= np.all(var > 0, axis=1)
    if gls and np.any(ok):
        if yb.shape[0] <= idx.size:
            return np.zeros(yb.shape[1], dtype=bool)
        cov = np.einsum("rbk,rbl->bkl", dev[:, ok], dev[:, ok])
        ok[np.flatnonzero(ok)] = _pd_mask(cov)
    return ok


# ------------------------------------------------------------------------- subsets


def largest_dt(dt: np.ndarray, n: int = 3) -> np.ndarray:
    """Indices of the n largest Δt, ascending in Δt (the paper's "3 largest Δt" study).

    Parameters
    ----------
    dt : ndarray, shape (K,)
        Time separations, s.
    n : int
        How many, 2 ≤ n ≤ K.

    Returns
    -------
    ndarray of int, shape (n,)
    """
    dt = _check_dt(dt)
    if not 2 <= n <= dt.size:
        raise ValueError(f"n must be between 2 and {dt.size}, got {n}")
    order = np.argsort(dt, kind="stable")
    idx = order[-n:]
    return idx[np.argsort(dt[idx], kind="stable")]


def smallest_and_largest_dt(dt: np.ndarray) -> np.ndarray:
    """Indices of the smallest and largest Δt (the paper's two-Δt study), shape (2,)."""
    dt = _check_dt(dt)
    return np.array([int(np.argmin(dt)), int(np.argmax(dt))])


def dt_subsets(dt: np.ndarray) -> dict[str, np.ndarray]:
    """The paper's Δt subset study: each subset smaller than the whole set, as a mask.

    "3 largest dt" (:func:`largest_dt`, needs K ≥ 4) and "smallest and largest dt"
    (:func:`smallest_and_largest_dt`, needs K ≥ 3), in that order.

    Parameters
    ----------
    dt : ndarray, shape (K,)
        Time separations, s.

    Returns
    -------
    dict of str to ndarray of bool, shape (K,)
        The Δt each subset uses.
    """
    dt = _check_dt(dt)
    chosen = {}
    if dt.size >= 4:
        chosen["3 largest dt"] = largest_dt(dt, 3)
    if dt.size >= 3:
        chosen["smallest and largest dt"] = smallest_and_largest_dt(dt)
    masks = {}
    for name, idx in chosen.items():
        mask = np.zeros(dt.size, dtype=bool)
        mask[idx] = True
        masks[name] = mask
    return masks
