"""The links of a run, per Δt: the input of the run statistics.

A link is one particle measured at t and t + Δt: its position X(t) and displacement
ΔX = X(t + Δt) − X(t). :class:`RunParticles` holds every link of the run at one Δt,
snapshot after snapshot, with the flags the statistics select on (inside the analysis
box by X(t), not an outlier). The PTV pipeline (:mod:`ptv.pipeline.double_frame`) produces them from
images; anything else that yields positions at t and t + Δt (exact trajectories,
truth-paired detections) can too, and the same statistics run on it.

Boxes are axis-aligned, given by their (lower, upper) corners in m.
"""

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

__all__ = ["RunParticles", "shared_snapshots"]


@dataclass(frozen=True, eq=False)
class RunParticles:
    """All links of the run at one Δt, snapshots concatenated.

    Attributes
    ----------
    k : int
        Δt index in the dataset.
    dt : float
        Δt, s.
    positions : ndarray, shape (N, 3)
        X(t), m.
    displacements : ndarray, shape (N, 3)
        ΔX, m.
    offsets : ndarray of int, shape (M + 1,)
        Rows offsets[i]:offsets[i + 1] belong to snapshot ``snapshot_ids[i]``.
    snapshot_ids : ndarray of int, shape (M,)
        Snapshot numbers kept (those with links).
    detections : ndarray of int, shape (S, 2, C)
        Detections per processed snapshot, frame (a, b) and camera.
    matches : ndarray of int, shape (S, 2)
        Matches per processed snapshot and frame.
    links : ndarray of int, shape (S,)
        Links per processed snapshot.
    processed : ndarray of int, shape (S,)
        Snapshot numbers processed (S ≥ M).
    in_analysis : ndarray of bool, shape (N,)
        X(t) inside the analysis volume.
    outlier : ndarray of bool, shape (N,)
        Links failing the normalised median test (not used by the statistics).
    ambiguous : ndarray of int, shape (S,) or None
        Links per processed snapshot whose particle had a second candidate within the
        link radius (None where no linking was done, as for exact trajectories).
    spacing : ndarray, shape (S,) or None
        Median nearest-neighbour distance of the matched particles of frame a per
        processed snapshot, m (None as ``ambiguous``).

    Examples
    --------
    The links of one Δt = 1 ms from another source (here: two snapshots of three
    particles; no cameras), the last one flagged an outlier:

    >>> import numpy as np
    >>> import ptv
    >>> positions = np.arange(18.0).reshape(6, 3) * 1e-3  # X(t), m
    >>> run = ptv.RunParticles(
    ...     k=0,
    ...     dt=1e-3,
    ...     positions=positions,
    ...     displacements=np.full((6, 3), 1e-4),  # ΔX, m
    ...     offsets=np.array([0, 3, 6]),  # snapshot i: rows offsets[i]:offsets[i + 1]
    ...     snapshot_ids=np.array([0, 1]),
    ...     detections=np.full((2, 2, 0), 3),  # per snapshot, frame and camera (none)
    ...     matches=np.full((2, 2), 3),
    ...     links=np.array([3, 3]),
    ...     processed=np.array([0, 1]),
    ...     in_analysis=np.ones(6, dtype=bool),
    ...     outlier=np.array([False] * 5 + [True]),
    ... )
    >>> run.used  # what the statistics take
    array([ True,  True,  True,  True,  True, False])
    >>> [len(x) for x, _ in run.snapshot_arrays()]  # used links per snapshot
    [3, 2]
    """

    k: int
    dt: float
    positions: np.ndarray
    displacements: np.ndarray
    offsets: np.ndarray
    snapshot_ids: np.ndarray
    detections: np.ndarray
    matches: np.ndarray
    links: np.ndarray
    processed: np.ndarray
    in_analysis: np.ndarray
    outlier: np.ndarray
    ambiguous: np.ndarray | None = None
    spacing: np.ndarray | None = None

    @classmethod
    def from_links(
        cls,
        k: int,
        dt: float,
        snapshots: Sequence[tuple[np.ndarray, np.ndarray]],
    ) -> "RunParticles":
        """The links of one Δt from another source: every link used, no cameras.

        Parameters
        ----------
        k : int
            Δt index.
        dt : float
            Δt, s.
        snapshots : sequence of M (ndarray (N_m, 3), ndarray (N_m, 3))
            Per snapshot, X(t) and ΔX of its links, m (the snapshots numbered 0 … M − 1).

        Returns
        -------
        RunParticles
            Every link in the analysis volume and none an outlier; the detections,
            matches and links of each snapshot counted as its N_m.

        Examples
        --------
        >>> import numpy as np
        >>> import ptv
        >>> x = np.zeros((4, 3))  # X(t) of four particles, m
        >>> run = ptv.RunParticles.from_links(0, 1e-3, [(x, x + 1e-4), (x[:2], x[:2])])
        >>> run.links, run.used.sum()
        (array([4, 2]), np.int64(6))
        """
        counts = np.array([len(x) for x, _ in snapshots], dtype=np.int64)
        numbers = np.arange(len(snapshots), dtype=np.int64)
        total = int(counts.sum())
        return cls(
            k=k,
            dt=float(dt),
            positions=np.concatenate([x for x, _ in snapshots]).reshape(-1, 3),
            displacements=np.concatenate([d for _, d in snapshots]).reshape(-1, 3),
            offsets=np.concatenate([[0], np.cumsum(counts)]).astype(np.int64),
            snapshot_ids=numbers,
            detections=np.broadcast_to(counts[:, None, None], (len(counts), 2, 0)).copy(),
            matches=np.repeat(counts[:, None], 2, axis=1),
            links=counts,
            processed=numbers,
            in_analysis=np.ones(total, dtype=bool),
            outlier=np.zeros(total, dtype=bool),
        )

    @property
    def used(self) -> np.ndarray:
        """(N,) bool: links the statistics use (in the analysis volume, not outliers)."""
        return self.in_analysis & ~self.outlier

    @property
    def ambiguity(self) -> float:
        """Fraction of the links with a second candidate within the link radius (nan
        without links or without linking)."""
        if self.ambiguous is None or self.links.sum() == 0:
            return float("nan")
        return float(self.ambiguous.sum() / self.links.sum())

    @property
    def skipped(self) -> np.ndarray:
        """Snapshot numbers processed but skipped (no match or no link)."""
        return np.setdiff1d(self.processed, self.snapshot_ids)

    def snapshot_arrays(self, *, analysis: bool = True) -> list[tuple[np.ndarray, np.ndarray]]:
        """(positions, displacements) per kept snapshot; with ``analysis``, the used links."""
        out = []
        for i in range(len(self.snapshot_ids)):
            rows = slice(int(self.offsets[i]), int(self.offsets[i + 1]))
            x, d = self.positions[rows], self.displacements[rows]
            if analysis:
                keep = self.used[rows]
                x, d = x[keep], d[keep]
            out.append((x, d))
        return out


