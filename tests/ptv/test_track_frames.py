"""Time-resolved tracks (``ptv.tracking.linking.track_frames``) against trajectories known exactly.

The trajectories are smooth random curves: a mean velocity plus, per component, three
sinusoids of random amplitude, frequency and phase, so that every particle's position,
velocity and acceleration are known at every time. Particles are seeded in a box larger
than the observed one, so they enter and leave it during the sequence; each frame holds
the particles inside the observed box, shuffled, with Gaussian position noise.
"""

import itertools

import numpy as np
import pytest

from ptv.tracking.linking import Tracks, link, search_radius, track_frames

#: Observed box (half sizes, m): 20 × 20 × 4 mm.
OBSERVED = np.array([10e-3, 10e-3, 2e-3])
#: Particles seeded per m³ (0.2 per mm³: a mean spacing n^(-1/3) of 1.7 mm).
DENSITY = 0.2e9
#: Velocity scale, one component, m/s, and the mean velocity, m/s.
U_RMS = 0.1
MEAN_VELOCITY = np.array([0.05, 0.0, 0.0])
#: Position noise, one component, m.
SIGMA = 10e-6


def smooth_paths(times, rng, *, u_rms=U_RMS, hertz=(10, 40), margin=2e-3):
    """Positions (T, P, 3), m, and accelerations (T, P, 3), m/s², of particles seeded
    uniformly in the observed box grown by ``margin`` plus the distance they travel:
    velocity u_rms per component, frequencies uniform in ``hertz``."""
    reach = margin + 4 * u_rms * times[-1] + np.abs(MEAN_VELOCITY) * times[-1]
    half = OBSERVED + reach
    count = rng.poisson(DENSITY * np.prod(2 * half))
    start = rng.uniform(-half, half, size=(count, 3)) - MEAN_VELOCITY * times[-1] / 2
    # Three modes per component; their amplitudes give u_rms per component.
    omega = 2 * np.pi * rng.uniform(*hertz, size=(1, count, 3, 3))
    phase = rng.uniform(0, 2 * np.pi, size=(1, count, 3, 3))
    amplitude = u_rms * np.sqrt(2 / 3) / omega
    t = times[:, None, None, None]
    wave = amplitude * (np.sin(omega * t + phase) - np.sin(phase))
    positions = start + MEAN_VELOCITY * times[:, None, None] + wave.sum(axis=-1)
    acceleration = -(amplitude * omega**2 * np.sin(omega * t + phase)).sum(axis=-1)
    return positions, acceleration


def observe(positions, rng):
    """Noisy, shuffled frames of the particles inside the observed box, and their ids."""
    frames, ids = [], []
    for x in positions:
        inside = rng.permutation(np.flatnonzero(np.all(np.abs(x) <= OBSERVED, axis=1)))
        frames.append(x[inside] + rng.normal(scale=SIGMA, size=(len(inside), 3)))
        ids.append(inside)
    return frames, ids


def truth_of(tracks: Tracks, ids) -> np.ndarray:
    """The true particle of every tracked point, shape (K,)."""
    return np.concatenate(ids)[np.cumsum([0, *map(len, ids)])[tracks.frame] + tracks.index]


def scores(tracks: Tracks, ids):
    """(wrong links / links made, true links found / true links, particles seen in every
    frame recovered as one pure full-length track / such particles)."""
    particle = truth_of(tracks, ids)
    same = tracks.track[1:] == tracks.track[:-1]
    wrong = same & (particle[1:] != particle[:-1])
    true_links = sum(len(np.intersect1d(a, b)) for a, b in itertools.pairwise(ids))
    everywhere = set(ids[0]).intersection(*map(set, ids[1:]))
    impure = set(tracks.track[1:][wrong].tolist())
    whole = {
        int(particle[tracks.track == t][0])
        for t in np.flatnonzero(tracks.lengths == tracks.n_frames)
        if t not in impure
    }
    return (
        wrong.sum() / same.sum(),
        (same.sum() - wrong.sum()) / true_links,
        len(whole & everywhere) / len(everywhere),
    )


