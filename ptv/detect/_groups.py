"""Groups of detections fitted together, and the neighbours held fixed (private).

Detections closer than :data:`GROUP_DISTANCE_PX` to one another (a lone one is a group
of one) are refined jointly (:mod:`ptv.detect._refine`). On dense images these chains
grow without bound (at 0.02 particles per pixel half the detections are in chains of
more than :data:`MAX_GROUP`), so a chain longer than that is cut into pieces: its
members are linked again at :data:`PIECE_DISTANCES`, one distance after the other, as
long as a piece is still too large, and what is left at the last distance is cut into
runs of :data:`MAX_GROUP` in index order. A piece is fitted with the light of its
neighbours (the other detections within :data:`GROUP_DISTANCE_PX` of a member) held
fixed (:mod:`ptv.detect.locate` fits them twice: with their neighbours' starting
spots, then with their fits). Close pairs, the most strongly coupled, stay in one piece
whenever it can hold them.
"""

from math import sqrt
from typing import NamedTuple

import numpy as np
from numba import njit

#: Detections closer than this, px, are refined together (one joint fit of their
#: spots): a spot further away puts at most 4·10⁻³ of its peak on a 5 × 5 window
#: (σ = 0.9 px), mostly absorbed by the fitted background (measured noise-free: a
#: neighbour 6 px away, even 10× brighter, moves a lone fit's centre < 10⁻⁴ px).
GROUP_DISTANCE_PX = 6.0
#: Largest group fitted jointly; longer chains are cut into pieces.
MAX_GROUP = 6
#: Link distances, px, at which a chain too long is cut, one after the other.
PIECE_DISTANCES = (5.0, 4.0, 3.0, 2.0)


class Groups(NamedTuple):
    """Groups in compressed form: group g is ``members[offsets[g]:offsets[g + 1]]`` and
    its neighbours held fixed ``near[near_offsets[g]:near_offsets[g + 1]]`` (indices
    of detections, int64 arrays)."""

    members: np.ndarray
    offsets: np.ndarray
    near: np.ndarray
    near_offsets: np.ndarray

    def subset(self, keep: np.ndarray) -> "Groups":
        """The groups selected by a boolean mask (n_groups,)."""
        members, offsets = _select(self.members, self.offsets, keep)
        near, near_offsets = _select(self.near, self.near_offsets, keep)
        return Groups(members, offsets, near, near_offsets)

    @property
    def has_near(self) -> np.ndarray:
        """(n_groups,) bool: groups with neighbours held fixed."""
        return np.diff(self.near_offsets) > 0


def _select(items: np.ndarray, offsets: np.ndarray, keep: np.ndarray) -> tuple:
    sizes = np.diff(offsets)[keep]
    rows = np.repeat(keep, np.diff(offsets))
    return items[rows], np.concatenate(([0], np.cumsum(sizes))).astype(np.int64)


@njit(cache=True)
def close_pairs(xy: np.ndarray, radius: float) -> np.ndarray:  # pragma: no cover (compiled)
    """Every pair of points at most ``radius`` apart.

    The points are sorted into square cells at least ``radius`` wide (wider where the
    points are sparse over a large extent, so that there are at most about twice as many
    cells as points), and each is compared with the points of its own cell and of the four
    neighbouring cells after it: linear in the number of points; for the 2200 detections
    of a paper-10hz image 0.14 ms, against 0.47 ms for a KD-tree's build and pair query.

    Parameters
    ----------
    xy : ndarray, shape (N, 2)
        Points, px.
    radius : float
        Largest distance of a pair, px, > 0.

    Returns
    -------
    ndarray of int64, shape (M, 2)
        Index pairs (i, j), i < j, in no particular order.
    """
    n = xy.shape[0]
    if n < 2:
        return np.empty((0, 2), np.int64)
    x0, y0 = xy[:, 0].min(), xy[:, 1].min()
    width, height = xy[:, 0].max() - x0, xy[:, 1].max() - y0
    cell = max(radius, sqrt(width * height / n), (width + height) / n)
    nx, ny = int(width / cell) + 1, int(height / cell) + 1
    where = np.empty(n, np.int64)
    start = np.zeros(nx * ny + 1, np.int64)
    for i in range(n):
        where[i] = int((xy[i, 1] - y0) / cell) * nx + int((xy[i, 0] - x0) / cell)
        start[where[i] + 1] += 1
    for c in range(nx * ny):
        start[c + 1] += start[c]
    order = np.empty(n, np.int64)
    filled = start[:-1].copy()
    for i in range(n):
        order[filled[where[i]]] = i
        filled[where[i]] += 1
    r2 = radius * radius
    pairs = np.empty((0, 2), np.int64)
    for sweep in range(2):  # count, then fill
        m = 0
        for i in range(n):
            cx, cy = where[i] % nx, where[i] // nx
            for dx, dy in ((0, 0), (1, 0), (-1, 1), (0, 1), (1, 1)):
                if not (0 <= cx + dx < nx and cy + dy < ny):
                    continue
                c = (cy + dy) * nx + cx + dx
                for t in range(start[c], start[c + 1]):
                    j = order[t]
                    if (dx == 0 and dy == 0 and j <= i) or (
                        (xy[i, 0] - xy[j, 0]) ** 2 + (xy[i, 1] - xy[j, 1]) ** 2 > r2
                    ):
                        continue
                    if sweep == 1:
                        pairs[m, 0], pairs[m, 1] = min(i, j), max(i, j)
                    m += 1
        if sweep == 0:
            pairs = np.empty((m, 2), np.int64)
    return pairs


