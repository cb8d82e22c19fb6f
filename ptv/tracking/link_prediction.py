"""Links at every Δt from one shared first frame, each predicted from the link at the
next smaller Δt.

When every Δt of a snapshot starts from the same frame a (a time-resolved recording cut
into pairs, as the paper's single high-speed sequence is), a particle's link at Δt_j
tells where it is at a larger Δt_k: X(t) + ΔX_j·Δt_k/Δt_j, off by the curvature of its
path, ½a·Δt_k(Δt_k − Δt_j), and by its position noise. Searching around that
prediction with a radius from its measured error, rather than around X(t) with
max_speed·Δt_k, keeps the search small at the largest Δt, where the radius
max_speed·Δt_k would reach the spacing of the particles and take strangers
(docs/ptv.md §4).

- :func:`chained_link`: the link of frame a's particles that were linked at Δt_j to
  frame b at Δt_k, around their predictions.
- :func:`measure_prediction`: the radius of every Δt from the misses of the predictions
  on a few snapshots: |median miss| + :data:`MISS_SIGMAS` σ, σ the largest per-component
  spread of the misses (from their median absolute deviation), as max_speed is
  measured (:mod:`ptv.tracking.link_speed`), with twice its 5σ for the misses' heavier
  tails.
"""

import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ptv.tracking.link_speed import MAD_TO_SIGMA
from ptv.tracking.linking import Links, link

__all__ = ["MISS_SIGMAS", "LinkPrediction", "chained_link", "measure_prediction"]

log = logging.getLogger(__name__)

#: The radius around a prediction: the median miss plus this many robust spreads of the
#: misses. The misses are heavier-tailed than a Gaussian (the dim particles of the sheet's
#: wings and the blended ones are noisier than the median particle): 5 spreads dropped
#: 0.25 % of the particles and took 0.15 % off u′ and 0.2 % off ε (`ci`, through the true
#: cameras); 10 keep them, and still leave 10⁻⁴ of the links a second candidate.
MISS_SIGMAS = 10.0
#: Fewest misses a Δt's radius is measured on.
MIN_MISSES = 20


def chained_link(
    frame_a: np.ndarray,
    frame_b: np.ndarray,
    dt: float,
    previous: tuple[float, np.ndarray, np.ndarray],
    *,
    radius: float,
) -> Links:
    """Link the particles of frame a linked at a smaller Δt to frame b at ``dt``.

    Parameters
    ----------
    frame_a, frame_b : ndarray, shapes (N_a, 3) and (N_b, 3)
        The matched points at t and at t + dt, m.
    dt : float
        Δt of frame b, s.
    previous : (float, ndarray (L,) of int, ndarray (L, 3))
        The smaller Δt_j (s), the rows of frame a linked at it and their displacements
        ΔX_j (m).
    radius : float
        Search radius around each prediction X(t) + ΔX_j·dt/Δt_j, m.

    Returns
    -------
    Links
        ``index_a`` rows of ``frame_a``; only particles linked at Δt_j can be linked.
    """
    dt_j, rows, moved = previous
    if not dt > dt_j > 0:
        raise ValueError(f"the prediction needs 0 < Δt_j < Δt, got Δt_j = {dt_j}, Δt = {dt}")
    rows = np.asarray(rows, dtype=np.int64)
    predicted = np.asarray(moved, dtype=float) * (dt / dt_j)
    found = link(frame_a[rows], frame_b, radius=radius, predictor=lambda _: predicted)
    return Links(
        index_a=rows[found.index_a],
        index_b=found.index_b,
        positions=found.positions,
        displacements=found.displacements,
        ambiguous=found.ambiguous,
        candidates=found.candidates,
    )


@dataclass(frozen=True)
class LinkPrediction:
    """How far the links' predictions missed, and the radius each Δt is linked with.

    Attributes
    ----------
    dt : ndarray, shape (K,)
        The Δt, s, in the dataset's order.
    radii : ndarray, shape (K,)
        Search radius around the prediction at each Δt, m (NaN at the smallest Δt, which
        is linked around X(t) with max_speed).
    mean_miss : ndarray, shape (K, 3)
        Median miss of the predictions (found − predicted), per component, m (NaN at
        the smallest Δt; the field keeps its first name in summary.json).
    sigma_miss : ndarray, shape (K, 3)
        Per-component spread of the misses, from their median absolute deviation, m.
    misses : ndarray of int, shape (K,)
        Links measured at each Δt.
    snapshots : int
        Snapshots measured.
    """

    dt: np.ndarray
    radii: np.ndarray
    mean_miss: np.ndarray
    sigma_miss: np.ndarray
    misses: np.ndarray
    snapshots: int

    def as_dict(self) -> dict:
        """JSON-able form (SI units; None for NaN)."""

        def listed(values) -> list:
            return [None if not np.isfinite(v) else float(v) for v in np.ravel(values)]

        return {
            "dt": listed(self.dt),
            "radii": listed(self.radii),
            "mean_miss": [listed(row) for row in self.mean_miss],
            "sigma_miss": [listed(row) for row in self.sigma_miss],
            "misses": [int(v) for v in self.misses],
            "snapshots": self.snapshots,
        }


