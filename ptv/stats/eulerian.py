"""Eulerian single-point statistics from displacements at several Δt.

Displacements ΔX = X(t + Δt) − X(t) are binned on a regular grid by the measured X(t).
Per cell and Δt the mean ⟨ΔX⟩ and the variance ⟨(ΔX − ⟨ΔX⟩)²⟩ (the mean displacement
of the cell subtracted) are formed per component. Then, per cell and component
(docs/statistics.md §7, the paper's section 3):

- ⟨ΔX⟩ = α·Δt + β0: α is the mean velocity; β0 = 0 within its error when the noise
  has zero mean (the paper's test). Holds when the mean acceleration in the cell is
  small (⟨ΔX⟩ = ⟨v⟩Δt + ½⟨a|X⟩Δt²).
- Var ΔX = α·Δt² + β: α is the velocity variance, β = 2σ_b² the noise term. The
  velocity-gradient variance inside a cell of size h, (∇U·h)²/12, is part of α.

u′ (rms of one component) is the square root of the spatial average over cells (and
components) of the fitted variance (`u_prime`).

Standard errors treat the displacements of a cell as independent samples
(σ/√n for the mean, sqrt((μ4 − (n−3)/(n−1)σ⁴)/n) for the variance); particles of one
snapshot in one cell are correlated, so these are lower bounds.
"""

import logging
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ptv.stats.multidt import fit_multi_dt, select_dt, wls_line

__all__ = [
    "CellSums",
    "EulerianFit",
    "EulerianMoments",
    "Grid",
    "UPrime",
    "cell_sums",
    "eulerian_fit",
    "eulerian_moments",
    "u_prime",
    "u_prime_replicates",
]

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class Grid:
    """Regular grid of cells [lower, upper) along X, Y, Z.

    Parameters
    ----------
    lower, upper : tuple of 3 floats
        Corners, m, lower < upper in each axis.
    shape : tuple of 3 ints
        Cells per axis, ≥ 1. Cells are numbered in C order (X slowest).
    """

    lower: tuple[float, float, float]
    upper: tuple[float, float, float]
    shape: tuple[int, int, int]

    def __post_init__(self) -> None:
        lo = np.asarray(self.lower, dtype=np.float64)
        hi = np.asarray(self.upper, dtype=np.float64)
        sh = np.asarray(self.shape)
        if lo.shape != (3,) or hi.shape != (3,) or sh.shape != (3,):
            raise ValueError(
                f"lower, upper and shape must have 3 entries, got {self.lower}, "
                f"{self.upper}, {self.shape}"
            )
        if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)) and np.all(lo < hi)):
            raise ValueError(f"need finite lower < upper, got {self.lower} and {self.upper}")
        if not np.issubdtype(sh.dtype, np.integer) or np.any(sh < 1):
            raise ValueError(f"shape must be 3 integers >= 1, got {self.shape}")
        object.__setattr__(self, "lower", tuple(float(v) for v in lo))
        object.__setattr__(self, "upper", tuple(float(v) for v in hi))
        object.__setattr__(self, "shape", tuple(int(v) for v in sh))

    @property
    def n_cells(self) -> int:
        """G = product of shape."""
        return int(np.prod(self.shape))

    @property
    def centres(self) -> np.ndarray:
        """Cell centres, shape (G, 3), m, in the order of cell indices."""
        axes = [
            lo + (np.arange(n) + 0.5) * (hi - lo) / n
            for lo, hi, n in zip(self.lower, self.upper, self.shape, strict=True)
        ]
        mesh = np.meshgrid(*axes, indexing="ij")
        return np.stack([m.ravel() for m in mesh], axis=1)

    def index(self, points: np.ndarray) -> np.ndarray:
        """Flat cell index of each point, shape (N,), −1 outside the grid.

        Parameters
        ----------
        points : ndarray, shape (N, 3)
            Positions, m, finite.
        """
        p = np.asarray(points, dtype=np.float64)
        if p.ndim != 2 or p.shape[1] != 3:
            raise ValueError(f"points must have shape (N, 3), got {p.shape}")
        if not np.all(np.isfinite(p)):
            raise ValueError("points contain NaN or infinite values")
        lo, hi, sh = np.array(self.lower), np.array(self.upper), np.array(self.shape)
        ijk = np.floor((p - lo) / (hi - lo) * sh).astype(np.int64)
        inside = np.all((ijk >= 0) & (ijk < sh), axis=1)
        flat = np.ravel_multi_index(tuple(np.clip(ijk, 0, sh - 1).T), self.shape)
        return np.where(inside, flat, -1)