def radii(tau, acceleration, u_rms=U_RMS):
    """The first link's radius (5 u' τ + 5σ) and the constant-velocity one (the largest
    acceleration times τ², plus 5√6 σ: five times the noise of the prediction's miss)."""
    largest = np.abs(acceleration).max()
    return search_radius(tau, u_rms=u_rms, sigma_b=SIGMA), largest * tau**2 + 5 * 6**0.5 * SIGMA


@pytest.fixture(scope="module")
def sequence():
    tau = 1e-3
    times = tau * np.arange(12)
    positions, acceleration = smooth_paths(times, np.random.default_rng(0))
    frames, ids = observe(positions, np.random.default_rng(1))
    return tau, frames, ids, acceleration


def test_tracks_recover_the_true_identities(sequence):
    # u'τ = 0.1 mm per component (0.17 mm in 3-D) against a spacing of 1.7 mm: a first
    # link goes wrong only when another particle is nearer its prediction than its own
    # partner, which the n·(4/3)π d³ = 0.2 · 4.19 · 0.17³ ≈ 0.4 % of particles within
    # d = 0.17 mm bounds; a longer track misses its prediction by aτ² + √6σ ≈ 40 µm,
    # with 5e-5 foreign particles that close. Most links are of longer tracks, so ≤ 1 %
    # wrong leaves a margin of several times the expected count.
    tau, frames, ids, acceleration = sequence
    radius, predicted_radius = radii(tau, acceleration)
    tracks = track_frames(frames, radius=radius, predicted_radius=predicted_radius)
    wrong, found, whole = scores(tracks, ids)
    assert wrong <= 0.01
    assert found >= 0.99
    assert whole >= 0.98
    # Every point is in exactly one track, tracks are sorted and their frames consecutive.
    assert len(tracks) == sum(map(len, frames))
    assert sorted(zip(tracks.frame.tolist(), tracks.index.tolist(), strict=True)) == [
        (f, i) for f, x in enumerate(frames) for i in range(len(x))
    ]
    assert np.array_equal(
        tracks.positions,
        np.concatenate(frames)[np.cumsum([0, *map(len, frames)])[tracks.frame] + tracks.index],
    )
    assert tracks.links == len(tracks) - tracks.n_tracks == sum(tracks.lengths - 1)


def test_particles_entering_and_leaving_start_and_end_tracks(sequence):
    tau, frames, ids, acceleration = sequence
    tracks = track_frames(frames, radius=radii(tau, acceleration)[0])
    particle = truth_of(tracks, ids)
    # The true segments: maximal runs of consecutive frames a particle is observed in.
    seen = np.zeros((len(frames), max(map(np.max, ids)) + 1), dtype=bool)
    for f, i in enumerate(ids):
        seen[f, i] = True
    starts = seen & ~np.vstack([np.zeros_like(seen[:1]), seen[:-1]])
    entering = np.flatnonzero(starts[1:].any(axis=0))
    assert len(entering) > 20 and (~seen[-1]).sum() > 20  # some come in, some go out
    assert abs(tracks.n_tracks - starts.sum()) <= 0.02 * starts.sum()
    # A particle that enters at frame f starts a track at f.
    first = np.concatenate([[True], tracks.track[1:] != tracks.track[:-1]])
    started = set(zip(particle[first].tolist(), tracks.frame[first].tolist(), strict=True))
    expected = {(int(p), int(np.argmax(seen[:, p]))) for p in entering if not seen[0, p]}
    assert len(expected & started) >= 0.98 * len(expected)


def fast_sequence(seed: int):
    """Ten frames 1 ms apart of particles four times faster on slower curves (2.5–10 Hz):
    (frames, ids, first-link radius, constant-velocity radius)."""
    tau, u_rms = 1e-3, 4 * U_RMS
    rng = np.random.default_rng(seed)
    positions, acceleration = smooth_paths(tau * np.arange(10), rng, u_rms=u_rms, hertz=(2.5, 10))
    frames, ids = observe(positions, rng)
    return frames, ids, *radii(tau, acceleration, u_rms)


