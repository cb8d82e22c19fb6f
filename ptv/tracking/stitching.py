"""Joining the pieces of a trajectory that the frame-by-frame tracker left apart.

:func:`ptv.tracking.linking.track_frames` decides each frame on its own. When a
particle is missed in a frame and a false point (a ghost match, or a point displaced by
an overlapping particle image) lies within its track's search radius there, the track
takes that point: its velocity is then wrong, the next prediction misses the particle,
the track ends on the false point and the particle starts a new track a frame later.
On the rendered tr recording (2000 tracers, paper-stereo) this is half of all the
breaks of the true trajectories.

:func:`stitch_tracks` looks at more than one frame: a track A whose last ``k`` points
(k = 1 … ``drop``) are left out is continued, from its point before them and the
velocity of its two points before that, ``n`` frames ahead, where another track B
starts; B's first point must lie within the constant-velocity search radius of that
prediction, scaled for n frames as the tracker scales it across a gap
(:func:`ptv.tracking.linking.predicted_radii`), with n − 1 ≤ ``gap`` frames between (the
k left out among them: a join bridges no more than the tracker would; measured on the
rendered tr recording, the joins across more frames were four in five wrong).
The joins are chosen one-to-one at the least total cost (d / r)², plus 0.01 per point
left out (so that leaving out fewer points wins a tie); A's points left out become
tracks of one point, and chains A → B → C are joined whole.
"""

import numpy as np
from scipy.spatial import cKDTree

from ptv._assign import assign
from ptv.tracking.linking import Tracks, predicted_radii

__all__ = ["stitch_tracks"]

#: Cost per point left out of the earlier track of a join.
DROP_COST = 0.01


def _candidates(tracks: Tracks, radii: tuple[float, float], gap: int, drop: int):
    """Every join (A, B, cost, points of A left out) within its radius."""
    t, f, x = tracks.track, tracks.frame, tracks.positions
    count = tracks.n_tracks
    start = np.searchsorted(t, np.arange(count))
    end = np.append(start[1:], len(t))
    first_frame, first_x, last_frame = f[start], x[start], f[end - 1]
    by_frame = {int(fr): np.flatnonzero(first_frame == fr) for fr in np.unique(first_frame)}
    trees = {fr: cKDTree(first_x[rows]) for fr, rows in by_frame.items()}
    found = []
    for k in range(1, drop + 1):
        a = np.flatnonzero(end - start >= k + 2)
        anchor = end[a] - 1 - k
        velocity = (x[anchor] - x[anchor - 1]) / (f[anchor] - f[anchor - 1])[:, None]
        for n in range(k + 1, gap + 2):
            predicted = x[anchor] + n * velocity
            at = f[anchor] + n
            radius = float(predicted_radii(n, *radii))
            for fr in np.unique(at):
                if int(fr) not in trees:
                    continue
                rows = by_frame[int(fr)]
                for q in np.flatnonzero(at == fr):
                    near = rows[trees[int(fr)].query_ball_point(predicted[q], radius)]
                    near = near[(near != a[q]) & (last_frame[a[q]] < fr)]
                    d = np.linalg.norm(first_x[near] - predicted[q], axis=1)
                    found += [
                        (a[q], b, (dist / radius) ** 2 + DROP_COST * k, k)
                        for b, dist in zip(near, d, strict=True)
                    ]
    return found, end


def stitch_tracks(
    tracks: Tracks,
    *,
    predicted_radius: float,
    predicted_noise: float = 0.0,
    gap: int,
    drop: int = 1,
) -> tuple[Tracks, int]:
    """Join tracks that continue one another once their last points are left out.

    Parameters
    ----------
    tracks : Tracks
        Of :func:`ptv.tracking.linking.track_frames`.
    predicted_radius, predicted_noise : float
        The tracker's constant-velocity search radius one frame ahead and its part from
        the position noise, m (:func:`ptv.tracking.linking.predicted_radii`).
    gap : int
        Frames a track may miss (the tracker's ``gap``).
    drop : int
        Most points of the earlier track left out of a join (>= 1).

    Returns
    -------
    (Tracks, int)
        The tracks, renumbered in the order they start, and the number of joins made.
    """
    if not (np.isfinite(predicted_radius) and predicted_radius > 0):
        raise ValueError(f"predicted_radius must be finite and > 0 m, got {predicted_radius!r}")
    if not isinstance(drop, int) or drop < 1:
        raise ValueError(f"drop must be an integer >= 1, got {drop!r}")
    found, end = _candidates(tracks, (predicted_radius, predicted_noise), gap, drop)
    if not found:
        return tracks, 0
    a, b, cost, k = (np.asarray(v) for v in zip(*found, strict=True))
    order = np.lexsort((cost, b, a))  # the cheapest of the same (A, B) first
    a, b, cost, k = a[order], b[order], cost[order], k[order]
    first = np.append(True, (a[1:] != a[:-1]) | (b[1:] != b[:-1]))
    a, b, cost, k = a[first], b[first], cost[first], k[first]
    count = tracks.n_tracks
    chosen = assign(a, b, cost, (count, count))
    label = tracks.track.copy()
    left_out = np.concatenate([np.arange(end[a[c]] - k[c], end[a[c]]) for c in chosen])
    label[left_out] = count + np.arange(len(left_out))
    parent = np.arange(count + len(left_out))
    parent[b[chosen]] = a[chosen]
    while True:  # every track to the first of its chain
        grand = parent[parent]
        if np.array_equal(grand, parent):
            break
        parent = grand
    return _renumbered(tracks, parent[label]), len(chosen)


def _renumbered(tracks: Tracks, label: np.ndarray) -> Tracks:
    """Tracks of the given labels, numbered in the order they start (frame, then row)."""
    order = np.lexsort((tracks.frame, label))
    label, frame = label[order], tracks.frame[order]
    index, positions = tracks.index[order], tracks.positions[order]
    new = np.append(True, label[1:] != label[:-1])
    starts = np.flatnonzero(new)
    rank = np.empty(len(starts), dtype=np.int64)
    rank[np.lexsort((index[starts], frame[starts]))] = np.arange(len(starts))
    track = rank[np.cumsum(new) - 1]
    order = np.lexsort((frame, track))
    return Tracks(track[order], frame[order], index[order], positions[order], tracks.n_frames)