@dataclass(frozen=True)
class EulerianMoments:
    """Per-cell moments of displacements at each Δt.

    Attributes
    ----------
    dt : ndarray, shape (K,)
        Time separations, s.
    count : ndarray of int64, shape (G, K)
        Displacements per cell and Δt.
    mean : ndarray, shape (G, K, 3)
        ⟨ΔX⟩ per component, m (NaN where empty).
    var : ndarray, shape (G, K, 3)
        Sample variance of ΔX about the cell mean, m² (NaN where count < 2).
    se_mean : ndarray, shape (G, K, 3)
        Standard error of mean, m.
    se_var : ndarray, shape (G, K, 3)
        Standard error of var, m².
    """

    dt: np.ndarray
    count: np.ndarray
    mean: np.ndarray
    var: np.ndarray
    se_mean: np.ndarray
    se_var: np.ndarray


def eulerian_moments(
    positions: Sequence[np.ndarray],
    displacements: Sequence[np.ndarray],
    dt: np.ndarray,
    grid: Grid,
) -> EulerianMoments:
    """Bin displacements by position, separately for each Δt.

    Parameters
    ----------
    positions : sequence of K ndarrays, shapes (N_k, 3)
        Measured positions X(t), m, of all particles (all snapshots) at Δt_k. For
        time-resolved data pass the same positions for every Δt; for double-frame data
        each run's own.
    displacements : sequence of K ndarrays, shapes (N_k, 3)
        ΔX = X(t + Δt_k) − X(t), m.
    dt : ndarray, shape (K,)
        Time separations, s.
    grid : Grid
        Cells; points outside are ignored.

    Returns
    -------
    EulerianMoments
    """
    dt = np.asarray(dt, dtype=np.float64)
    select_dt(None, dt)  # validates dt
    k = dt.size
    if len(positions) != k or len(displacements) != k:
        raise ValueError(
            f"need one positions and one displacements array per Δt ({k}), got "
            f"{len(positions)} and {len(displacements)}"
        )
    g = grid.n_cells
    count = np.zeros((g, k), dtype=np.int64)
    mean, var, se_mean, se_var = (np.full((g, k, 3), np.nan) for _ in range(4))
    for kk in range(k):
        x = np.asarray(positions[kk], dtype=np.float64)
        d = np.asarray(displacements[kk], dtype=np.float64)
        if d.ndim != 2 or d.shape[1] != 3 or x.shape != d.shape:
            raise ValueError(
                f"Δt #{kk}: positions {x.shape} and displacements {d.shape} must both be (N, 3)"
            )
        if x.shape[0] == 0:
            raise ValueError(f"Δt #{kk}: no displacements")
        if not np.all(np.isfinite(d)):
            raise ValueError(f"Δt #{kk}: displacements contain NaN or infinite values")
        cell = grid.index(x)
        keep = cell >= 0
        cell, d = cell[keep], d[keep]
        n = np.bincount(cell, minlength=g)
        count[:, kk] = n
        nf = n.astype(np.float64)[:, None]
        with np.errstate(invalid="ignore", divide="ignore"):
            m1 = np.stack([np.bincount(cell, d[:, c], minlength=g) for c in range(3)], 1) / nf
            dev = d - m1[cell]
            s2 = np.stack([np.bincount(cell, dev[:, c] ** 2, minlength=g) for c in range(3)], 1)
            s4 = np.stack([np.bincount(cell, dev[:, c] ** 4, minlength=g) for c in range(3)], 1)
            v = s2 / (nf - 1)
            mu4, mu2 = s4 / nf, s2 / nf
            var_v = (mu4 - (nf - 3) / (nf - 1) * mu2**2) / nf
        has1, has2 = n >= 1, n >= 2
        mean[has1, kk] = m1[has1]
        var[has2, kk] = v[has2]
        se_mean[has2, kk] = np.sqrt(v[has2] / nf[has2])
        se_var[has2, kk] = np.sqrt(np.maximum(var_v[has2], 0.0))
    return EulerianMoments(dt=dt, count=count, mean=mean, var=var, se_mean=se_mean, se_var=se_var)


