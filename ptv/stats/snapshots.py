"""Per-snapshot pair sums, stacked so that snapshots can be resampled without re-binning.

Snapshots (independent realisations of the flow) are the unit of independence of PTV
data: pairs of one snapshot share particles and see the same velocity field, so their
q values are correlated and Var(q)/N_pairs underestimates the error of ⟨q⟩. The
bootstrap over snapshots (docs/statistics.md §3.3) gets it right. `SnapshotSums` holds the sums
of every snapshot, bin and Δt column; a bootstrap replicate is a weighted sum over
snapshots (weights = how often each snapshot is drawn), computed as one matrix product.

Two acquisition modes map onto one layout, with a *stratum* per snapshot:

- time-resolved (skip-frame): every snapshot has all K Δt columns, from the same
  positions at t; one stratum, so a replicate keeps the columns of a snapshot together
  and the bootstrap sees the correlation between Δt;
- double-frame: one run per Δt; a snapshot of run k only fills column k and has
  stratum k; snapshots are resampled within their run, so each replicate has as many
  snapshots per Δt as the data.
"""

import logging
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ptv.stats.pairs import PairSums
from ptv.stats.resampling import SnapshotCorrelation, autocorrelation_time, block_weights

__all__ = ["SnapshotSums", "cluster_mean"]

logger = logging.getLogger(__name__)


def _per_column(values, b: int, k: int) -> np.ndarray:
    """Per-bin values (B,) repeated for the K columns, or per-column values (B, K)."""
    values = np.asarray(values)
    return values if values.ndim == 2 else np.broadcast_to(values[:, None], (b, k))


