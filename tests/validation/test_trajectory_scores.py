"""TrackPoints perturbed from the truth in known ways score as perturbed, by exactly as much."""

import numpy as np
import pytest

from validation.score.trajectories import TrackPoints, TrueTrajectories, trajectory_scores

P, F = 40, 30
RADIUS = 1e-3


@pytest.fixture(scope="module")
def truth() -> TrueTrajectories:
    """P particles on smooth paths 5 mm apart at least, F frames 0.1 ms apart."""
    rng = np.random.default_rng(0)
    grid = np.stack(np.meshgrid(np.arange(8), np.arange(5), indexing="ij"), -1).reshape(-1, 2)
    x0 = np.c_[grid * 5e-3, np.zeros(P)] + rng.uniform(-5e-4, 5e-4, (P, 3))
    v0 = rng.normal(0, 0.1, (P, 3))
    a = rng.normal(0, 20, (P, 3))
    t = np.arange(F) * 1e-4
    position = x0[:, None] + v0[:, None] * t[:, None] + 0.5 * a[:, None] * t[:, None] ** 2
    velocity = v0[:, None] + a[:, None] * t[:, None]
    return TrueTrajectories(
        particle=np.repeat(np.arange(P), F),
        frame=np.tile(np.arange(F), P),
        position=position.reshape(-1, 3),
        velocity=velocity.reshape(-1, 3),
        acceleration=np.repeat(a, F, axis=0),
        observed=np.ones(P * F, dtype=bool),
    )


def _as_tracks(truth: TrueTrajectories, track=None, position=None, keep=None) -> TrackPoints:
    keep = np.ones(len(truth.frame), dtype=bool) if keep is None else keep
    track = truth.particle if track is None else track
    position = truth.position if position is None else position
    return TrackPoints(
        track[keep],
        truth.frame[keep],
        position[keep],
        truth.velocity[keep],
        truth.acceleration[keep],
    )


def test_the_truth_itself_scores_perfectly(truth):
    s = trajectory_scores(truth, _as_tracks(truth), RADIUS)
    assert s["tracked"] == 1.0 and s["ghost_tracks"] == 0.0
    assert s["fragmentation"] == 1.0 and s["mislinks"] == 0.0 and s["ghost_links"] == 0.0
    assert s["lengths"]["tracks"]["mean"] == s["lengths"]["trajectories"]["mean"] == F
    assert s["errors"]["position_um"] == {"x": 0.0, "y": 0.0, "z": 0.0}
    assert s["errors"]["acceleration_m_s2"] == {"x": 0.0, "y": 0.0, "z": 0.0}


def test_tracks_broken_in_two_give_two_segments_per_trajectory(truth):
    broken = 2 * truth.particle + (truth.frame >= F // 2)
    s = trajectory_scores(truth, _as_tracks(truth, track=broken), RADIUS)
    assert s["fragmentation"] == 2.0 and s["tracks"] == 2 * P
    assert s["lengths"]["tracks"]["mean"] == F / 2
    assert s["tracked"] == 1.0 and s["mislinks"] == 0.0


def test_swapped_ids_are_mislinks(truth):
    # Particles 2i and 2i + 1 swap tracks from the middle frame on: one jump per track.
    swapped = np.where(truth.frame >= F // 2, truth.particle ^ 1, truth.particle)
    s = trajectory_scores(truth, _as_tracks(truth, track=swapped), RADIUS)
    assert s["mislinks"] == pytest.approx(P / (P * (F - 1)))
    # Every particle has its own point in every frame: each jump could have been avoided.
    assert s["avoidable_mislinks"] == s["mislinks"]
    assert s["fragmentation"] == 2.0 and s["tracked"] == 1.0


def test_a_jump_onto_a_neighbour_after_a_merge_is_not_avoidable(truth):
    # From the middle frame on the even particles are not found (their images merged with
    # their odd neighbour's) and each even track goes on with its odd neighbour's points:
    # one jump per even track, none of them avoidable.
    middle = truth.frame >= F // 2
    keep = ~(middle & (truth.particle % 2 == 0))  # the even particles lose their points
    track = np.where(middle & (truth.particle % 2 == 1), truth.particle - 1, truth.particle)
    s = trajectory_scores(truth, _as_tracks(truth, track=track, keep=keep), RADIUS)
    links = s["links"]
    assert s["mislinks"] == pytest.approx((P // 2) / links) and s["avoidable_mislinks"] == 0.0


def test_position_noise_is_its_rms(truth):
    sigma = 20e-6
    noisy = truth.position + np.random.default_rng(1).normal(0, sigma, truth.position.shape)
    s = trajectory_scores(truth, _as_tracks(truth, position=noisy), RADIUS)
    n = len(truth.frame)
    for value in s["errors"]["position_um"].values():
        # The rms of n normal errors: σ within 4 standard errors σ/√(2n).
        assert value == pytest.approx(sigma * 1e6, abs=4 * sigma * 1e6 / np.sqrt(2 * n))
    assert s["mislinks"] == 0.0


def test_ghost_tracks_are_counted_and_pair_with_nothing(truth):
    tracks = _as_tracks(truth)
    ghosts = 10
    far = np.tile(np.arange(F), ghosts), np.repeat(np.arange(ghosts) + 1000, F)
    position = np.c_[np.full((ghosts * F, 2), 1.0), np.zeros(ghosts * F)]
    with_ghosts = TrackPoints(
        np.r_[tracks.track, far[1]],
        np.r_[tracks.frame, far[0]],
        np.r_[tracks.position, position],
    )
    s = trajectory_scores(truth, with_ghosts, RADIUS)
    assert s["ghost_tracks"] == pytest.approx(ghosts / (P + ghosts))
    assert s["tracked"] == 1.0 and s["mislinks"] == 0.0
    assert s["ghost_links"] == pytest.approx(ghosts * (F - 1) / ((P + ghosts) * (F - 1)))


def test_a_particle_out_of_view_starts_a_new_trajectory(truth):
    # Every particle unseen for frames 10–12: two trajectories each, and tracks that
    # bridge the gap (gap closing) follow each in one segment.
    seen = (truth.frame < 10) | (truth.frame > 12)
    hidden = TrueTrajectories(
        truth.particle, truth.frame, truth.position, truth.velocity, truth.acceleration, seen
    )
    s = trajectory_scores(hidden, _as_tracks(truth, keep=seen), RADIUS)
    assert s["trajectories"] == 2 * P and s["fragmentation"] == 1.0
    assert s["tracked"] == 1.0 and s["mislinks"] == 0.0


def test_untracked_frames_lower_the_tracked_fraction_not_the_segments(truth):
    keep = truth.frame % 3 != 0  # a third of the frames missed: tracks that close gaps
    s = trajectory_scores(truth, _as_tracks(truth, keep=keep), RADIUS)
    assert s["tracked"] == pytest.approx(np.mean(keep))
    assert s["fragmentation"] == 1.0 and s["mislinks"] == 0.0


def test_a_track_that_swaps_back_has_three_segments_on_each_trajectory(truth):
    middle = (truth.frame >= 10) & (truth.frame < 20)
    swapped = np.where(middle, truth.particle ^ 1, truth.particle)
    s = trajectory_scores(truth, _as_tracks(truth, track=swapped), RADIUS)
    assert s["fragmentation"] == 3.0
    assert s["mislinks"] == pytest.approx(2 * P / (P * (F - 1)))
