"""Time-resolved tracks scored against the true trajectories.

Any code's tracks (:class:`TrackPoints`: track id, frame and position of every point, and the
velocity and acceleration of a track fit where the code gives them) are put beside the
truth of the recording (:class:`TrueTrajectories`: every particle's position, velocity
and acceleration at every frame, and whether enough cameras image it to be found).

In every frame the track points are paired one-to-one with the observed particles
within ``radius`` (:func:`validation.truth.matching.assign_one_to_one`, closest pairs
first); a point left without a particle is a ghost point. Then, with a *true
trajectory* a particle's run of consecutive observed frames (a particle that leaves the
sheet and comes back starts a new one) and a *link* two consecutive points of a track:

- ``tracked``: the fraction of the observed particle-frames paired with a point of a
  track of at least two points;
- ``ghost_tracks``: the fraction of the tracks of which more than half the points are
  ghost points;
- ``lengths``: the points per track and the observed frames per true trajectory, as
  histograms on the same bins, and their means;
- ``fragmentation``: per true trajectory that is tracked at all, the number of
  segments, runs of its tracked frames that one track follows (a change of track starts
  a new one; frames no track pairs with it do not, so that a track that closes a gap
  stays one segment); 1 is a whole trajectory in one track;
- ``mislinks``: the fraction of the links whose two ends are paired with different
  particles (a track that jumps to another particle); links with a ghost end are counted
  apart (``ghost_links``). ``avoidable_mislinks`` counts only the jumps whose first
  particle has a point of its own (paired with it) in the second frame: the code had
  that point and linked elsewhere. The others follow a particle whose image merged with
  a neighbour's into one point (two particles a fraction of a pixel apart), which the
  pairing gives to whichever is nearer: no tracker can tell them apart;
- ``errors``: rms per component of position, and of velocity and acceleration where the
  tracks give them, over the points paired with a particle, in µm, mm/s and m/s² (a
  point a fit left out, NaN, counts for its position only).
"""

from dataclasses import dataclass

import numpy as np

from validation.truth.matching import assign_one_to_one

#: Fewest points of a track whose points count as tracked.
MIN_TRACK_POINTS = 2
#: Bins of the length histograms: points per track or frames per trajectory.
LENGTH_EDGES = np.array([1, 2, 3, 5, 10, 20, 50, 100, 200, 500, 1000, 10**9])


@dataclass(frozen=True, eq=False)
class TrueTrajectories:
    """The truth of a recording, one row per particle and frame.

    Attributes
    ----------
    particle, frame : ndarray of int, shape (N,)
        Particle id and frame number.
    position, velocity, acceleration : ndarray, shape (N, 3)
        m, m/s, m/s².
    observed : ndarray of bool, shape (N,)
        Imaged by enough cameras to be found (only these count).

    Examples
    --------
    A rendered recording's truth gives it through
    ``validation.score.recorded_tracks.true_trajectories(
    validation.truth.recording_truth.read_recording_truth(folder), min_cameras)``.
    Here, the exact trajectories of a recording of 10 frames at 2 kHz in a
    20 × 20 × 2 mm slab, every particle-frame observed:

    >>> import numpy as np
    >>> import simulator, validation
    >>> preset = simulator.flow_preset("lem-10hz")
    >>> flow = simulator.KSFlow(simulator.PopeSpectrum(preset.parameters), n_modes=50)
    >>> slab = simulator.Box((0.02, 0.02, 0.002))  # m
    >>> recorded = simulator.follow_recording(flow, 2000.0, 10, particles=50, region=slab,
    ...                                       rng=0)
    >>> truth = validation.TrueTrajectories(
    ...     recorded.particle, recorded.frame, recorded.position, recorded.velocity,
    ...     recorded.acceleration, observed=np.ones(len(recorded.frame), dtype=bool))
    >>> truth.position.shape, len(np.unique(truth.particle))  # (N, 3), m; particles
    ((523, 3), 62)
    """

    particle: np.ndarray
    frame: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    observed: np.ndarray