def test_constant_velocity_prediction_beats_frame_to_frame_links():
    # Four times faster, on slower curves (2.5-10 Hz): u'τ = 0.4 mm per component, and a
    # first link searches 2 mm, more than the mean spacing: such links are often wrong,
    # as are those of each pair of frames linked on its own (ptv.tracking.linking.link, the same
    # radius). Once a track has two points, its constant-velocity prediction misses by
    # aτ² + √6σ, inside r_p = 0.15 mm here, with n·(4/3)π r_p³ ≈ 0.3 % of particles
    # that close to it: those links are almost all right.
    frames, ids, radius, predicted_radius = fast_sequence(2)
    assert radius > DENSITY ** (-1 / 3) and predicted_radius < 0.2e-3
    tracks = track_frames(frames, radius=radius, predicted_radius=predicted_radius)
    particle = truth_of(tracks, ids)
    same = tracks.track[1:] == tracks.track[:-1]
    wrong = same & (particle[1:] != particle[:-1])
    # Links whose track already had two points: not the first two rows of a track.
    row = np.arange(len(tracks)) - np.searchsorted(tracks.track, tracks.track)
    predicted = same & (row[1:] >= 2)
    assert predicted.sum() > 0.5 * same.sum()
    assert wrong[predicted].mean() <= 0.005
    pairs = [link(a, b, radius=radius) for a, b in itertools.pairwise(frames)]
    pair_wrong = sum(
        np.sum(ids[f][p.index_a] != ids[f + 1][p.index_b]) for f, p in enumerate(pairs)
    ) / sum(map(len, pairs))
    assert pair_wrong > 0.1
    assert wrong.sum() / same.sum() < pair_wrong / 2


def test_the_look_ahead_corrects_most_wrong_first_links():
    # The fast set-up above. A first link searches 2 mm: another particle is nearer than
    # its own partner (0.7 mm off in 3-D) for n·(4/3)π·0.7³ mm³ ≈ 0.3 of them, and
    # about a fifth of the first links go wrong. With the look-ahead, a wrong candidate
    # must also be continued by a point within r_p = 0.15 mm of where it leads, which
    # n·(4/3)π r_p³ ≈ 0.3 % of them are: where the particle is seen two frames on (so
    # that its own candidate has its continuation), a few per cent of wrong first links
    # are left (the rest follow from other tracks' choices), a fifth of those without.
    frames, ids, radius, predicted_radius = fast_sequence(3)
    wrong_first = {}
    for lookahead in (False, True):
        tracks = track_frames(
            frames, radius=radius, predicted_radius=predicted_radius, lookahead=lookahead
        )
        particle = truth_of(tracks, ids)
        same = tracks.track[1:] == tracks.track[:-1]
        wrong = same & (particle[1:] != particle[:-1])
        second = same & (
            np.arange(1, len(tracks)) - np.searchsorted(tracks.track, tracks.track[1:]) == 1
        )
        frame, first_particle = tracks.frame[:-1], particle[:-1]
        seen_on = np.array(
            [
                f + 2 < len(ids) and np.isin(p, ids[f + 1]) and np.isin(p, ids[f + 2])
                for f, p in zip(frame, first_particle, strict=True)
            ]
        )
        wrong_first[lookahead] = wrong[second & seen_on].mean()
    assert wrong_first[False] > 0.1
    assert wrong_first[True] < min(0.05, wrong_first[False] / 5)


def test_a_mean_displacement_predictor_follows_a_fast_mean_flow():
    # A jittered lattice 1 mm apart moving 3.5 mm per frame: no particle is near its own
    # partner, but each is near its mean-flow prediction.
    rng = np.random.default_rng(3)
    grid = np.stack(np.meshgrid(*[np.arange(8) * 1e-3] * 3, indexing="ij"), -1).reshape(-1, 3)
    x0 = grid + rng.normal(scale=20e-6, size=grid.shape)
    step = np.array([3.5e-3, 0.0, 0.0])
    order = [rng.permutation(len(x0)) for _ in range(6)]
    frames = [
        (x0 + f * step + rng.normal(scale=SIGMA, size=x0.shape))[o] for f, o in enumerate(order)
    ]
    tracks = track_frames(frames, radius=3e-4, predicted_radius=1e-4, predictor=step)
    wrong, found, whole = scores(tracks, order)
    assert tracks.n_tracks == len(x0) and wrong == 0 and found == whole == 1
    assert track_frames(frames, radius=3e-4).n_tracks == 6 * len(x0)  # without it: no link
    # A predictor as a function of position does the same.
    moving = track_frames(frames, radius=3e-4, predictor=lambda x: np.broadcast_to(step, x.shape))
    assert moving.n_tracks == len(x0)