@njit(cache=True)
def _components(n: int, pairs: np.ndarray) -> np.ndarray:  # pragma: no cover (compiled)
    """Connected-component label (n,) of each of n nodes linked by ``pairs`` (M, 2),
    labels 0, 1, … in the order of each component's lowest node (union–find: a few
    microseconds where building a sparse graph for SciPy took a third of a millisecond)."""
    root = np.arange(n)
    for m in range(pairs.shape[0]):
        a, b = pairs[m, 0], pairs[m, 1]
        while root[a] != a:
            root[a] = root[root[a]]  # path halving
            a = root[a]
        while root[b] != b:
            root[b] = root[root[b]]
            b = root[b]
        if a != b:
            root[max(a, b)] = min(a, b)  # the lower node is the root
    label = np.empty(n, np.int64)
    count = 0
    for i in range(n):
        if root[i] == i:
            label[i] = count
            count += 1
        else:
            label[i] = label[root[i]]  # root[i] < i: already labelled
    return label


def _cut(label: np.ndarray, pairs: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """Labels with every group larger than MAX_GROUP cut into pieces (module docstring)."""
    for distance in PIECE_DISTANCES:
        big = np.bincount(label)[label] > MAX_GROUP
        if not big.any():
            return label
        inner = big[pairs[:, 0]] & big[pairs[:, 1]] & (dist < distance)
        piece = _components(len(label), pairs[inner])
        label = np.where(big, label.max() + 1 + piece, label)
        label = np.unique(label, return_inverse=True)[1]
    big = np.flatnonzero(np.bincount(label)[label] > MAX_GROUP)
    if big.size:
        big = big[np.argsort(label[big], kind="stable")]
        rank = np.arange(big.size) - np.searchsorted(label[big], label[big])
        label = label.copy()
        label[big] = label.max() + 1 + label[big] * len(label) + rank // MAX_GROUP
        label = np.unique(label, return_inverse=True)[1]
    return label


def fit_groups(xy: np.ndarray, unmodelled: np.ndarray) -> Groups:
    """The groups of detections to fit jointly and their neighbours held fixed.

    Parameters
    ----------
    xy : ndarray, shape (N, 2)
        Centres of the detections, px.
    unmodelled : ndarray of bool, shape (N,)
        Detections whose light is not one Gaussian spot (saturated, on the edge, a
        blob): neither they nor a detection within :data:`GROUP_DISTANCE_PX` of them
        is fitted, since their light would bias the fit.

    Returns
    -------
    Groups
        The short chains in the order of their lowest member, then the pieces of the
        long ones; members in index order.
    """
    n = len(xy)
    pairs = close_pairs(xy, GROUP_DISTANCE_PX)
    dist = np.hypot(*(xy[pairs[:, 0]] - xy[pairs[:, 1]]).T)
    label = _cut(_components(n, pairs), pairs, dist)
    tainted = unmodelled.copy()
    tainted[pairs[unmodelled[pairs[:, 1]], 0]] = True
    tainted[pairs[unmodelled[pairs[:, 0]], 1]] = True
    fit = np.bincount(label, weights=tainted)[label] == 0
    members = np.flatnonzero(fit)
    members = members[np.argsort(label[members], kind="stable")]
    starts = np.flatnonzero(np.diff(label[members], prepend=-1))
    offsets = np.append(starts, members.size).astype(np.int64)
    group_of = np.full(n, -1, np.int64)
    group_of[members] = np.cumsum(np.diff(label[members], prepend=-1) != 0) - 1
    # Neighbours held fixed: the other end of every pair that leaves a fitted group.
    ends = np.concatenate((pairs, pairs[:, ::-1]))
    ends = ends[(group_of[ends[:, 0]] >= 0) & (label[ends[:, 0]] != label[ends[:, 1]])]
    key = np.unique(group_of[ends[:, 0]] * n + ends[:, 1])
    near = (key % n).astype(np.int64)
    near_offsets = np.searchsorted(key // n, np.arange(len(offsets))).astype(np.int64)
    return Groups(members.astype(np.int64), offsets, near, near_offsets)
