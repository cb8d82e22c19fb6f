"""Sample truth: statistics of the exact velocities over the actual particles and pairs.

Comparing an estimate with the sample truth, rather than with the ensemble D_LL,
removes the sampling noise of the particular realizations and isolates method error
(docs/statistics.md §8).
"""

import numpy as np

from ptv.bins import LogBins
from ptv.stats.pairs import PairSums, pair_sums
from simulator.particles import Box


def sample_structure_function(
    positions: np.ndarray, velocity: np.ndarray, bins: LogBins, *, region: Box
) -> PairSums:
    """Longitudinal S2 of the exact velocities over all pairs inside ``region``.

    Parameters
    ----------
    positions : ndarray, shape (M, P, 3)
        Positions of P particles in M snapshots, m.
    velocity : ndarray, shape (M, P, 3)
        Exact velocities at those positions, m/s.
    bins : LogBins
        Separation bins.
    region : Box
        Only particles inside it enter pairs (pairs never span snapshots).

    Returns
    -------
    PairSums
        One column; ``mean[:, 0]`` is the sample-truth S2, m²/s².
    """
    positions = np.asarray(positions)
    velocity = np.asarray(velocity)
    if positions.ndim != 3 or positions.shape != velocity.shape:
        raise ValueError(
            "positions and velocity must both be (M, P, 3), "
            f"got {positions.shape} and {velocity.shape}"
        )
    total = None
    for x, u in zip(positions, velocity, strict=True):
        inside = region.contains(x)
        sums = pair_sums(x[inside], u[inside], bins)
        total = sums if total is None else total + sums
    return total
