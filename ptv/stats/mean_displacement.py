"""The spatially averaged mean displacement against Δt, and the test that it is a line.

For zero-mean position noise ⟨ΔX⟩ = ⟨v⟩Δt + β0 with β0 = 0: a line through the origin.
A significant β0 flags a bias that does not scale with Δt (a cavity-to-cavity offset
between frames a and b, a calibration that differs between frames).
"""

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from scipy.stats import chi2 as chi2_distribution
from scipy.stats import f as f_distribution

from ptv.stats.links import RunParticles
from ptv.stats.multidt import LineFit, wls_line
from ptv.stats.snapshots import cluster_mean

__all__ = [
    "OFFSET_FALSE_ALARM",
    "MeanDisplacement",
    "mean_displacement",
    "shared_mean_displacement",
]

#: The offset test's false alarms: how often β0 = 0 is rejected when it holds.
OFFSET_FALSE_ALARM = 0.001


@dataclass(frozen=True, eq=False)
class MeanDisplacement:
    """Spatially averaged mean displacement against Δt and its line αΔt + β0.

    Attributes
    ----------
    dt : ndarray, shape (K,)
        s.
    mean : ndarray, shape (K, 3)
        ⟨ΔX⟩ over the links in the analysis volume (with a shared first frame: over the
        particles linked at every Δt), m.
    se : ndarray, shape (K, 3)
        Its standard error from the scatter of the snapshot means (snapshots are the
        independent units), m; from the particles when a run has one snapshot.
    count : ndarray of int, shape (K,)
        Links averaged.
    fit : LineFit
        Per component (3 rows): c1 = α, the mean velocity, m/s; c2 = β0, m (zero
        within se_c2 for zero-mean noise); chi2_dof of the line. A WLS line for
        independent runs; with shared particles, the least-squares line and the
        snapshot covariance of the K means (:func:`shared_mean_displacement`).
    offset_covariance : ndarray, shape (3, 3), or None
        Covariance of the three β0, m² (shared particles only: their components are
        correlated through the snapshots).
    snapshots : int or None
        Snapshots M that covariance was estimated from.
    """

    dt: np.ndarray
    mean: np.ndarray
    se: np.ndarray
    count: np.ndarray
    fit: LineFit
    offset_covariance: np.ndarray | None = None
    snapshots: int | None = None

    @property
    def se_offset_scaled(self) -> np.ndarray:
        """se of β0 times the Birge ratio max(1, sqrt(χ²/dof)), m, shape (3,).

        With a few snapshots per Δt the snapshot scatter underestimates the errors; the
        scatter of the points about the line then shows it, and this scales them up.
        """
        chi2 = np.nan_to_num(self.fit.chi2_dof, nan=1.0)
        return self.fit.se_c2 * np.sqrt(np.maximum(chi2, 1.0))

    def with_correlated_snapshots(self, tau: float) -> "MeanDisplacement":
        """The same line with its errors scaled for snapshots whose integrated
        autocorrelation time is ``tau`` (≥ 1, in snapshots): the variance of a mean of
        correlated snapshots is τ times that of independent ones
        (:mod:`ptv.stats.resampling`).

        Shared means: their covariance is scaled by τ and is worth M/τ snapshots.
        Independent means per Δt: the per-Δt errors and the intercept's are scaled by √τ
        and the fit's χ²/dof by 1/τ, so that :attr:`se_offset_scaled` counts the
        correlation once, whether it shows in the scatter about the line or not.
        """
        if tau <= 1.0:
            return self
        if self.offset_covariance is not None:
            return replace(
                self,
                offset_covariance=self.offset_covariance * tau,
                snapshots=max(4, int(self.snapshots / tau)),
            )
        grow = np.sqrt(tau)
        fit = replace(
            self.fit,
            se_c1=self.fit.se_c1 * grow,
            se_c2=self.fit.se_c2 * grow,
            cov_c1c2=self.fit.cov_c1c2 * tau,
            chi2_dof=self.fit.chi2_dof / tau,
        )
        return replace(self, se=self.se * grow, fit=fit)

    def offset_test(self, false_alarm: float = OFFSET_FALSE_ALARM) -> tuple[float, float]:
        """β0ᵀ C⁻¹ β0 and the limit it stays below when β0 = 0, but for ``false_alarm``.

        C is ``offset_covariance`` when the K means share their particles: estimated
        from M snapshots, so the statistic follows Hotelling's T², 3(M − 1)/(M − 3)
        F(3, M − 3). Otherwise C = diag(``se_offset_scaled``²) and the limit is χ²₃'s.
        """
        if self.offset_covariance is None:
            statistic = float(np.sum((self.fit.c2 / self.se_offset_scaled) ** 2))
            return statistic, float(chi2_distribution.ppf(1 - false_alarm, 3))
        beta = self.fit.c2
        statistic = float(beta @ np.linalg.solve(self.offset_covariance, beta))
        m = self.snapshots
        limit = 3 * (m - 1) / (m - 3) * f_distribution.ppf(1 - false_alarm, 3, m - 3)
        return statistic, float(limit)


