"""Tracks of a rendered recording put beside its truth: frames aligned, sequences joined.

A code's points are in its calibration's frame, which differs from the world by the
plate's small tilt and the traverse origin (tens of µm, a fraction of a degree): the
points of every frame are brought onto the true particles by one rigid transform
(:func:`validation.truth.matching.align_to_truth`), as ``synptv score`` does for
positions, and the transform is reported. A true particle counts (``observed``) where at
least ``min_cameras`` cameras image it.

Several recordings are scored as one: frame numbers of recording s are shifted by
s·(F + :data:`SEQUENCE_SEPARATION`) and ids made distinct, so that no track or
trajectory runs from one recording into the next.
"""

from collections.abc import Sequence

import numpy as np

from validation.score.trajectories import TrackPoints, TrueTrajectories
from validation.truth.matching import align_to_truth, rotation_angle_deg
from validation.truth.recording_truth import RecordingTruth

#: Frames left between joined recordings (more than any gap a tracker closes).
SEQUENCE_SEPARATION = 1000


def true_trajectories(truth: RecordingTruth, min_cameras: int) -> TrueTrajectories:
    """A recording's truth as :class:`TrueTrajectories` (observed: imaged by at least
    ``min_cameras`` cameras)."""
    return TrueTrajectories(
        particle=truth.particle,
        frame=truth.frame,
        position=truth.position,
        velocity=truth.velocity,
        acceleration=truth.acceleration,
        observed=truth.imaged_by(min_cameras),
    )


def align_tracks(
    tracks: TrackPoints, truth: RecordingTruth
) -> tuple[TrackPoints, np.ndarray, np.ndarray]:
    """The tracks moved onto the truth by the rigid transform of their points.

    Returns
    -------
    (TrackPoints, ndarray (3, 3), ndarray (3,))
        The moved tracks (positions, and velocities and accelerations rotated), R and t
        (X_world = R X + t).
    """
    frames = np.unique(tracks.frame)

    def pairs():
        for f in frames:
            yield tracks.position[tracks.frame == f], truth.position[truth.frame == f]

    rotation, translation = align_to_truth(pairs)

    def rotated(v):
        return None if v is None else v @ rotation.T

    moved = TrackPoints(
        track=tracks.track,
        frame=tracks.frame,
        position=tracks.position @ rotation.T + translation,
        velocity=rotated(tracks.velocity),
        acceleration=rotated(tracks.acceleration),
    )
    return moved, rotation, translation


def alignment_dict(rotation: np.ndarray, translation: np.ndarray) -> dict:
    """The transform as JSON: its angle, degrees, and translation, µm."""
    return {
        "rotation_deg": rotation_angle_deg(rotation),
        "translation_um": (np.asarray(translation) * 1e6).tolist(),
    }


def join_sequences(
    parts: Sequence[tuple[TrackPoints, TrueTrajectories]], frames: int
) -> tuple[TrackPoints, TrueTrajectories]:
    """Recordings of ``frames`` frames each scored as one (module docstring)."""
    shift = frames + SEQUENCE_SEPARATION
    track_offset = particle_offset = 0
    joined_tracks, joined_truth = [], []
    for s, (tracks, truth) in enumerate(parts):
        joined_tracks.append((tracks.track + track_offset, tracks.frame + s * shift, tracks))
        joined_truth.append((truth.particle + particle_offset, truth.frame + s * shift, truth))
        track_offset += int(tracks.track.max(initial=-1)) + 1
        particle_offset += int(truth.particle.max(initial=-1)) + 1

    def stack(items, name):
        values = [getattr(item[2], name) for item in items]
        return None if any(v is None for v in values) else np.concatenate(values)

    tracks = TrackPoints(
        track=np.concatenate([t[0] for t in joined_tracks]),
        frame=np.concatenate([t[1] for t in joined_tracks]),
        position=stack(joined_tracks, "position"),
        velocity=stack(joined_tracks, "velocity"),
        acceleration=stack(joined_tracks, "acceleration"),
    )
    truth = TrueTrajectories(
        particle=np.concatenate([t[0] for t in joined_truth]),
        frame=np.concatenate([t[1] for t in joined_truth]),
        position=stack(joined_truth, "position"),
        velocity=stack(joined_truth, "velocity"),
        acceleration=stack(joined_truth, "acceleration"),
        observed=stack(joined_truth, "observed"),
    )
    return tracks, truth
