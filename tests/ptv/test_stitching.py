"""Joining tracks broken on a false point (``ptv.tracking.stitching``) against known paths.

A particle moving at constant velocity is missed in one frame, and a false point lies
within the tracker's radius of its prediction there: the frame-by-frame tracker takes
it, misses the particle in the next frame and leaves the trajectory in two tracks. The
join must give back one track of the particle's points, the false point alone.
"""

import numpy as np
import pytest

from ptv.tracking.linking import Tracks, track_frames
from ptv.tracking.stitching import stitch_tracks

#: Frames, frame of the false point, velocity per frame (m), predicted radius (m).
FRAMES = 12
MISSED = 6
VELOCITY = np.array([40e-6, -10e-6, 5e-6])
RADIUS = 30e-6


def frames_with_false_point(offset: np.ndarray, *, others: int = 0) -> list[np.ndarray]:
    """Frames of one particle from the origin at ``VELOCITY`` per frame, replaced at
    frame ``MISSED`` by a false point ``offset`` from it; ``others`` particles far away
    (5 mm apart) moving alike, never missed."""
    frames = []
    for f in range(FRAMES):
        x = f * VELOCITY
        point = x + offset if f == MISSED else x
        far = [x + (i + 1) * np.array([5e-3, 0.0, 0.0]) for i in range(others)]
        frames.append(np.array([point, *far]))
    return frames


def tracked(frames) -> Tracks:
    return track_frames(frames, radius=200e-6, predicted_radius=RADIUS, gap=2)


def test_a_false_point_breaks_the_track_and_the_join_mends_it():
    frames = frames_with_false_point(np.array([25e-6, 0.0, 0.0]), others=2)
    before = tracked(frames)
    # The particle (row 0 of each frame) is in two tracks of two points or more.
    ours = before.track[before.index == 0]
    assert len(np.unique(ours)) == 2
    after, joins = stitch_tracks(before, predicted_radius=RADIUS, gap=2)
    assert joins == 1
    mine = after.index == 0
    frame, track = after.frame[mine], after.track[mine]
    # One track of every true point; the false point on its own.
    whole = track[frame != MISSED]
    assert len(np.unique(whole)) == 1
    alone = track[frame == MISSED][0]
    assert alone != whole[0] and np.count_nonzero(after.track == alone) == 1
    # The far particles are untouched: one whole track each.
    for row in (1, 2):
        assert len(np.unique(after.track[after.index == row])) == 1
    # Invariants of Tracks: ids 0 … T − 1 in the order they start, every point once.
    assert after.n_tracks == before.n_tracks
    starts = np.flatnonzero(np.append(True, np.diff(after.track) != 0))
    first = after.frame[starts] * 10 + after.index[starts]
    assert np.all(np.diff(first) > 0)
    assert sorted(zip(after.frame, after.index, strict=True)) == sorted(
        zip(before.frame, before.index, strict=True)
    )


def test_no_join_beyond_the_radius():
    # The particle comes back 5 radii off the prediction from the earlier track (its
    # second half displaced): nothing to join.
    frames = frames_with_false_point(np.array([25e-6, 0.0, 0.0]))
    for f in range(MISSED + 1, FRAMES):
        frames[f] = frames[f] + np.array([0.0, 5 * RADIUS * 3, 0.0])
    before = tracked(frames)
    after, joins = stitch_tracks(before, predicted_radius=RADIUS, gap=2)
    assert joins == 0
    np.testing.assert_array_equal(after.track, before.track)


def test_whole_tracks_are_left_as_they_are():
    frames = [np.array([f * VELOCITY]) for f in range(FRAMES)]
    before = tracked(frames)
    assert before.n_tracks == 1
    after, joins = stitch_tracks(before, predicted_radius=RADIUS, gap=2)
    assert joins == 0 and after.n_tracks == 1


@pytest.mark.parametrize("bad", [0.0, -1.0, np.nan])
def test_a_radius_must_be_positive(bad):
    with pytest.raises(ValueError, match="predicted_radius"):
        stitch_tracks(tracked([np.zeros((1, 3))] * 3), predicted_radius=bad, gap=2)