@dataclass(frozen=True)
class EulerianFit:
    """Per-cell multi-Δt fits of the mean and the variance of displacements.

    Attributes
    ----------
    valid : ndarray of bool, shape (G,)
        Cells fitted (enough displacements at every fitted Δt); others are NaN.
    mean_velocity : ndarray, shape (G, 3)
        Slope α of ⟨ΔX⟩ = αΔt + β0, m/s.
    se_mean_velocity : ndarray, shape (G, 3)
        m/s.
    offset : ndarray, shape (G, 3)
        β0, m: zero within se_offset for zero-mean noise.
    se_offset : ndarray, shape (G, 3)
        m.
    mean_chi2_dof : ndarray, shape (G, 3)
        χ²/(n − 2) of the mean fit.
    variance : ndarray, shape (G, 3)
        Slope of Var ΔX = α Δt² + β: velocity variance, m²/s².
    se_variance : ndarray, shape (G, 3)
        m²/s².
    noise : ndarray, shape (G, 3)
        β = 2σ_b² for white noise, m².
    se_noise : ndarray, shape (G, 3)
        m².
    var_chi2_dof : ndarray, shape (G, 3)
        χ²/(n − 2) of the variance fit.
    """

    valid: np.ndarray
    mean_velocity: np.ndarray
    se_mean_velocity: np.ndarray
    offset: np.ndarray
    se_offset: np.ndarray
    mean_chi2_dof: np.ndarray
    variance: np.ndarray
    se_variance: np.ndarray
    noise: np.ndarray
    se_noise: np.ndarray
    var_chi2_dof: np.ndarray


def eulerian_fit(
    moments: EulerianMoments, *, use: np.ndarray | None = None, min_count: int = 10
) -> EulerianFit:
    """Fit ⟨ΔX⟩ = αΔt + β0 and Var ΔX = αΔt² + β in every cell and component.

    Parameters
    ----------
    moments : EulerianMoments
        Binned moments.
    use : ndarray of bool, shape (K,), or of int, optional
        Δt subset to fit.
    min_count : int
        Cells need at least this many displacements (≥ 3) at every fitted Δt.

    Returns
    -------
    EulerianFit
    """
    dt = moments.dt
    idx = select_dt(use, dt)
    if not isinstance(min_count, int | np.integer) or min_count < 3:
        raise ValueError(f"min_count must be an integer >= 3, got {min_count!r}")
    g = moments.count.shape[0]
    ok = np.all(moments.count[:, idx] >= min_count, axis=1)
    ok &= np.all(moments.se_mean[:, idx] > 0, axis=(1, 2))
    ok &= np.all(moments.se_var[:, idx] > 0, axis=(1, 2))
    out = {name: np.full((g, 3), np.nan) for name in EulerianFit.__dataclass_fields__}
    out["valid"] = ok
    if np.any(ok):

        def rows(a):  # (G, K, 3) → (G_ok·3, n)
            return np.moveaxis(a[ok][:, idx], 1, 2).reshape(-1, idx.size)

        mfit = wls_line(dt[idx], rows(moments.mean), rows(moments.se_mean))
        vfit = fit_multi_dt(dt[idx], rows(moments.var), sigma=rows(moments.se_var))
        for name, arr in (
            ("mean_velocity", mfit.c1),
            ("se_mean_velocity", mfit.se_c1),
            ("offset", mfit.c2),
            ("se_offset", mfit.se_c2),
            ("mean_chi2_dof", mfit.chi2_dof),
            ("variance", vfit.c1),
            ("se_variance", vfit.se_c1),
            ("noise", vfit.c2),
            ("se_noise", vfit.se_c2),
            ("var_chi2_dof", vfit.chi2_dof),
        ):
            out[name][ok] = arr.reshape(-1, 3)
    logger.info("Eulerian fit: %d of %d cells on %d Δt", int(ok.sum()), g, idx.size)
    return EulerianFit(**out)


