"""Longitudinal second moments binned over all particle pairs of a snapshot.

For every pair (i, j) of particles of one snapshot with separation r = x_j − x_i in a
logarithmic bin, and for every column k of an increment array d (displacements at the
K values of Δt, or velocities), accumulate q = [(d_jk − d_ik)·e]², e = r/|r|. The mean
of q per bin is the longitudinal second-order structure function of d.

Displacements may instead be binned by the chord midpoint (``binning="midpoint"``,
docs/statistics.md §4): for column k the separation is r̄_k = r + (d_jk − d_ik)/2, the
mean of the separations at t and t + Δt_k, and e = r̄_k/|r̄_k|. The bin of a pair then
depends on Δt, so the counts and separations are kept per column.
"""

from dataclasses import dataclass
from math import log, sqrt

import numpy as np
from numba import njit, prange

from ptv._threads import over_threads
from ptv.bins import BINNINGS, LogBins


@dataclass(frozen=True)
class PairSums:
    """Per-bin sums over pairs, to be added across snapshots.

    Attributes
    ----------
    count : ndarray of int64, shape (B,) or (B, K)
        Pairs per bin (per bin and column when the bin depends on the column: chord
        midpoint binning).
    sum_q : ndarray, shape (B, K)
        Σ q per bin and increment column, (units of d)².
    sum_q2 : ndarray, shape (B, K)
        Σ q² per bin and column, (units of d)⁴.
    sum_r : ndarray, shape (B,) or (B, K)
        Σ |r| per bin (and column, as ``count``), m, for the mean separation of a bin.
    """

    count: np.ndarray
    sum_q: np.ndarray
    sum_q2: np.ndarray
    sum_r: np.ndarray

    def __add__(self, other: "PairSums") -> "PairSums":
        return PairSums(
            self.count + other.count,
            self.sum_q + other.sum_q,
            self.sum_q2 + other.sum_q2,
            self.sum_r + other.sum_r,
        )

    @property
    def per_column(self) -> bool:
        """Whether the counts are per bin and column (chord-midpoint binning)."""
        return np.ndim(self.count) == 2

    @property
    def mean(self) -> np.ndarray:
        """⟨q⟩ per bin and column, shape (B, K); NaN in empty bins."""
        count = self.count if self.per_column else self.count[:, None]
        with np.errstate(invalid="ignore", divide="ignore"):
            return self.sum_q / count

    @property
    def mean_separation(self) -> np.ndarray:
        """⟨|r|⟩ per bin, shape (B,), m (over every column's pairs); NaN in empty bins."""
        count, sum_r = self.count, self.sum_r
        if self.per_column:
            count, sum_r = count.sum(axis=1), sum_r.sum(axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            return sum_r / count


#: Interleaved row chunks of the pair loop, summed in a fixed order: a fixed count makes
#: the sums independent of the number of threads (bit for bit), and 64 keeps 16 threads
#: busy on the triangle.
N_CHUNKS = 64


_FLAGS = {"contract", "nsz", "arcp"}


def _pair_sums(x, d, r_min, r_max, n_bins, n_chunks):
    """Count, Σ q, Σ q² and Σ r per bin (columns of ``d`` apart), over all pairs of ``x``,
    in ``n_chunks`` interleaved row chunks summed in order."""
    k = d.shape[1]
    count = np.zeros((n_chunks, n_bins), dtype=np.int64)
    sum_q = np.zeros((n_chunks, n_bins, k))
    sum_q2 = np.zeros((n_chunks, n_bins, k))
    sum_r = np.zeros((n_chunks, n_bins))
    over_threads(_start_chunks, n_chunks, x, d, r_min, r_max, count, sum_q, sum_q2, sum_r)
    return count.sum(axis=0), sum_q.sum(axis=0), sum_q2.sum(axis=0), sum_r.sum(axis=0)


@njit(fastmath=_FLAGS, cache=True, nogil=True, error_model="numpy")
def _start_chunks(first, stop, x, d, r_min, r_max, count, sum_q, sum_q2, sum_r):  # pragma: no cover
    """Row chunks ``first … stop − 1`` of :func:`_pair_sums`, each into its row of the sums."""
    p, k = d.shape[0], d.shape[1]
    n_chunks, n_bins = count.shape
    r2_min, r2_max = r_min * r_min, r_max * r_max
    log_r_min = log(r_min)
    inv_dlog = n_bins / (log(r_max) - log_r_min)
    for c in range(first, stop):
        for i in range(c, p, n_chunks):  # interleaved rows balance the triangle
            xi, yi, zi = x[i, 0], x[i, 1], x[i, 2]
            for j in range(i + 1, p):
                dx, dy, dz = x[j, 0] - xi, x[j, 1] - yi, x[j, 2] - zi
                r2 = dx * dx + dy * dy + dz * dz
                if r2 < r2_min or r2 >= r2_max:
                    continue
                r = sqrt(r2)
                b = min(int((log(r) - log_r_min) * inv_dlog), n_bins - 1)
                count[c, b] += 1
                sum_r[c, b] += r
                ex, ey, ez = dx / r, dy / r, dz / r
                for m in range(k):
                    q = (
                        (d[j, m, 0] - d[i, m, 0]) * ex
                        + (d[j, m, 1] - d[i, m, 1]) * ey
                        + (d[j, m, 2] - d[i, m, 2]) * ez
                    )
                    q *= q
                    sum_q[c, b, m] += q
                    sum_q2[c, b, m] += q * q


# A prange loop still: as a chunk kernel on threads (as _start_chunks) it compiled in a
# fifth of the time but ran 8 % slower, and only the "midpoint" binning compiles it.
@njit(parallel=True, fastmath=_FLAGS, cache=True)
def _pair_sums_midpoint(x, d, r_min, r_max, n_bins, n_chunks):
    """As :func:`_pair_sums`, each column binned and projected on its chord midpoint."""
    p, k = d.shape[0], d.shape[1]
    r2_min, r2_max = r_min * r_min, r_max * r_max
    log_r_min = log(r_min)
    inv_dlog = n_bins / (log(r_max) - log_r_min)
    # A pair's midpoint separation differs from r by at most half its largest relative
    # displacement: pairs farther than that outside the bins are skipped at once.
    reach = 0.0
    for i in range(p):
        for m in range(k):
            reach = max(reach, abs(d[i, m, 0]) + abs(d[i, m, 1]) + abs(d[i, m, 2]))
    r_lo, r_hi = max(r_min - reach, 0.0), r_max + reach
    count = np.zeros((n_chunks, n_bins, k), dtype=np.int64)
    sum_q = np.zeros((n_chunks, n_bins, k))
    sum_q2 = np.zeros((n_chunks, n_bins, k))
    sum_r = np.zeros((n_chunks, n_bins, k))
    for c in prange(n_chunks):
        for i in range(c, p, n_chunks):
            xi, yi, zi = x[i, 0], x[i, 1], x[i, 2]
            for j in range(i + 1, p):
                dx, dy, dz = x[j, 0] - xi, x[j, 1] - yi, x[j, 2] - zi
                r2 = dx * dx + dy * dy + dz * dz
                if r2 < r_lo * r_lo or r2 >= r_hi * r_hi:
                    continue
                for m in range(k):
                    ux = d[j, m, 0] - d[i, m, 0]
                    uy = d[j, m, 1] - d[i, m, 1]
                    uz = d[j, m, 2] - d[i, m, 2]
                    mx, my, mz = dx + 0.5 * ux, dy + 0.5 * uy, dz + 0.5 * uz
                    s2 = mx * mx + my * my + mz * mz
                    if s2 < r2_min or s2 >= r2_max:
                        continue
                    r = sqrt(s2)
                    b = min(int((log(r) - log_r_min) * inv_dlog), n_bins - 1)
                    q = (ux * mx + uy * my + uz * mz) / r
                    q *= q
                    count[c, b, m] += 1
                    sum_r[c, b, m] += r
                    sum_q[c, b, m] += q
                    sum_q2[c, b, m] += q * q
    return count.sum(axis=0), sum_q.sum(axis=0), sum_q2.sum(axis=0), sum_r.sum(axis=0)


def pair_sums(
    positions: np.ndarray, increments: np.ndarray, bins: LogBins, *, binning: str = "start"
) -> PairSums:
    """Accumulate longitudinal squared increments over all pairs of one snapshot.

    Parameters
    ----------
    positions : ndarray, shape (P, 3)
        Particle positions at time t, m.
    increments : ndarray, shape (P, K, 3) or (P, 3)
        Per-particle vectors (displacements at K values of Δt, or velocities).
    bins : LogBins
        Separation bins.
    binning : {"start", "midpoint"}
        Bin and project each pair on its separation at t (default), or, for
        displacements, on its chord midpoint r + (d_j − d_i)/2 (module docstring).

    Returns
    -------
    PairSums
        Sums with K columns (K = 1 for a (P, 3) input); counts and separations per
        column with ``binning="midpoint"``.
    """
    if binning not in BINNINGS:
        raise ValueError(f"binning must be one of {', '.join(BINNINGS)}, got {binning!r}")
    x = np.ascontiguousarray(positions, dtype=np.float64)
    d = np.asarray(increments, dtype=np.float64)
    if d.ndim == 2:
        d = d[:, None, :]
    d = np.ascontiguousarray(d)
    if x.ndim != 2 or x.shape[1] != 3:
        raise ValueError(f"positions must have shape (P, 3), got {x.shape}")
    if d.ndim != 3 or d.shape[0] != x.shape[0] or d.shape[2] != 3:
        raise ValueError(f"increments must have shape ({x.shape[0]}, K, 3), got {d.shape}")
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(d))):
        raise ValueError("positions or increments contain NaN or infinite values")
    kernel = _pair_sums if binning == "start" else _pair_sums_midpoint
    count, sum_q, sum_q2, sum_r = kernel(
        x, d, float(bins.r_min), float(bins.r_max), int(bins.n_bins), N_CHUNKS
    )
    return PairSums(count=count, sum_q=sum_q, sum_q2=sum_q2, sum_r=sum_r)
