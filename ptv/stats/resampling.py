"""How correlated successive snapshots are, and bootstrap weights that respect it.

The bootstrap over snapshots (:class:`ptv.stats.snapshots.SnapshotSums`) takes snapshots
as independent. Snapshots of independent flow realizations are; frames of one recording
cut into pairs, or fields of a simulation sampled less than a few integral times apart,
are not, and resampling them one by one understates every error (docs/statistics.md §3.4).

- :func:`autocorrelation_time`: the integrated autocorrelation time τ of snapshot
  series (in snapshots), from their lag-one autocorrelation ρ₁ pooled over several series
  of the same snapshots, as for a correlation that decays exponentially:
  τ = (1 + ρ₁)/(1 − ρ₁). M/τ is the effective number of independent snapshots. A few
  tens of snapshots do not resolve the correlation at longer lags (the windowed sum of
  Madras & Sokal scatters by ±0.7 snapshots at M = 40), and ρ₁ pooled over the bins of
  a structure function scatters by ±0.06 (the standard deviation over 55 KS runs of 40
  independent snapshots).
- :func:`block_length`: the block of consecutive snapshots a resample draws together,
  τ rounded up where ρ₁ stands out of the scatter of independent snapshots (1 below).
- :func:`block_weights`: how often each snapshot is drawn in each replicate of a moving
  block bootstrap (Künsch 1989), circular so that every snapshot is drawn as often on
  average.
"""

import logging
from dataclasses import dataclass

import numpy as np

__all__ = [
    "RESOLVED_RHO1",
    "SnapshotBootstrap",
    "SnapshotCorrelation",
    "autocorrelation_time",
    "block_length",
    "block_weights",
]

log = logging.getLogger(__name__)

#: The lag-one autocorrelation from which successive snapshots are drawn in blocks:
#: 1.7 times the scatter of the pooled estimate over independent snapshots (±0.06 at
#: M = 40, measured on 55 KS runs), so that independent snapshots keep blocks of one.
RESOLVED_RHO1 = 0.1


@dataclass(frozen=True)
class SnapshotCorrelation:
    """How correlated successive snapshots are.

    Attributes
    ----------
    rho1 : float
        Lag-one autocorrelation, the mean over the series (NaN when there are fewer than
        4 snapshots or no usable series).
    snapshots : int
        M.
    series : int
        The series pooled.
    """

    rho1: float
    snapshots: int
    series: int

    @property
    def tau(self) -> float:
        """Integrated autocorrelation time (1 + ρ₁)/(1 − ρ₁), at least 1, in snapshots
        (1 when ρ₁ is not known)."""
        if not np.isfinite(self.rho1):
            return 1.0
        rho = min(self.rho1, 0.95)
        return max(1.0, (1.0 + rho) / (1.0 - rho))

    @property
    def effective_snapshots(self) -> float:
        """M/τ: the independent snapshots the sample is worth."""
        return self.snapshots / self.tau

    def as_dict(self) -> dict:
        """JSON-able form."""
        return {
            "lag_one_autocorrelation": None if not np.isfinite(self.rho1) else float(self.rho1),
            "tau_snapshots": self.tau,
            "snapshots": self.snapshots,
            "series": self.series,
            "effective_snapshots": self.effective_snapshots,
        }


def autocorrelation_time(series: np.ndarray) -> SnapshotCorrelation:
    """How correlated successive snapshots of the series are (module docstring).

    Parameters
    ----------
    series : ndarray, shape (M,) or (M, S)
        S series of one value per snapshot, in the order the snapshots were taken.
        Columns with a non-finite value or no variance are left out.

    Returns
    -------
    SnapshotCorrelation
    """
    x = np.asarray(series, dtype=np.float64)
    if x.ndim == 1:
        x = x[:, None]
    if x.ndim != 2:
        raise ValueError(f"series must have shape (M,) or (M, S), got {x.shape}")
    m = x.shape[0]
    x = x[:, np.all(np.isfinite(x), axis=0)]
    if m >= 2:
        x = x[:, np.std(x, axis=0) > 0]
    s = x.shape[1]
    if m < 4 or s == 0:
        return SnapshotCorrelation(np.nan, m, s)
    centred = x - x.mean(axis=0)
    rho1 = np.sum(centred[:-1] * centred[1:], axis=0) / np.sum(centred**2, axis=0)
    return SnapshotCorrelation(float(np.mean(rho1)), m, s)