@dataclass(frozen=True)
class SnapshotSums:
    """Pair sums per snapshot, separation bin and Δt column.

    Attributes
    ----------
    count : ndarray of int64, shape (M, B, K)
        Pairs of snapshot m in bin b contributing to column k.
    sum_q : ndarray, shape (M, B, K)
        Σ q, q = [(d_j − d_i)·e]² (m² for displacements).
    sum_q2 : ndarray, shape (M, B, K)
        Σ q² (m⁴).
    sum_r : ndarray, shape (M, B, K)
        Σ |r| over the same pairs, m.
    stratum : ndarray of int64, shape (M,)
        Resampling group of each snapshot (0 for time-resolved data; the run, i.e. the
        Δt column, for double-frame data).
    """

    count: np.ndarray
    sum_q: np.ndarray
    sum_q2: np.ndarray
    sum_r: np.ndarray
    stratum: np.ndarray

    def __post_init__(self) -> None:
        shape = np.shape(self.count)
        if len(shape) != 3 or min(shape) == 0:
            raise ValueError(f"count must have a non-empty shape (M, B, K), got {shape}")
        for name in ("sum_q", "sum_q2", "sum_r"):
            if np.shape(getattr(self, name)) != shape:
                raise ValueError(
                    f"{name} has shape {np.shape(getattr(self, name))}, expected {shape}"
                )
            if not np.all(np.isfinite(getattr(self, name))):
                raise ValueError(f"{name} contains NaN or infinite values")
        if np.shape(self.stratum) != (shape[0],):
            raise ValueError(f"stratum must have shape ({shape[0]},), got {np.shape(self.stratum)}")
        if np.any(np.asarray(self.count) < 0):
            raise ValueError("count has negative entries")

    # ------------------------------------------------------------------ builders

    @classmethod
    def from_time_resolved(cls, sums: Sequence[PairSums]) -> "SnapshotSums":
        """Stack per-snapshot PairSums that each hold all K Δt columns (one stratum).

        Parameters
        ----------
        sums : sequence of PairSums, length M ≥ 1
            One per snapshot, each with sum_q (B, K) and count (B,), or (B, K) when
            the bins depend on the column (chord-midpoint binning).
        """
        if len(sums) == 0:
            raise ValueError("no snapshots given")
        b, k = np.shape(sums[0].sum_q)
        for m, s in enumerate(sums):
            if np.shape(s.sum_q) != (b, k):
                raise ValueError(
                    f"snapshot {m} has sum_q of shape {np.shape(s.sum_q)}, expected {(b, k)}"
                )
        count = np.stack([_per_column(s.count, b, k) for s in sums])
        sum_r = np.stack([_per_column(s.sum_r, b, k) for s in sums])
        return cls(
            count=count.astype(np.int64),
            sum_q=np.stack([np.asarray(s.sum_q, dtype=np.float64) for s in sums]),
            sum_q2=np.stack([np.asarray(s.sum_q2, dtype=np.float64) for s in sums]),
            sum_r=sum_r.astype(np.float64),
            stratum=np.zeros(len(sums), dtype=np.int64),
        )

    @classmethod
    def from_double_frame(cls, runs: Sequence[Sequence[PairSums]]) -> "SnapshotSums":
        """Stack the snapshots of K runs, run k giving column k (one stratum per run).

        Parameters
        ----------
        runs : sequence of length K ≥ 1 of sequences of PairSums
            runs[k] holds the per-snapshot sums of the run at Δt_k, each with one column
            (sum_q of shape (B, 1) or (B,)). Runs may have different numbers of snapshots.
        """
        k = len(runs)
        if k == 0:
            raise ValueError("no runs given")
        b = None
        rows = []
        for kk, run in enumerate(runs):
            if len(run) == 0:
                raise ValueError(f"run {kk} has no snapshots")
            for m, s in enumerate(run):
                sq = np.asarray(s.sum_q, dtype=np.float64)
                sq = sq[:, None] if sq.ndim == 1 else sq
                if sq.ndim != 2 or sq.shape[1] != 1:
                    raise ValueError(
                        f"run {kk}, snapshot {m}: double-frame sums must have one column, "
                        f"got sum_q of shape {np.shape(s.sum_q)}"
                    )
                b = sq.shape[0] if b is None else b
                if sq.shape[0] != b:
                    raise ValueError(f"run {kk}, snapshot {m} has {sq.shape[0]} bins, expected {b}")
                rows.append((kk, s))
        m_total = len(rows)
        count = np.zeros((m_total, b, k), dtype=np.int64)
        sum_q = np.zeros((m_total, b, k))
        sum_q2 = np.zeros((m_total, b, k))
        sum_r = np.zeros((m_total, b, k))
        stratum = np.empty(m_total, dtype=np.int64)
        for m, (kk, s) in enumerate(rows):
            count[m, :, kk] = np.reshape(s.count, b)
            sum_q[m, :, kk] = np.reshape(s.sum_q, b)
            sum_q2[m, :, kk] = np.reshape(s.sum_q2, b)
            sum_r[m, :, kk] = np.reshape(s.sum_r, b)
            stratum[m] = kk
        return cls(count=count, sum_q=sum_q, sum_q2=sum_q2, sum_r=sum_r, stratum=stratum)

    # ------------------------------------------------------------------ pooled

    @property
    def n_snapshots(self) -> int:
        """M."""
        return self.count.shape[0]

    @property
    def n_columns(self) -> int:
        """K."""
        return self.count.shape[2]

    @property
    def total_count(self) -> np.ndarray:
        """Pairs per bin and column over all snapshots, shape (B, K)."""
        return self.count.sum(axis=0)

    @property
    def mean(self) -> np.ndarray:
        """⟨q⟩ over all pairs of all snapshots, shape (B, K); NaN where empty."""
        with np.errstate(invalid="ignore", divide="ignore"):
            return self.sum_q.sum(axis=0) / self.total_count

    @property
    def naive_sem(self) -> np.ndarray:
        """sqrt(Var(q)/N_pairs), shape (B, K): the standard error of ⟨q⟩ if all pairs
        were independent, which they are not (an underestimate); NaN where N < 2."""
        n = self.total_count.astype(np.float64)
        with np.errstate(invalid="ignore", divide="ignore"):
            m1 = self.sum_q.sum(axis=0) / n
            m2 = self.sum_q2.sum(axis=0) / n
            var = np.maximum(m2 - m1 * m1, 0.0) * n / (n - 1)
            out = np.sqrt(var / n)
        return np.where(n >= 2, out, np.nan)

    @property
    def mean_separation(self) -> np.ndarray:
        """⟨|r|⟩ per bin over all pairs and columns, shape (B,), m; NaN where empty."""
        with np.errstate(invalid="ignore", divide="ignore"):
            return self.sum_r.sum(axis=(0, 2)) / self.count.sum(axis=(0, 2))

    # ------------------------------------------------------------------ bootstrap

    def bootstrap_weights(
        self,
        n_boot: int,
        *,
        rng: np.random.Generator | int | None = None,
        block: int = 1,
    ) -> np.ndarray:
        """How often each snapshot is drawn in each of n_boot replicates, shape (R, M).

        Snapshots are drawn with replacement within their stratum, as many as the
        stratum holds: one at a time (``block`` 1, independent snapshots), or in blocks
        of ``block`` consecutive snapshots of the stratum where successive snapshots are
        correlated (:func:`ptv.stats.resampling.block_weights`), at most a quarter of the
        stratum (one at a time below 8 snapshots).

        Parameters
        ----------
        n_boot : int
            Number R of replicates, ≥ 2.
        rng : numpy.random.Generator, int or None
            Source of randomness.
        block : int
            Consecutive snapshots per block, ≥ 1.

        Returns
        -------
        ndarray, shape (R, M)
            Draws of each snapshot per replicate; each stratum's row sums to its size.
        """
        if not isinstance(n_boot, int | np.integer) or n_boot < 2:
            raise ValueError(f"n_boot must be an integer >= 2, got {n_boot!r}")
        if not isinstance(block, int | np.integer) or block < 1:
            raise ValueError(f"block must be an integer >= 1, got {block!r}")
        gen = np.random.default_rng(rng)
        w = np.zeros((n_boot, self.n_snapshots))
        for s in np.unique(self.stratum):
            members = np.flatnonzero(self.stratum == s)
            if members.size < 2:
                raise ValueError(
                    f"stratum {s} has {members.size} snapshot: the bootstrap over "
                    "snapshots needs at least 2 per stratum"
                )
            # A block of more than a quarter of the stratum would leave too few blocks
            # to vary (a block of the whole stratum draws every replicate alike).
            length = min(block, max(1, members.size // 4))
            if length > 1:
                w[:, members] = block_weights(n_boot, members.size, length, gen)
                continue
            p = np.full(members.size, 1.0 / members.size)
            w[:, members] = gen.multinomial(members.size, p, size=n_boot)
        return w

    def bootstrap_means(
        self,
        n_boot: int,
        *,
        rng: np.random.Generator | int | None = None,
        chunk: int = 256,
    ) -> np.ndarray:
        """⟨q⟩ per bin and column in n_boot replicates resampled over snapshots.

        Parameters
        ----------
        n_boot : int
            Number R of replicates, ≥ 2.
        rng : numpy.random.Generator, int or None
            Source of randomness.
        chunk : int
            Replicates per matrix product (bounds the memory to chunk × M weights).

        Returns
        -------
        ndarray, shape (R, B, K)
            Replicate means; NaN where a replicate has no pair in a bin and column.
        """
        return self.weighted_means(self.bootstrap_weights(n_boot, rng=rng), chunk=chunk)

    def weighted_means(self, weights: np.ndarray, *, chunk: int = 256) -> np.ndarray:
        """⟨q⟩ per bin and column of each row of snapshot weights (a bootstrap replicate).

        Parameters
        ----------
        weights : ndarray, shape (R, M)
            How often each snapshot counts in each replicate
            (:meth:`bootstrap_weights`).
        chunk : int
            Replicates per matrix product (bounds the memory to chunk × M weights).

        Returns
        -------
        ndarray, shape (R, B, K)
            Replicate means; NaN where a replicate has no pair in a bin and column.
        """
        w = np.asarray(weights, dtype=np.float64)
        m, b, k = self.count.shape
        if w.ndim != 2 or w.shape[1] != m:
            raise ValueError(f"weights must have shape (R, {m}), got {w.shape}")
        cnt = self.count.reshape(m, b * k).astype(np.float64)
        sq = self.sum_q.reshape(m, b * k)
        out = np.empty((len(w), b * k))
        for start in range(0, len(w), max(int(chunk), 1)):
            ws = w[start : start + chunk]
            with np.errstate(invalid="ignore", divide="ignore"):
                out[start : start + chunk] = (ws @ sq) / (ws @ cnt)
        logger.debug("bootstrap over %d snapshots: %d replicates of %d×%d", m, len(w), b, k)
        return out.reshape(len(w), b, k)

    def correlation(self) -> SnapshotCorrelation:
        """How correlated successive snapshots of each stratum are.

        Returns
        -------
        SnapshotCorrelation
            The lag-one autocorrelation of the snapshots' ⟨q⟩ in every bin and column
            that each snapshot fills, pooled over them and over the strata
            (:func:`ptv.stats.resampling.autocorrelation_time`).
        """
        with np.errstate(invalid="ignore", divide="ignore"):
            means = self.sum_q / self.count
        found = []
        for s in np.unique(self.stratum):
            members = np.flatnonzero(self.stratum == s)
            series = means[members].reshape(members.size, -1)
            found.append(autocorrelation_time(series))
        usable = [c for c in found if np.isfinite(c.rho1)]
        if not usable:
            return SnapshotCorrelation(np.nan, self.n_snapshots, 0)
        rho1 = np.average([c.rho1 for c in usable], weights=[c.snapshots for c in usable])
        return SnapshotCorrelation(
            float(rho1),
            int(max(c.snapshots for c in usable)),
            int(sum(c.series for c in usable)),
        )


def cluster_mean(
    weights: np.ndarray, values: np.ndarray, *, full: bool = False
) -> tuple[np.ndarray, np.ndarray]:
    """Weighted mean over snapshots (axis 0) and its cluster-robust error.

    Snapshots are the independent units: with w_m the weight (e.g. particles or pairs)
    and x_m the mean of snapshot m, the mean is x̄ = Σ w_m x_m / Σ w_m and its
    covariance M/(M − 1) Σ w_m²(x_m − x̄)(x_m − x̄)ᵀ / (Σ w_m)², M the snapshots with
    weight.

    Parameters
    ----------
    weights : ndarray, shape (M,) or (M, *S)
        Weights ≥ 0 (broadcast against ``values``).
    values : ndarray, shape (M, *S)
        Snapshot means (NaN where the weight is 0).
    full : bool
        Return the covariance of the flattened mean instead of its standard error.

    Returns
    -------
    (ndarray (*S), ndarray (*S) or (N, N))
        The mean and its standard error, or its covariance with N = prod(S); NaN where
        no snapshot has weight, and the error too where only one has.
    """
    values = np.asarray(values, dtype=np.float64)
    w = np.asarray(weights, dtype=np.float64)
    w = np.broadcast_to(w.reshape(w.shape + (1,) * (values.ndim - w.ndim)), values.shape)
    total = w.sum(axis=0)
    x = np.where(w > 0, values, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.sum(w * x, axis=0) / total
        dev = np.where(w > 0, w * (x - mean), 0.0)
        m = (w > 0).sum(axis=0)
        factor = np.where(m > 1, m / np.maximum(m - 1, 1), np.nan)
        if not full:
            return mean, np.sqrt(factor * np.sum(dev**2, axis=0)) / total
        d = dev.reshape(len(values), -1)
        scale = np.sqrt(factor.ravel()) / total.ravel()
        return mean, (d.T @ d) * np.outer(scale, scale)