@dataclass(frozen=True, eq=False)
class TrackPoints:
    """A code's tracks, one row per point.

    Attributes
    ----------
    track, frame : ndarray of int, shape (M,)
        Track id and frame number; (track, frame) unique.
    position : ndarray, shape (M, 3)
        m.
    velocity, acceleration : ndarray, shape (M, 3), or None
        Of a track fit, m/s and m/s², where the code gives them.

    Examples
    --------
    Two tracks of three and two points (:func:`validation.score.track_file.read_tracks`
    reads them from a CSV file):

    >>> import numpy as np
    >>> import validation
    >>> tracks = validation.TrackPoints(
    ...     track=np.array([0, 0, 0, 1, 1]), frame=np.array([0, 1, 2, 0, 1]),
    ...     position=np.zeros((5, 3)))  # m
    >>> np.unique(tracks.track, return_counts=True)[1]  # points per track
    array([3, 2])
    >>> tracks.velocity is None  # no track fit given
    True
    """

    track: np.ndarray
    frame: np.ndarray
    position: np.ndarray
    velocity: np.ndarray | None = None
    acceleration: np.ndarray | None = None


def pair_points(truth: TrueTrajectories, tracks: TrackPoints, radius: float) -> np.ndarray:
    """The truth row each track point is paired with in its frame, −1 for a ghost point.

    Parameters
    ----------
    truth : TrueTrajectories
    tracks : TrackPoints
    radius : float
        Largest distance of a pair, m.

    Returns
    -------
    ndarray of int, shape (M,)
    """
    row = np.full(len(tracks.frame), -1, dtype=np.int64)
    observed = np.flatnonzero(truth.observed)
    for f in np.unique(tracks.frame):
        points = np.flatnonzero(tracks.frame == f)
        here = observed[truth.frame[observed] == f]
        partner = assign_one_to_one(tracks.position[points], truth.position[here], radius)
        row[points[partner >= 0]] = here[partner[partner >= 0]]
    return row


def _runs(ids: np.ndarray, frames: np.ndarray) -> np.ndarray:
    """Run index of each row, rows sorted by (id, frame): a new run starts at a new id
    or a frame gap."""
    new = np.ones(len(ids), dtype=bool)
    new[1:] = (ids[1:] != ids[:-1]) | (frames[1:] != frames[:-1] + 1)
    return np.cumsum(new) - 1


def _histogram(lengths: np.ndarray) -> dict:
    counts, _ = np.histogram(lengths, bins=LENGTH_EDGES)
    return {
        "edges": [int(e) for e in LENGTH_EDGES[:-1]],
        "counts": [int(c) for c in counts],
        "mean": float(np.mean(lengths)) if len(lengths) else None,
    }


def _rms(error: np.ndarray, scale: float) -> dict | None:
    if not len(error):
        return None
    rms = np.sqrt(np.mean(error**2, axis=0)) * scale
    return {axis: float(v) for axis, v in zip("xyz", rms, strict=True)}


def _trajectories(truth: TrueTrajectories) -> tuple[np.ndarray, np.ndarray]:
    """The true trajectory of every truth row (−1 where not observed), and the observed
    rows sorted by particle, then frame."""
    observed = np.flatnonzero(truth.observed)
    obs = observed[np.lexsort((truth.frame[observed], truth.particle[observed]))]
    trajectory = np.full(len(truth.frame), -1, dtype=np.int64)
    trajectory[obs] = _runs(truth.particle[obs], truth.frame[obs])
    return trajectory, obs


def _segments(trajectory, obs, row, track, counted) -> np.ndarray:
    """Segments per trajectory: its observed rows paired with a counted track point, by
    frame; a new segment where the trajectory or the track changes."""
    track_of_row = np.full(len(trajectory), -1, dtype=np.int64)
    track_of_row[row[counted]] = track[counted]
    covered = obs[track_of_row[obs] >= 0]
    starts = np.ones(len(covered), dtype=bool)
    starts[1:] = (trajectory[covered[1:]] != trajectory[covered[:-1]]) | (
        track_of_row[covered[1:]] != track_of_row[covered[:-1]]
    )
    return np.bincount(trajectory[covered][starts], minlength=int(trajectory.max()) + 1)


def _links(truth: TrueTrajectories, tracks: TrackPoints, row: np.ndarray) -> dict:
    """Links, the fraction that jump to another particle (and of those, the fraction
    whose first particle had a point of its own in the second frame) and the fraction
    with a ghost end."""
    order = np.lexsort((tracks.frame, tracks.track))
    same = tracks.track[order][1:] == tracks.track[order][:-1]
    a, b = row[order][:-1][same], row[order][1:][same]
    frame_b = tracks.frame[order][1:][same]
    both = (a >= 0) & (b >= 0)
    first = truth.particle[np.maximum(a, 0)]
    jumps = both & (first != truth.particle[np.maximum(b, 0)])
    found = row[row >= 0]
    stride = int(truth.frame.max()) + 1
    seen = np.isin(first * stride + frame_b, truth.particle[found] * stride + truth.frame[found])
    avoidable = jumps & seen
    return {
        "links": int(same.sum()),
        "mislinks": float(jumps.sum() / both.sum()) if both.any() else None,
        "avoidable_mislinks": float(avoidable.sum() / both.sum()) if both.any() else None,
        "ghost_links": float(np.mean(~both)) if same.any() else None,
    }


