"""Double-frame links and their median test, in plain NumPy and SciPy.

The references the crowded-case claims compare the stack's linking and outlier test
with. They solve the same problems with none of the stack's code:

- :func:`optimal_links`: the links from frame a to frame b within a radius that use
  every particle at most once and minimise Σ (d/r)² + (particles left unlinked), i.e.
  maximise Σ (2 − (d/r)²) over the links, by a dense linear assignment on each connected
  group of candidates;
- :func:`median_test`: the normalised median test (Westerweel & Scarano 2005) on each
  link's nearest neighbours by position, found from the full distance matrix.
"""

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

__all__ = ["median_test", "optimal_links"]


def optimal_links(a: np.ndarray, b: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Minimum-cost one-to-one links of ``a`` to ``b`` within ``radius`` (module docstring).

    Parameters
    ----------
    a, b : ndarray, shape (N_a, 3) and (N_b, 3)
        Positions at t and t + Δt, m.
    radius : float
        Largest displacement of a link, m.

    Returns
    -------
    index_a, index_b : ndarray of int, shape (L,)
        The linked rows, ordered by ``index_a``.
    """
    rows, cols = [], []
    for start in range(0, len(a), 512):  # the distance matrix a block of rows at a time
        distance = np.linalg.norm(a[start : start + 512, None, :] - b[None, :, :], axis=2)
        i, j = np.nonzero(distance <= radius)
        rows.append(i + start)
        cols.append(j)
    i, j = np.concatenate(rows), np.concatenate(cols)
    benefit = 2.0 - (np.linalg.norm(a[i] - b[j], axis=1) / radius) ** 2
    # Groups: particles of either frame joined by a candidate link.
    graph = coo_matrix((np.ones(len(i)), (i, len(a) + j)), shape=(len(a) + len(b),) * 2)
    _, group = connected_components(graph, directed=False)
    chosen_a, chosen_b = [], []
    for g in np.unique(group[i]):
        edges = group[i] == g
        ga, ia = np.unique(i[edges], return_inverse=True)
        gb, ib = np.unique(j[edges], return_inverse=True)
        matrix = np.zeros((len(ga), len(gb)))
        matrix[ia, ib] = benefit[edges]
        r, c = linear_sum_assignment(matrix, maximize=True)
        keep = matrix[r, c] > 0
        chosen_a.append(ga[r[keep]])
        chosen_b.append(gb[c[keep]])
    if not chosen_a:
        return np.empty(0, dtype=np.int64), np.empty(0, dtype=np.int64)
    index_a, index_b = np.concatenate(chosen_a), np.concatenate(chosen_b)
    order = np.argsort(index_a)
    return index_a[order], index_b[order]


def median_test(
    positions: np.ndarray,
    displacements: np.ndarray,
    *,
    threshold: float,
    noise: float,
    neighbours: int,
) -> np.ndarray:
    """Links whose displacement departs from their neighbours' median.

    With m the component-wise median of the ``neighbours`` nearest other links'
    displacements and s the median of their distances from m, a link is an outlier when
    |ΔX − m| > threshold · (s + noise).

    Parameters
    ----------
    positions, displacements : ndarray, shape (N, 3)
        X(t) and ΔX, m.
    threshold, noise : float
        The test's threshold and noise floor ε₀ (m).
    neighbours : int
        Neighbours per link (fewer when there are fewer links; no test below 4 links).

    Returns
    -------
    ndarray of bool, shape (N,)
    """
    n = len(positions)
    k = min(neighbours, n - 1)
    if k < 3:
        return np.zeros(n, dtype=bool)
    outlier = np.empty(n, dtype=bool)
    for start in range(0, n, 512):
        block = slice(start, min(start + 512, n))
        distance = np.linalg.norm(positions[block, None, :] - positions[None, :, :], axis=2)
        distance[np.arange(block.stop - start), np.arange(start, block.stop)] = np.inf
        nearest = np.argpartition(distance, k - 1, axis=1)[:, :k]
        around = displacements[nearest]
        median = np.median(around, axis=1)
        spread = np.median(np.linalg.norm(around - median[:, None, :], axis=2), axis=1)
        departure = np.linalg.norm(displacements[block] - median, axis=1)
        outlier[block] = departure > threshold * (spread + noise)
    return outlier