def test_tracks_survive_empty_frames_and_refuse_bad_input():
    x = np.array([[0.0, 0, 0], [1.0, 0, 0]])
    tracks = track_frames([x, np.empty((0, 3)), x, x + 0.01], radius=0.1)
    assert tracks.n_frames == 4 and tracks.n_tracks == 4
    assert tracks.lengths.tolist() == [1, 1, 2, 2]
    assert tracks.frame.tolist() == [0, 0, 2, 3, 2, 3]
    empty = track_frames([], radius=0.1)
    assert empty.n_tracks == 0 and empty.n_frames == 0 and empty.links == 0
    none = track_frames([np.empty((0, 3))] * 3, radius=0.1)
    assert none.n_tracks == 0 and none.n_frames == 3
    with pytest.raises(ValueError, match=r"frame 1 must have shape \(N, 3\)"):
        track_frames([x, x[:, :2]], radius=0.1)
    with pytest.raises(ValueError, match="predicted_radius"):
        track_frames([x, x], radius=0.1, predicted_radius=0.0)
    with pytest.raises(ValueError, match="radius"):
        track_frames([x, x], radius=-1.0)


def test_tracks_check_their_layout():
    track = np.array([0, 0, 1, 2, 2])
    frame = np.array([0, 1, 0, 1, 2])
    index = np.zeros(5, dtype=int)
    assert Tracks(track, frame, index, np.zeros((5, 3)), 3).lengths.tolist() == [2, 1, 2]
    with pytest.raises(ValueError, match="must align"):
        Tracks(track, frame[:-1], index, np.zeros((5, 3)), 3)
    # A closed gap (frames 0 and 2 of track 0) is a track; frames that do not increase
    # are not.
    assert Tracks(track, np.array([0, 2, 0, 1, 2]), index, np.zeros((5, 3)), 3).links == 2
    with pytest.raises(ValueError, match="increasing frames"):
        Tracks(track, np.array([1, 1, 0, 1, 2]), index, np.zeros((5, 3)), 3)
    with pytest.raises(ValueError, match="without gaps"):
        Tracks(track + 1, frame, index, np.zeros((5, 3)), 3)


def test_a_particle_missed_for_a_frame_or_two_keeps_its_track(sequence):
    # 5 % of the points of frames 2 … 10 missed at random: without gap closing every
    # miss splits a track; across up to two missed frames the constant-velocity
    # prediction s frames ahead (radius × s(s + 1)/2) finds the particle again.
    tau, frames, ids, acceleration = sequence
    rng = np.random.default_rng(5)
    kept = [
        np.ones(len(x), dtype=bool) if f < 2 or f == len(frames) - 1 else rng.random(len(x)) > 0.05
        for f, x in enumerate(frames)
    ]
    seen = [x[k] for x, k in zip(frames, kept, strict=True)]
    seen_ids = [i[k] for i, k in zip(ids, kept, strict=True)]
    radius, predicted_radius = radii(tau, acceleration)
    split = track_frames(seen, radius=radius, predicted_radius=predicted_radius)
    closed = track_frames(seen, radius=radius, predicted_radius=predicted_radius, gap=2)
    particle = truth_of(closed, seen_ids)
    same = closed.track[1:] == closed.track[:-1]
    assert np.mean(particle[1:][same] != particle[:-1][same]) <= 0.01
    first_and_last = set(seen_ids[0]) & set(seen_ids[-1])
    # Tracks that run from the first frame to the last, each one particle's.
    whole = {
        int(particle[closed.track == t][0])
        for t in np.unique(closed.track)
        if {0, len(frames) - 1} <= set(closed.frame[closed.track == t].tolist())
        and len(set(particle[closed.track == t].tolist())) == 1
    }
    assert len(whole) >= 0.98 * len(first_and_last)
    assert split.n_tracks > closed.n_tracks + 0.2 * len(first_and_last)
    assert np.all(np.diff(closed.frame)[np.diff(closed.track) == 0] <= 3)


def test_gap_must_be_a_count_of_frames():
    with pytest.raises(ValueError, match="gap"):
        track_frames([np.zeros((1, 3))], radius=1.0, gap=-1)