@dataclass(frozen=True)
class UPrime:
    """rms velocity of one component from the spatially averaged variance.

    Attributes
    ----------
    value : float
        u′ = sqrt(mean over cells and the chosen components of the variance), m/s.
    se : float
        Standard error from the per-cell errors taken as independent, m/s (a lower
        bound: particles of one snapshot see the same eddies).
    per_component : ndarray, shape (3,)
        sqrt of the spatially averaged variance of each component, m/s (NaN where the
        average is negative).
    n_cells : int
        Cells averaged.
    replicates : ndarray, shape (R,), or None
        u′ of each bootstrap replicate over snapshots (:func:`u_prime_replicates`), m/s;
        their spread is the error that knows the snapshots are the independent units.
    """

    value: float
    se: float
    per_component: np.ndarray
    n_cells: int
    replicates: np.ndarray | None = None

    @property
    def se_snapshots(self) -> float:
        """Standard error from the bootstrap over snapshots, m/s (NaN without it)."""
        if self.replicates is None or not np.isfinite(self.replicates).all():
            return float("nan")
        return float(np.std(self.replicates, ddof=1))


def u_prime(fit: EulerianFit, *, components: Sequence[int] = (0, 1, 2)) -> UPrime:
    """u′ from the fitted (noise-free) velocity variance, averaged over valid cells.

    Parameters
    ----------
    fit : EulerianFit
        Per-cell fits.
    components : sequence of int
        Components averaged into u′ (default all three: u′² = ⟨u_i u_i⟩/3).
    """
    comps = np.asarray(components)
    if comps.ndim != 1 or comps.size == 0 or np.any((comps < 0) | (comps > 2)):
        raise ValueError(f"components must be a non-empty list from 0, 1, 2, got {components}")
    ok = fit.valid
    n = int(np.count_nonzero(ok))
    if n == 0:
        raise ValueError("no valid cell to average the variance over")
    var = fit.variance[ok]
    se = fit.se_variance[ok]
    per = var.mean(axis=0)
    with np.errstate(invalid="ignore"):
        per_component = np.sqrt(np.where(per >= 0, per, np.nan))
    v = float(var[:, comps].mean())
    se_v = float(np.sqrt(np.sum(se[:, comps] ** 2)) / se[:, comps].size)
    value = float(np.sqrt(v)) if v > 0 else float("nan")
    return UPrime(value=value, se=se_v / (2 * value), per_component=per_component, n_cells=n)


@dataclass(frozen=True)
class CellSums:
    """Sums of the displacements of each snapshot per cell at one Δt.

    Attributes
    ----------
    count : ndarray of int64, shape (M, G)
        Displacements of snapshot m in cell g.
    first : ndarray, shape (M, G, 3)
        Σ ΔX per component, m.
    second : ndarray, shape (M, G, 3)
        Σ ΔX² per component, m².
    """

    count: np.ndarray
    first: np.ndarray
    second: np.ndarray


