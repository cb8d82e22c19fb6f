"""One-to-one assignment on a sparse candidate set, with the option to leave items out.

Shared by stereo matching (detections of camera 1 against camera 2) and particle
linking (particles at t against particles at t + Δt).

The problem: rows (items of set A) and columns (items of set B), candidate edges
(r, c) with costs w ≥ 0. Choose a set of edges using every row and every column at
most once that minimises

    Σ_chosen w  +  u · (unassigned rows + unassigned columns),

where u is the cost of leaving an item out. With costs normalised to w ≤ 1 and u = 1
(the callers' choice), pairing two otherwise idle items always pays, so the solution
is close to a maximum-cardinality matching, and among those the one with the least
total cost.

It is solved exactly as a square assignment problem (Jonker–Volgenant, sparse:
``scipy.sparse.csgraph.min_weight_full_bipartite_matching``) on the usual augmented
matrix [[W, U_r], [U_c, Wᵀ·0]]: every row gets a private dummy column of cost u,
every column a private dummy row of cost u, and dummy rows meet dummy columns
(at zero cost) wherever the transposed real edge exists, which keeps the matrix sparse
and still guarantees a full matching. Components that are a single isolated edge are
taken directly without the solver.
"""

import numpy as np
from scipy import sparse
from scipy.sparse.csgraph import min_weight_full_bipartite_matching


def assign(
    rows: np.ndarray,
    cols: np.ndarray,
    cost: np.ndarray,
    shape: tuple[int, int],
    *,
    unmatched_cost: float = 1.0,
) -> np.ndarray:
    """Minimum-cost one-to-one selection of candidate edges.

    Parameters
    ----------
    rows, cols : ndarray of int, shape (E,)
        Candidate edges; each (row, col) pair at most once.
    cost : ndarray, shape (E,)
        Edge costs, finite and ≥ 0.
    shape : tuple of int
        (number of rows, number of columns).
    unmatched_cost : float
        Cost u of leaving one row or one column unassigned, > 0.

    Returns
    -------
    ndarray of int
        Indices into the edge arrays of the chosen edges, increasing.
    """
    rows = np.asarray(rows, dtype=np.int64)
    cols = np.asarray(cols, dtype=np.int64)
    cost = np.asarray(cost, dtype=float)
    n_rows, n_cols = int(shape[0]), int(shape[1])
    if not (rows.shape == cols.shape == cost.shape and rows.ndim == 1):
        raise ValueError(
            f"rows, cols and cost must be 1-D of one length, got {rows.shape}, "
            f"{cols.shape}, {cost.shape}"
        )
    if len(rows) == 0:
        return np.empty(0, dtype=np.int64)
    if rows.min() < 0 or rows.max() >= n_rows or cols.min() < 0 or cols.max() >= n_cols:
        raise ValueError(f"edge indices outside the shape {shape}")
    if not (np.isfinite(cost).all() and cost.min() >= 0):
        raise ValueError("edge costs must be finite and >= 0")
    if not unmatched_cost > 0:
        raise ValueError(f"unmatched_cost must be > 0, got {unmatched_cost}")
    key = rows * n_cols + cols
    if len(np.unique(key)) != len(key):
        raise ValueError("each (row, col) edge may be given only once")

    row_degree = np.bincount(rows, minlength=n_rows)
    col_degree = np.bincount(cols, minlength=n_cols)
    # An edge alone in its component: take it when it beats leaving both ends out.
    lone = (row_degree[rows] == 1) & (col_degree[cols] == 1)
    chosen = [np.flatnonzero(lone & (cost < 2 * unmatched_cost))]
    rest = np.flatnonzero(~lone)
    if len(rest):
        chosen.append(rest[_solve(rows[rest], cols[rest], cost[rest], unmatched_cost)])
    return np.sort(np.concatenate(chosen))


def _solve(rows: np.ndarray, cols: np.ndarray, cost: np.ndarray, u: float) -> np.ndarray:
    """Exact solution on the augmented sparse matrix; returns chosen edge indices."""
    r_ids, r = np.unique(rows, return_inverse=True)
    c_ids, c = np.unique(cols, return_inverse=True)
    nr, nc = len(r_ids), len(c_ids)
    e = len(rows)
    # Every full matching of the (nr + nc)² matrix has nr + nc edges: adding 1 to all
    # weights keeps the optimum and keeps them non-zero, as the solver requires.
    i = np.concatenate([r, np.arange(nr), nr + np.arange(nc), nr + c])
    j = np.concatenate([c, nc + np.arange(nr), np.arange(nc), nc + r])
    w = np.concatenate([cost, np.full(nr, u), np.full(nc, u), np.zeros(e)]) + 1.0
    n = nr + nc
    graph = sparse.csr_array((w, (i, j)), shape=(n, n))
    row_ind, col_ind = min_weight_full_bipartite_matching(graph)
    real = (row_ind < nr) & (col_ind < nc)
    picked_r, picked_c = row_ind[real], col_ind[real]
    # Map the chosen (local row, local col) back to edge indices.
    order = np.lexsort((c, r))
    keys = r[order] * nc + c[order]
    return order[np.searchsorted(keys, picked_r * nc + picked_c)]
