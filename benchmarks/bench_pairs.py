"""Pair binning speed: all pairs of a snapshot, all Δt columns per pair.

Target (docs/performance.md): ≥ 5·10⁷ particle pairs/s with all Δt values of a snapshot
processed per pair.
"""

import time

import numpy as np

from ptv.bins import LogBins
from ptv.stats.pairs import pair_sums


def run(quick: bool) -> dict:
    """Time ``pair_sums`` on 2000 particles in the 70 × 70 × 2 mm volume, 5 Δt + truth."""
    rng = np.random.default_rng(0)
    p, k = 2000, 6
    x = rng.uniform(-0.5, 0.5, (p, 3)) * np.array([0.07, 0.07, 0.002])
    d = rng.normal(size=(p, k, 3)) * 1e-5
    bins = LogBins(5e-4, 0.035, 30)
    pair_sums(x, d, bins)
    best = np.inf
    for _ in range(3 if quick else 10):
        start = time.perf_counter()
        sums = pair_sums(x, d, bins)
        best = min(best, time.perf_counter() - start)
    pairs = p * (p - 1) / 2
    return {
        "particle_pairs_per_s": pairs / best,
        "pairs_in_range_per_s": float(sums.count.sum()) / best,
        "fraction_in_range": float(sums.count.sum()) / pairs,
        "columns_per_pair": k,
        "target_pairs_per_s": 5e7,
    }
