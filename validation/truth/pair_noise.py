"""The noise term of S2 over the very pairs a measurement used, from the truth.

The multi-Δt fit's intercept c2(r) is the mean over the pairs of a separation bin of
q = [(δ_j − δ_i)·e]², δ the error of a measured displacement ΔX against the true one
and e = r/|r|. Predicting it from one displacement-noise variance per component
(:class:`validation.score.noise_prediction.NoisePrediction`) assumes every particle
equally noisy and errors independent between particles. On dense images neither holds exactly: two
particles close in space are close on every image, so they are more often blended and
their fitted centres share an error (a joint fit trades light between the two spots).
Summing q over the actual pairs with the actual errors needs neither assumption.

The pairs are enumerated by a k-d tree (:class:`scipy.spatial.cKDTree`), independently
of the stack's binned pair kernel (:func:`ptv.stats.pairs.pair_sums`). A snapshot with
more than :data:`MAX_PARTICLES` scored particles contributes the pairs of a random
subset of that size (every pair equally likely to be kept: an unbiased sample).
"""

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ptv.bins import LogBins

#: Particles per snapshot whose pairs are summed (about 5·10⁵ pairs at most).
MAX_PARTICLES = 1000


@dataclass(frozen=True)
class PairNoiseSums:
    """Sums over pairs of the squared longitudinal difference of their ΔX errors.

    Attributes
    ----------
    sum_q : ndarray, shape (K, B)
        Σ [(δ_j − δ_i)·e]² per Δt and separation bin, m².
    pairs : ndarray of int64, shape (K, B)
        Pairs in each sum.
    """

    sum_q: np.ndarray
    pairs: np.ndarray

    @classmethod
    def empty(cls, dt_count: int, bins: LogBins) -> "PairNoiseSums":
        """No pair yet, for ``dt_count`` values of Δt."""
        shape = (dt_count, bins.n_bins)
        return cls(np.zeros(shape), np.zeros(shape, dtype=np.int64))

    @classmethod
    def of_snapshot(
        cls, positions: np.ndarray, errors: np.ndarray, bins: LogBins, *, seed: int = 0
    ) -> "PairNoiseSums":
        """The sums over the pairs of one snapshot's particles.

        Parameters
        ----------
        positions : ndarray, shape (N, 3)
            True X(t) of the scored particles, m.
        errors : ndarray, shape (N, K, 3)
            Measured − true ΔX per Δt, m (NaN where a particle has no ΔX at that Δt).
        bins : LogBins
            Separation bins.
        seed : int
            Seed of the subset drawn when N > :data:`MAX_PARTICLES`.
        """
        positions = np.asarray(positions, dtype=float).reshape(-1, 3)
        errors = np.asarray(errors, dtype=float)
        if len(positions) > MAX_PARTICLES:
            keep = np.random.default_rng(seed).choice(len(positions), MAX_PARTICLES, False)
            positions, errors = positions[keep], errors[keep]
        sums = cls.empty(errors.shape[1], bins)
        if len(positions) < 2:
            return sums
        pairs = cKDTree(positions).query_pairs(bins.edges[-1], output_type="ndarray")
        if not len(pairs):
            return sums
        i, j = pairs[:, 0], pairs[:, 1]
        separation = positions[j] - positions[i]
        r = np.linalg.norm(separation, axis=1)
        b = np.searchsorted(bins.edges, r, side="right") - 1
        ok = (b >= 0) & (b < bins.n_bins)
        i, j, b = i[ok], j[ok], b[ok]
        direction = separation[ok] / r[ok, None]
        for k in range(errors.shape[1]):
            q = np.einsum("pc,pc->p", errors[j, k] - errors[i, k], direction) ** 2
            valid = np.isfinite(q)
            sums.sum_q[k] += np.bincount(b[valid], q[valid], minlength=bins.n_bins)
            sums.pairs[k] += np.bincount(b[valid], minlength=bins.n_bins)
        return sums

    @classmethod
    def stacked(cls, rows: "list[PairNoiseSums]") -> "PairNoiseSums":
        """One row per Δt from sums of one Δt each (K = 1)."""
        return cls(
            np.concatenate([r.sum_q for r in rows]), np.concatenate([r.pairs for r in rows])
        )

    def merged(self, other: "PairNoiseSums") -> "PairNoiseSums":
        """The sums of this and ``other``."""
        return PairNoiseSums(self.sum_q + other.sum_q, self.pairs + other.pairs)

    def mean(self) -> np.ndarray:
        """⟨[(δ_j − δ_i)·e]²⟩ per Δt and bin, shape (K, B), m² (NaN where no pair)."""
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(self.pairs > 0, self.sum_q / np.maximum(self.pairs, 1), np.nan)