def measure_prediction(
    snapshots: Sequence[tuple[np.ndarray, Sequence[np.ndarray]]],
    dt: np.ndarray,
    *,
    first_radius: float,
    search_radius: Callable[[float], float],
) -> LinkPrediction:
    """The radius around the prediction at every Δt but the smallest, measured on the
    misses of a few snapshots (module docstring).

    Each snapshot is linked at the smallest Δt around X(t) within ``first_radius``, then
    at each larger Δt around its prediction from the previous Δt within
    ``search_radius(Δt)`` (the radius max_speed·Δt of unpredicted links: the
    assignment then takes the candidate nearest to the prediction); the misses of those
    links give the radius, which is kept below ``search_radius(Δt)``.

    Parameters
    ----------
    snapshots : sequence of (ndarray (N_a, 3), sequence of K ndarray (N_b, 3))
        Per snapshot, the matched points of frame a and of frame b at every Δt (in the
        order of ``dt``), m.
    dt : ndarray, shape (K,)
        The Δt, s, distinct (any order).
    first_radius : float
        Link radius at the smallest Δt, m.
    search_radius : callable(float) -> float
        The radius of an unpredicted link at a Δt, m.

    Returns
    -------
    LinkPrediction

    Raises
    ------
    ValueError
        Fewer than :data:`MIN_MISSES` links at a Δt to measure its misses on.
    """
    dt = np.asarray(dt, dtype=float)
    order = np.argsort(dt)
    misses: list[list[np.ndarray]] = [[] for _ in dt]
    for a, frames_b in snapshots:
        first = order[0]
        found = link(a, frames_b[first], radius=first_radius)
        previous = (dt[first], found.index_a, found.displacements)
        for k in order[1:]:
            chained = chained_link(
                a, frames_b[k], dt[k], previous, radius=search_radius(float(dt[k]))
            )
            # Links come ordered by their row of frame a, so the rows linked at Δt_j are
            # sorted and those chained at Δt_k are found among them by bisection.
            at_j = np.searchsorted(previous[1], chained.index_a)
            predicted = previous[2][at_j] * (dt[k] / previous[0])
            misses[k].append(chained.displacements - predicted)
            previous = (dt[k], chained.index_a, chained.displacements)
    k_count = len(dt)
    radii = np.full(k_count, np.nan)
    mean = np.full((k_count, 3), np.nan)
    sigma = np.full((k_count, 3), np.nan)
    counts = np.zeros(k_count, dtype=np.int64)
    for k in order[1:]:
        miss = np.concatenate(misses[k]) if misses[k] else np.empty((0, 3))
        counts[k] = len(miss)
        if len(miss) < MIN_MISSES:
            raise ValueError(
                f"Δt_{k} = {dt[k]:.4g} s: {len(miss)} link(s) predicted from the smaller Δt "
                f"on {len(snapshots)} snapshot(s), at least {MIN_MISSES} needed to measure "
                "how far the predictions miss"
            )
        mean[k] = np.median(miss, axis=0)
        sigma[k] = MAD_TO_SIGMA * np.median(np.abs(miss - mean[k]), axis=0)
        measured = float(np.linalg.norm(mean[k]) + MISS_SIGMAS * sigma[k].max())
        radii[k] = min(measured, search_radius(float(dt[k])))
        log.info(
            "Δt_%d = %.4g s: links searched within %.3g µm of their prediction from Δt_%d "
            "(misses: mean %.3g µm, spread %s µm, %d links)",
            k,
            dt[k],
            radii[k] * 1e6,
            order[np.searchsorted(dt[order], dt[k]) - 1],
            np.linalg.norm(mean[k]) * 1e6,
            np.round(sigma[k] * 1e6, 2).tolist(),
            counts[k],
        )
    return LinkPrediction(dt, radii, mean, sigma, counts, len(snapshots))