def mean_displacement(runs: Sequence[RunParticles]) -> MeanDisplacement:
    """:class:`MeanDisplacement` of runs whose links are averaged run by run.

    Parameters
    ----------
    runs : sequence of K RunParticles
        One per Δt; each needs at least two used links.

    Returns
    -------
    MeanDisplacement
        A WLS line through the K means, with errors from the scatter of the snapshot
        means (from the links when a run has one snapshot).

    Raises
    ------
    ValueError
        A run with fewer than two used links.
    """
    k = len(runs)
    mean, se = np.zeros((k, 3)), np.zeros((k, 3))
    count = np.zeros(k, dtype=np.int64)
    for i, run in enumerate(runs):
        per = [d for _, d in run.snapshot_arrays() if len(d)]
        d = np.concatenate(per) if per else np.empty((0, 3))
        count[i] = len(d)
        if len(d) < 2:
            raise ValueError(
                f"Δt_{run.k} = {run.dt:.4g} s: {len(d)} link(s) in the analysis volume; "
                "too few for statistics"
            )
        if len(per) >= 2:  # cluster (snapshot) standard error
            n = np.array([len(p) for p in per], dtype=np.float64)
            mean[i], se[i] = cluster_mean(n, np.array([p.mean(axis=0) for p in per]))
        else:
            mean[i] = d.mean(axis=0)
            se[i] = d.std(axis=0, ddof=1) / np.sqrt(len(d))
    dt = np.array([r.dt for r in runs])
    sigma = np.where(se > 0, se, np.max(se) if np.max(se) > 0 else 1.0)
    fit = wls_line(np.broadcast_to(dt, (3, k)), mean.T, sigma.T)
    return MeanDisplacement(dt=dt, mean=mean, se=se, count=count, fit=fit)


def shared_mean_displacement(
    joined: Sequence[tuple[np.ndarray, np.ndarray]], dt: np.ndarray
) -> MeanDisplacement | None:
    """:class:`MeanDisplacement` of the particles followed over every Δt (shared frame a).

    The K means then share their particles, so their errors are correlated, across Δt
    and across components: their covariance Σ comes from the scatter of the snapshot
    means (snapshots are the independent units, :func:`ptv.stats.snapshots.cluster_mean`).
    The line is the least-squares one, c = L·⟨ΔX⟩ with L = (XᵀX)⁻¹Xᵀ fixed by the Δt
    alone, so Cov(c) = L Σ Lᵀ holds exactly and β0ᵀC⁻¹β0 follows Hotelling's T² (a
    GLS line would weigh the Δt by the estimated Σ, and its χ² test raise 2-3 % false
    alarms instead of 1 % at M = 30-40).

    Parameters
    ----------
    joined : sequence of (ndarray (P, 3), ndarray (P, K, 3))
        X(t) and ΔX at every Δt of the particles of each snapshot, m
        (:func:`ptv.stats.links.shared_snapshots`).
    dt : ndarray, shape (K,)
        s.

    Returns
    -------
    MeanDisplacement or None
        None when there are too few snapshots for Σ to be positive definite (M ≤ K) or
        for Hotelling's test of β0 to have degrees of freedom (M ≤ 3).
    """
    groups = [d for _, d in joined if len(d)]
    k = len(dt)
    if len(groups) <= max(k, 3):
        return None
    n = np.array([len(d) for d in groups], dtype=np.float64)
    mean, cov = cluster_mean(n, np.array([d.mean(axis=0) for d in groups]), full=True)
    cov = cov.reshape(k, 3, k, 3)
    per_component = np.stack([cov[:, c, :, c] for c in range(3)])  # (3, K, K)
    if not np.all(np.linalg.eigvalsh(per_component) > 0):
        return None
    design = np.stack([dt, np.ones_like(dt)], axis=1)
    operator = np.linalg.pinv(design)  # (2, K): slope and intercept rows
    coef = np.einsum("pk,kc->pc", operator, mean)  # (2, 3)
    cov_coef = np.einsum("pk,kcld,ql->pcqd", operator, cov, operator)  # (2, 3, 2, 3)
    residual = mean - design @ coef  # (K, 3)
    chi2 = np.array(
        [residual[:, c] @ np.linalg.solve(per_component[c], residual[:, c]) for c in range(3)]
    )
    fit = LineFit(
        c1=coef[0],
        c2=coef[1],
        se_c1=np.sqrt(np.diagonal(cov_coef[0, :, 0, :])),
        se_c2=np.sqrt(np.diagonal(cov_coef[1, :, 1, :])),
        cov_c1c2=np.diagonal(cov_coef[0, :, 1, :]).copy(),
        chi2_dof=chi2 / (k - 2) if k > 2 else np.full(3, np.nan),
        n_points=k,
        method="ols-cluster",
    )
    return MeanDisplacement(
        dt=dt,
        mean=mean,
        se=np.sqrt(np.diagonal(per_component, axis1=1, axis2=2)).T,
        count=np.full(k, int(n.sum())),
        fit=fit,
        offset_covariance=cov_coef[1, :, 1, :].copy(),
        snapshots=len(groups),
    )