def cell_sums(snapshots: Sequence[tuple[np.ndarray, np.ndarray]], grid: Grid) -> CellSums:
    """The per-snapshot sums of the displacements in each cell of the grid.

    Parameters
    ----------
    snapshots : sequence of M (ndarray (N_m, 3), ndarray (N_m, 3))
        Per snapshot, the positions X(t) and displacements ΔX of its links, m.
    grid : Grid
        The cells; points outside the grid are left out.

    Returns
    -------
    CellSums
        Counts, shape (M, G), and the sums of ΔX and ΔX², shape (M, G, 3), in m and m².
    """
    g = grid.n_cells
    m = len(snapshots)
    count = np.zeros((m, g), dtype=np.int64)
    first, second = np.zeros((m, g, 3)), np.zeros((m, g, 3))
    for i, (x, d) in enumerate(snapshots):
        if len(x) == 0:
            continue
        cell = grid.index(np.asarray(x, dtype=np.float64))
        keep = cell >= 0
        cell, d = cell[keep], np.asarray(d, dtype=np.float64)[keep]
        count[i] = np.bincount(cell, minlength=g)
        for c in range(3):
            first[i, :, c] = np.bincount(cell, d[:, c], minlength=g)
            second[i, :, c] = np.bincount(cell, d[:, c] ** 2, minlength=g)
    return CellSums(count, first, second)


def u_prime_replicates(
    sums: Sequence[CellSums],
    weights: Sequence[np.ndarray],
    moments: EulerianMoments,
    fit: EulerianFit,
    *,
    components: Sequence[int] = (0, 1, 2),
) -> np.ndarray:
    """u′ of each bootstrap replicate over snapshots, fitted as :func:`u_prime` fits it.

    Each replicate weighs every snapshot's cell sums by how often it was drawn, forms the
    cell variances about the cell means (n − 1 in the denominator, as
    :func:`eulerian_moments`), and fits their slope in Δt² with the weights of the
    point estimate (1/se_var² of ``moments``), over the cells ``fit`` found valid.

    Parameters
    ----------
    sums : sequence of K CellSums
        Per Δt, the sums of its snapshots.
    weights : sequence of K ndarray, shape (R, M_k)
        How often each of those snapshots is drawn in each replicate.
    moments : EulerianMoments
        The point estimate's moments (their se_var weigh the fit).
    fit : EulerianFit
        The point estimate's fit (its valid cells).
    components : sequence of int
        As :func:`u_prime`.

    Returns
    -------
    ndarray, shape (R,)
        m/s; NaN in a replicate whose mean variance is not positive.
    """
    if len(sums) != len(weights) or len(sums) != moments.dt.size:
        raise ValueError(
            f"need cell sums and weights per Δt ({moments.dt.size}), got {len(sums)} and "
            f"{len(weights)}"
        )
    ok = fit.valid
    comps = np.asarray(components)
    variances = []
    for s, w in zip(sums, weights, strict=True):
        w = np.asarray(w, dtype=np.float64)
        n = np.einsum("rm,mg->rg", w, s.count.astype(np.float64))[:, ok, None]
        s1 = np.einsum("rm,mgc->rgc", w, s.first)[:, ok][..., comps]
        s2 = np.einsum("rm,mgc->rgc", w, s.second)[:, ok][..., comps]
        with np.errstate(invalid="ignore", divide="ignore"):
            variances.append((s2 - s1**2 / n) / (n - 1))
    var = np.stack(variances, axis=-1)  # (R, G_ok, C, K)
    x = moments.dt**2
    with np.errstate(divide="ignore"):
        w_fit = 1.0 / np.moveaxis(moments.se_var[ok][..., comps], 1, 2) ** 2  # (G_ok, C, K)
    xbar = np.sum(w_fit * x, axis=-1, keepdims=True) / np.sum(w_fit, axis=-1, keepdims=True)
    a1 = w_fit * (x - xbar)
    a1 /= np.sum(a1 * (x - xbar), axis=-1, keepdims=True)
    slope = np.einsum("rgck,gck->r", var, a1) / a1[..., 0].size
    with np.errstate(invalid="ignore"):
        return np.sqrt(np.where(slope > 0, slope, np.nan))