def _errors(truth: TrueTrajectories, tracks: TrackPoints, row: np.ndarray) -> dict:
    """rms per component over the paired points: µm, mm/s, m/s²."""
    good = row >= 0
    errors = {"position_um": _rms(tracks.position[good] - truth.position[row[good]], 1e6)}
    for key, given, true, scale in (
        ("velocity_mm_s", tracks.velocity, truth.velocity, 1e3),
        ("acceleration_m_s2", tracks.acceleration, truth.acceleration, 1.0),
    ):
        if given is not None:  # points a fit left out (NaN) are not counted
            fitted = good & np.isfinite(given).all(axis=1)
            errors[key] = _rms(given[fitted] - true[row[fitted]], scale)
    return errors


def trajectory_scores(truth: TrueTrajectories, tracks: TrackPoints, radius: float) -> dict:
    """The scores of the module docstring.

    Parameters
    ----------
    truth : TrueTrajectories
        Every particle at every frame, and whether it is observed.
    tracks : TrackPoints
        The code's tracks, in the truth's world frame.
    radius : float
        Largest distance between a point and the particle it is paired with, m.

    Returns
    -------
    dict
        JSON-able: ``tracked``, ``ghost_tracks``, ``lengths`` (``tracks``,
        ``trajectories``), ``fragmentation``, ``mislinks``, ``ghost_links``, ``errors``
        and the counts they come from.

    Examples
    --------
    The exact trajectories of a recording of 10 frames at 2 kHz, and tracks of a code
    that follows every particle with 10 µm of noise but breaks each track in two at
    frame 5:

    >>> import numpy as np
    >>> import simulator, validation
    >>> preset = simulator.flow_preset("lem-10hz")
    >>> flow = simulator.KSFlow(simulator.PopeSpectrum(preset.parameters), n_modes=50)
    >>> slab = simulator.Box((0.02, 0.02, 0.002))  # m
    >>> recorded = simulator.follow_recording(flow, 2000.0, 10, particles=50, region=slab,
    ...                                       rng=0)
    >>> truth = validation.TrueTrajectories(
    ...     recorded.particle, recorded.frame, recorded.position, recorded.velocity,
    ...     recorded.acceleration, observed=np.ones(len(recorded.frame), dtype=bool))
    >>> broken = recorded.particle + np.where(recorded.frame < 5, 0, 1000)  # track ids
    >>> noise = np.random.default_rng(1).normal(0.0, 10e-6, recorded.position.shape)  # m
    >>> tracks = validation.TrackPoints(broken, recorded.frame, recorded.position + noise)
    >>> scores = validation.trajectory_scores(truth, tracks, radius=1e-4)
    >>> round(scores["tracked"], 3), round(scores["fragmentation"], 2), scores["mislinks"]
    (0.989, 1.76, 0.0)
    >>> {axis: round(rms, 1) for axis, rms in scores["errors"]["position_um"].items()}  # µm
    {'x': 10.0, 'y': 9.9, 'z': 10.4}
    """
    row = pair_points(truth, tracks, radius)
    _, track_index = np.unique(tracks.track, return_inverse=True)
    points = np.bincount(track_index)
    ghost_points = np.bincount(track_index, weights=row < 0)
    counted = (row >= 0) & (points >= MIN_TRACK_POINTS)[track_index]
    trajectory, obs = _trajectories(truth)
    segments = _segments(trajectory, obs, row, tracks.track, counted)
    touched = segments > 0
    return {
        "radius_m": float(radius),
        "observed_particle_frames": len(obs),
        "tracked": len(np.unique(row[counted])) / len(obs) if len(obs) else None,
        "tracks": len(points),
        "ghost_tracks": float(np.mean(ghost_points > points / 2)) if len(points) else None,
        "trajectories": len(segments),
        "lengths": {
            "tracks": _histogram(points),
            "trajectories": _histogram(np.bincount(trajectory[obs], minlength=len(segments))),
        },
        "fragmentation": float(np.mean(segments[touched])) if touched.any() else None,
        **_links(truth, tracks, row),
        "errors": _errors(truth, tracks, row),
    }