def block_length(correlation: SnapshotCorrelation) -> int:
    """Snapshots per block of the bootstrap.

    Parameters
    ----------
    correlation : SnapshotCorrelation
        The lag-one autocorrelation of the snapshots and their number M.

    Returns
    -------
    int
        1 (independent draws) where ρ₁ is below :data:`RESOLVED_RHO1` or not finite;
        else τ rounded up, at least 2, at most M/4. Fewer than 8 correlated snapshots
        leave no room for two blocks of 2 per quarter: 1, with a warning that the
        errors will read low.
    """
    if not np.isfinite(correlation.rho1) or correlation.rho1 < RESOLVED_RHO1:
        return 1
    cap = max(1, correlation.snapshots // 4)
    if cap == 1:
        log.warning(
            "successive snapshots correlate (lag-one %.2f) but %d are too few to draw "
            "in blocks: the bootstrap errors read low by about sqrt(%.2g)",
            correlation.rho1,
            correlation.snapshots,
            correlation.tau,
        )
    return int(min(max(2, int(np.ceil(correlation.tau))), cap))


def block_weights(n_boot: int, members: int, block: int, gen: np.random.Generator) -> np.ndarray:
    """How often each of ``members`` ordered snapshots is drawn, per replicate, by a
    circular moving block bootstrap: ⌈members/block⌉ blocks of ``block`` consecutive
    snapshots (wrapping round the end) start at uniformly drawn snapshots, and the last
    block is cut so that each replicate holds ``members`` draws.

    Parameters
    ----------
    n_boot : int
        Replicates R.
    members : int
        Snapshots of the stratum, in time order.
    block : int
        Snapshots per block, 1 ≤ block ≤ members.
    gen : numpy.random.Generator
        Randomness.

    Returns
    -------
    ndarray, shape (R, members)
        Counts summing to ``members`` in every row.
    """
    if not 1 <= block <= members:
        raise ValueError(f"block must be in 1 … {members}, got {block}")
    n_blocks = -(-members // block)
    starts = gen.integers(0, members, size=(n_boot, n_blocks))
    drawn = (starts[:, :, None] + np.arange(block)).reshape(n_boot, -1)[:, :members] % members
    w = np.zeros((n_boot, members))
    np.add.at(w, (np.arange(n_boot)[:, None], drawn), 1.0)
    return w


@dataclass(frozen=True, eq=False)
class SnapshotBootstrap:
    """The bootstrap over snapshots a run's statistics share, drawn once.

    Every estimate of the run (S2 and its Δt subsets, the plateau ε, u′) is refitted on
    the same replicates, so that its replicates pair with another measurement's of the
    same snapshots drawn with the same seed (the exact trajectories against the PTV):
    the spread of their difference is the paired error, free of the sampling both share.

    Attributes
    ----------
    weights : ndarray, shape (R, M)
        How often each snapshot is drawn in each replicate
        (:meth:`ptv.stats.snapshots.SnapshotSums.bootstrap_weights`).
    block : int
        Snapshots per block of consecutive snapshots drawn together (1: one at a time).
    correlation : SnapshotCorrelation
        How correlated successive snapshots are, which set ``block``.
    snapshot_ids : tuple of ndarray of int
        Per stratum (one for a shared first frame, one per Δt otherwise), the snapshot
        numbers of the weights' columns, in order.
    seed : int
        The seed the weights were drawn with.
    """

    weights: np.ndarray
    block: int
    correlation: SnapshotCorrelation
    snapshot_ids: tuple[np.ndarray, ...]
    seed: int

    @property
    def replicates(self) -> int:
        """R."""
        return len(self.weights)

    def pairs_with(self, snapshot_ids) -> bool:
        """Whether another measurement whose strata hold ``snapshot_ids`` (sequence of
        sequences of int) draws the same snapshots in the same replicates, given the same
        seed, replicate count and block: the same snapshots in every stratum."""
        theirs = [np.asarray(ids, dtype=np.int64) for ids in snapshot_ids]
        return len(theirs) == len(self.snapshot_ids) and all(
            np.array_equal(a, b) for a, b in zip(self.snapshot_ids, theirs, strict=True)
        )
