"""The normalised median test on scattered 3-D displacements: mislinks among links."""

import numpy as np
from scipy.spatial import cKDTree

__all__ = ["median_test_outliers"]


def median_test_outliers(
    positions: np.ndarray,
    displacements: np.ndarray,
    *,
    threshold: float,
    noise: float,
    neighbours: int = 8,
) -> np.ndarray:
    """Normalised median test (Westerweel & Scarano 2005) on scattered 3-D displacements.

    For link i with neighbours j (its ``neighbours`` nearest links by position), m_i is
    the component-wise median of ΔX_j, r̃_i the median of |ΔX_j − m_i|, and link i is
    an outlier when |ΔX_i − m_i| > threshold·(r̃_i + noise).

    Parameters
    ----------
    positions, displacements : ndarray, shape (N, 3)
        X(t) and ΔX of the links of one snapshot, m.
    threshold : float
        > 0 (about 2 for PIV vectors; 4 keeps genuine turbulent increments).
    noise : float
        ε0, the displacement noise floor, m (> 0).
    neighbours : int
        Neighbours per link (fewer when the snapshot has fewer links).

    Returns
    -------
    ndarray of bool, shape (N,)
        True for outliers; all False with fewer than 4 links.
    """
    x = np.asarray(positions, dtype=np.float64)
    d = np.asarray(displacements, dtype=np.float64)
    n = len(x)
    k = min(int(neighbours), n - 1)
    if k < 3:
        return np.zeros(n, dtype=bool)
    _, nb = cKDTree(x).query(x, k=k + 1)
    nb = nb[:, 1:]  # drop the point itself
    median = np.median(d[nb], axis=1)
    spread = np.median(np.linalg.norm(d[nb] - median[:, None, :], axis=2), axis=1)
    return np.linalg.norm(d - median, axis=1) > threshold * (spread + noise)