def shared_snapshots(
    runs: Sequence[RunParticles],
) -> tuple[np.ndarray, list[tuple[np.ndarray, np.ndarray]]]:
    """The particles used at every Δt of runs that share their first frames.

    With a shared frame a, a particle has the same measured X(t) in every run, so the
    runs' used links are joined on X(t) (bit for bit), snapshot by snapshot.

    Parameters
    ----------
    runs : sequence of K RunParticles
        Runs whose snapshot m shares frame a.

    Returns
    -------
    (ndarray of int (S,), list of S (ndarray (P, 3), ndarray (P, K, 3)))
        The snapshots kept in every run, and per snapshot X(t), m, and ΔX at each Δt, m.
    """
    per_run = [
        dict(zip(run.snapshot_ids.tolist(), run.snapshot_arrays(), strict=True)) for run in runs
    ]
    common = sorted(set.intersection(*(set(d) for d in per_run)))
    out = []
    for m in common:
        arrays = [d[m] for d in per_run]
        index = [{row.tobytes(): i for i, row in enumerate(x)} for x, _ in arrays]
        keys = [key for key in index[0] if all(key in ix for ix in index[1:])]
        rows = [[ix[key] for key in keys] for ix in index]
        x = arrays[0][0][rows[0]].reshape(-1, 3)
        d = np.stack([a[1][r].reshape(-1, 3) for a, r in zip(arrays, rows, strict=True)], axis=1)
        out.append((x, d))
    return np.array(common, dtype=np.int64), out
