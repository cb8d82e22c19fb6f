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

from typing import NamedTuple

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

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


def _components(n: int, pairs: np.ndarray) -> np.ndarray:
    """Connected-component label of each of n nodes linked by ``pairs`` (M, 2)."""
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    return connected_components(graph, directed=False)[1]


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
    pairs = cKDTree(xy).query_pairs(GROUP_DISTANCE_PX, output_type="ndarray")
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
