"""Two-camera stereo matching by brute force, in plain NumPy and SciPy.

The reference the image-stack claims compare :func:`ptv.matching.stereo.match` with. It solves
the same problem with none of its code (no candidate pre-search, no sparse
assignment):

- every pair of rays (one per camera) is a candidate when their skew distance d is
  below the tolerance and the midpoint of their common perpendicular lies in the
  measurement box;
- the chosen pairs use every detection at most once and minimise
  Σ (d/tol)² + (detections left unmatched), i.e. maximise Σ (2 − (d/tol)²) over the
  chosen pairs, found by a dense linear assignment over all N₁ × N₂ pairs.
"""

import numpy as np
from scipy.optimize import linear_sum_assignment


def _skew_midpoints(o1, v1, o2, v2) -> tuple[np.ndarray, np.ndarray]:
    """Skew distance (N₁, N₂) and midpoint of the common perpendicular (N₁, N₂, 3) of
    every pair of rays (origins o, unit directions v)."""
    w = o1[:, None, :] - o2[None, :, :]
    b = v1 @ v2.T
    d = np.einsum("ik,ijk->ij", v1, w)
    e = np.einsum("jk,ijk->ij", v2, w)
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = 1.0 - b * b
        s = (b * e - d) / denom
        t = (e - b * d) / denom
    p1 = o1[:, None, :] + s[..., None] * v1[:, None, :]
    p2 = o2[None, :, :] + t[..., None] * v2[None, :, :]
    return np.linalg.norm(p1 - p2, axis=2), 0.5 * (p1 + p2)


def brute_force_match(
    rays: tuple, volume: tuple[np.ndarray, np.ndarray], tolerance: float
) -> np.ndarray:
    """The matched 3-D points of two cameras' rays.

    Parameters
    ----------
    rays : (RayBundle, RayBundle)
        Each camera's rays: ``origins`` and unit ``directions``, shapes (N_c, 3), m.
    volume : (lower, upper)
        Corners of the measurement box, shape (3,) each, m.
    tolerance : float
        Largest skew distance of a matched pair, m.

    Returns
    -------
    ndarray, shape (N, 3)
        Midpoints of the chosen pairs, m.
    """
    (o1, v1), (o2, v2) = ((np.asarray(r.origins), np.asarray(r.directions)) for r in rays)
    if not len(o1) or not len(o2):
        return np.empty((0, 3))
    distance, midpoint = _skew_midpoints(o1, v1, o2, v2)
    lower, upper = (np.asarray(c, dtype=float) for c in volume)
    inside = np.all((midpoint >= lower) & (midpoint <= upper), axis=2)
    candidate = np.isfinite(distance) & (distance < tolerance) & inside
    gain = np.where(candidate, 2.0 - (np.where(candidate, distance, 0.0) / tolerance) ** 2, 0.0)
    rows, cols = linear_sum_assignment(gain, maximize=True)
    chosen = candidate[rows, cols]
    return midpoint[rows[chosen], cols[chosen]]
