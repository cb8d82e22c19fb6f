"""Double-frame links, time-resolved tracks and skip-frame pairs against the truth."""

import numpy as np
import pytest

from ptv.track import (
    Tracks,
    link,
    search_radius,
    skip_pairs,
    track_frames,
    trajectory_residuals,
)
from simulator.particles import SHEET, Box, double_frame, time_resolved
from simulator.presets import flow_preset
from simulator.spectra import PopeSpectrum

PRESET = flow_preset("lem-10hz")
U_RMS = PRESET.parameters.u_rms
#: Stereo-like anisotropic position noise (σ_X, σ_Y, σ_Z), m.
SIGMA = np.array([15e-6, 10e-6, 25e-6])


def frames_from(positions, rng, region=SHEET):
    """Noisy, shuffled frames of the particles inside the region, and their true ids."""
    frames, ids = [], []
    for x in positions:
        inside = rng.permutation(np.flatnonzero(region.contains(x)))
        frames.append(x[inside] + rng.normal(size=(len(inside), 3)) * SIGMA)
        ids.append(inside)
    return frames, ids


@pytest.fixture(scope="module")
def largest_dt_pair():
    dt = float(PRESET.dt[-1])
    sample = double_frame(PopeSpectrum(PRESET.parameters), [dt], particles=2000, snapshots=1, rng=0)
    frames, ids = frames_from(sample.runs[0].positions[0], np.random.default_rng(1))
    return dt, frames, ids


def test_search_radius_scales_with_dt():
    assert search_radius(1e-3, u_rms=0.2, sigma_b=1e-5) == pytest.approx(5 * 0.2e-3 + 5e-5)
    assert search_radius(2e-3, u_rms=0.2, k_v=3, k_b=0) == pytest.approx(1.2e-3)
    with pytest.raises(ValueError, match="u_rms"):
        search_radius(1e-3, u_rms=-1.0)
    with pytest.raises(ValueError, match="> 0"):
        search_radius(0.0, u_rms=0.2)


def test_double_frame_links_at_the_largest_dt(largest_dt_pair):
    dt, (a, b), (ia, ib) = largest_dt_pair
    links = link(a, b, radius=search_radius(dt, u_rms=U_RMS, sigma_b=SIGMA.max()))
    both = np.intersect1d(ia, ib)
    right = ia[links.index_a] == ib[links.index_b]
    assert right.sum() / len(both) >= 0.95
    assert 1 - right.mean() <= 0.01
    assert len(np.unique(links.index_a)) == len(links) == len(np.unique(links.index_b))
    assert np.all(np.diff(links.index_a) > 0)
    assert np.array_equal(links.positions, a[links.index_a])
    assert np.allclose(links.displacements, b[links.index_b] - a[links.index_a])
    assert links.candidates >= len(links) and links.ambiguous >= 0


def test_a_mean_displacement_predictor_follows_a_mean_flow(largest_dt_pair):
    dt, (a, b), (ia, ib) = largest_dt_pair
    radius = search_radius(dt, u_rms=U_RMS, sigma_b=SIGMA.max())
    shift = np.array([3e-3, -1e-3, 0.0])  # a mean flow far larger than the radius
    moved = b + shift
    blind = link(a, moved, radius=radius)
    assert np.sum(ia[blind.index_a] == ib[blind.index_b]) < 0.01 * len(a)
    for predictor in (shift, lambda x: np.broadcast_to(shift, x.shape)):
        links = link(a, moved, radius=radius, predictor=predictor)
        right = ia[links.index_a] == ib[links.index_b]
        assert right.sum() / len(np.intersect1d(ia, ib)) >= 0.95
        assert np.allclose(links.displacements, b[links.index_b] + shift - a[links.index_a])
    # A position-dependent mean displacement (shear) works the same way.
    gradient = 0.3  # ΔU_x = 0.3 · Y over Δt: ±15 mm across the sheet
    sheared = b + np.outer(b[:, 1], [gradient, 0, 0])
    links = link(a, sheared, radius=radius, predictor=lambda x: np.outer(x[:, 1], [gradient, 0, 0]))
    assert np.mean(ia[links.index_a] == ib[links.index_b]) >= 0.99


def test_the_assignment_is_one_to_one_and_minimises_the_total():
    # Two particles, two targets: nearest-neighbour would send both to target 0.
    a = np.array([[0.0, 0, 0], [1.0, 0, 0]])
    b = np.array([[0.45, 0, 0], [-0.6, 0, 0]])
    links = link(a, b, radius=1.2)
    assert links.index_a.tolist() == [0, 1] and links.index_b.tolist() == [1, 0]
    assert links.ambiguous == 1 and links.candidates == 3


def test_empty_frames_and_bad_input(largest_dt_pair):
    _, (a, b), _ = largest_dt_pair
    for x, y in ((np.empty((0, 3)), b), (a, np.empty((0, 3))), ([], [])):
        links = link(x, y, radius=1e-3)
        assert len(links) == 0 and links.positions.shape == (0, 3)
    with pytest.raises(ValueError, match=r"frame_b must have shape \(N, 3\)"):
        link(a, b[:, :2], radius=1e-3)
    with pytest.raises(ValueError, match="frame_a holds 1 non-finite"):
        link(np.vstack([a, [[np.nan, 0, 0]]]), b, radius=1e-3)
    with pytest.raises(ValueError, match="radius"):
        link(a, b, radius=-1.0)
    with pytest.raises(ValueError, match=r"constant predictor .* shape \(3,\)"):
        link(a, b, radius=1e-3, predictor=[1.0, 2.0])
    with pytest.raises(ValueError, match="predictor must return"):
        link(a, b, radius=1e-3, predictor=lambda x: x[:, :2])


def _identity_scores(tracks: Tracks, ids):
    truth = np.empty(len(tracks.track), dtype=np.int64)
    for f, i in enumerate(ids):
        sel = tracks.frame == f
        truth[sel] = i[tracks.index[sel]]
    same = tracks.track[1:] == tracks.track[:-1]
    wrong = np.sum(same & (truth[1:] != truth[:-1]))
    # Particles seen in every frame, recovered as one full-length pure track.
    everywhere = set(ids[0]).intersection(*map(set, ids[1:]))
    full = tracks.lengths == tracks.n_frames
    pure = np.ones(tracks.n_tracks, dtype=bool)
    pure[tracks.track[1:][same & (truth[1:] != truth[:-1])]] = False
    first_row = np.searchsorted(tracks.track, np.flatnonzero(full & pure))
    recovered = set(truth[first_row].tolist())
    return wrong / same.sum(), len(recovered & everywhere) / len(everywhere)


@pytest.mark.parametrize(("frame_dt", "density"), [(1, 2000), (4, 5000)])
def test_time_resolved_tracks_recover_the_true_identities(frame_dt, density):
    # τ = Δt_max of lem-10hz (u'τ ≈ 0.1 mm, a 2 kHz camera) and 4 Δt_max with 2.5× the
    # seeding (u'τ ≈ 0.4 mm, first links ambiguous; the KS acceleration moves a particle
    # ≈ 90 µm rms per component off its constant-velocity prediction at this τ).
    # Half the sheet's width and height at the density of ``density`` per sheet, to save
    # simulation time.
    region = Box((0.05, 0.05, 0.01))
    tau = frame_dt * float(PRESET.dt[-1])
    sample = time_resolved(
        PopeSpectrum(PRESET.parameters),
        tau,
        8,
        particles=density // 4,
        snapshots=1,
        region=region,
        rng=2,
    )
    frames, ids = frames_from(sample.snapshots.positions[0], np.random.default_rng(3), region)
    tracks = track_frames(
        frames,
        radius=search_radius(tau, u_rms=U_RMS, sigma_b=SIGMA.max()),
        predicted_radius=5 * (9e-5 * (frame_dt / 4) ** 2 + np.sqrt(6) * SIGMA.max()),
    )
    wrong, recovered = _identity_scores(tracks, ids)
    assert wrong <= (1e-4 if frame_dt == 1 else 5e-3)
    assert recovered >= (0.999 if frame_dt == 1 else 0.99)
    for f, x in enumerate(frames):  # every observation is on exactly one track
        assert np.array_equal(np.sort(tracks.index[tracks.frame == f]), np.arange(len(x)))
        assert np.array_equal(
            tracks.positions[tracks.frame == f], x[tracks.index[tracks.frame == f]]
        )


def test_constant_velocity_prediction_carries_fast_particles():
    # Each particle moves 1 mm per frame ± 0.3 mm, far beyond the 0.2 mm radius after
    # the first link (which the mean displacement predicts): only the constant-velocity
    # prediction keeps them on track.
    rng = np.random.default_rng(4)
    x0 = rng.uniform(0, 0.1, (300, 3))
    step = np.array([1e-3, 0, 0]) + rng.uniform(-3e-4, 3e-4, (300, 3))
    frames = [x0 + f * step for f in range(6)]
    order = [rng.permutation(300) for _ in frames]
    shuffled = [x[o] for x, o in zip(frames, order, strict=True)]
    tracks = track_frames(shuffled, radius=1e-3, predicted_radius=2e-4, predictor=[1e-3, 0, 0])
    assert tracks.n_tracks == 300 and np.all(tracks.lengths == 6)
    wrong, recovered = _identity_scores(tracks, order)
    assert wrong == 0 and recovered == 1
    # Without the mean displacement nothing links.
    lost = track_frames(shuffled, radius=2e-4)
    assert lost.n_tracks == 6 * 300


def test_tracks_survive_empty_frames():
    x = np.array([[0.0, 0, 0], [1.0, 0, 0]])
    tracks = track_frames([x, np.empty((0, 3)), x, x + 0.01], radius=0.1)
    assert tracks.n_frames == 4 and tracks.n_tracks == 4
    assert tracks.lengths.tolist() == [1, 1, 2, 2]
    assert tracks.ids(2, 2).tolist() == [2, 3] and tracks.ids(1, 0).tolist() == []
    empty = track_frames([], radius=0.1)
    assert empty.n_tracks == 0 and empty.n_frames == 0
    none = track_frames([np.empty((0, 3))] * 3, radius=0.1)
    assert none.n_tracks == 0 and len(skip_pairs(none, [1, 2])) == 0
    with pytest.raises(ValueError, match=r"frame 1 must have shape \(N, 3\)"):
        track_frames([x, x[:, :2]], radius=0.1)
    with pytest.raises(ValueError, match="predicted_radius"):
        track_frames([x, x], radius=0.1, predicted_radius=0.0)


def test_skip_pairs_use_the_same_segments_for_every_skip():
    # Hand-made tracks: lengths 6, 3 and 4 (starting at frame 2).
    track = np.array([0] * 6 + [1] * 3 + [2] * 4)
    frame = np.array([*range(6), *range(3), *range(2, 6)])
    positions = np.column_stack([track * 100.0 + frame**2, np.zeros(13), np.zeros(13)])
    tracks = Tracks(track, frame, np.zeros(13, dtype=int), positions, 6)
    pairs = skip_pairs(tracks, [3, 1, 2])
    assert pairs.skips.tolist() == [1, 2, 3]
    # m_max = 3: segments of 4 frames; track 1 is too short, track 2 has one.
    assert list(zip(pairs.track.tolist(), pairs.frame.tolist(), strict=True)) == [
        (0, 0),
        (0, 1),
        (0, 2),
        (2, 2),
    ]
    assert pairs.displacements.shape == (4, 3, 3)
    start = pairs.track * 100.0 + pairs.frame**2
    assert np.array_equal(pairs.positions[:, 0], start)
    for k, m in enumerate(pairs.skips):
        assert np.allclose(pairs.displacements[:, k, 0], (pairs.frame + m) ** 2 - pairs.frame**2)
    disjoint = skip_pairs(tracks, [1, 3], stride=4)
    assert list(zip(disjoint.track.tolist(), disjoint.frame.tolist(), strict=True)) == [
        (0, 0),
        (2, 2),
    ]
    with pytest.raises(ValueError, match="skips"):
        skip_pairs(tracks, [0, 1])
    with pytest.raises(ValueError, match="skips"):
        skip_pairs(tracks, [1.5])
    with pytest.raises(ValueError, match="stride"):
        skip_pairs(tracks, [1], stride=0)
    with pytest.raises(ValueError, match="sorted by track id"):
        Tracks(track[::-1], frame, np.zeros(13, dtype=int), positions, 6)
    with pytest.raises(ValueError, match="must align"):
        Tracks(track, frame[:-1], np.zeros(13, dtype=int), positions, 6)


def test_skip_pairs_from_tracked_flow_match_the_truth():
    tau = float(PRESET.dt[0])
    sample = time_resolved(
        PopeSpectrum(PRESET.parameters), tau, 7, particles=1000, snapshots=1, rng=5
    )
    truth = sample.snapshots.positions[0]
    frames, ids = frames_from(truth, np.random.default_rng(6))
    tracks = track_frames(frames, radius=search_radius(tau, u_rms=U_RMS, sigma_b=SIGMA.max()))
    pairs = skip_pairs(tracks, [1, 2, 3, 5])
    first_row = np.searchsorted(tracks.track, pairs.track)
    rows = first_row + pairs.frame - tracks.frame[first_row]
    assert np.array_equal(tracks.frame[rows], pairs.frame)
    particle = np.array([ids[f][i] for f, i in zip(pairs.frame, tracks.index[rows], strict=True)])
    for k, m in enumerate(pairs.skips):
        exact = truth[pairs.frame + m, particle] - truth[pairs.frame, particle]
        # Measured increments carry the noise of two positions, nothing more.
        assert np.all(np.abs(pairs.displacements[:, k] - exact) < 6 * np.sqrt(2) * SIGMA)


def quadratic_displacements(dt, rng, particles=20):
    """ΔX_k = c + uΔt_k + ½aΔt_k² with c of the noise scale and typical u, a, m."""
    c = rng.normal(size=(particles, 1, 3)) * 10e-6
    u = rng.normal(size=(particles, 1, 3)) * U_RMS
    a = rng.normal(size=(particles, 1, 3)) * 20.0
    t = np.asarray(dt)[None, :, None]
    return c + u * t + 0.5 * a * t**2


@pytest.mark.parametrize("dt", [PRESET.dt, PRESET.dt[:4], np.array([1e-4, 3e-4, 4e-4, 9e-4, 2e-3])])
def test_trajectory_residuals_vanish_on_quadratic_paths(dt):
    d = quadratic_displacements(dt, np.random.default_rng(11))
    residuals = trajectory_residuals(dt, d)
    assert residuals.shape == (len(d),)
    # Round-off only: displacements are ~0.1 mm, a mislink or noise is ≥ 1 µm.
    assert np.all(residuals < 1e-15)
    assert np.all(residuals < 1e-12 * np.abs(d).max(axis=(1, 2)))


def test_a_jump_at_one_dt_gives_its_least_squares_residual():
    dt = PRESET.dt
    d = quadratic_displacements(dt, np.random.default_rng(12))
    jump, k, mislinked = np.array([120e-6, -50e-6, 80e-6]), 2, 5
    d[mislinked, k] += jump
    residuals = trajectory_residuals(dt, d)
    # The residual of a unit vector e_k off span(1, Δt, Δt²) has squared norm 1 − H_kk,
    # H the hat matrix, so the RMS over K Δt and 3 components is |J| sqrt((1 − H_kk)/3K).
    q, _ = np.linalg.qr(np.vander(dt, 3))
    leverage = np.sum(q[k] ** 2)
    expected = np.linalg.norm(jump) * np.sqrt((1 - leverage) / (3 * len(dt)))
    assert residuals[mislinked] == pytest.approx(expected, rel=1e-9)
    assert residuals[mislinked] > np.linalg.norm(jump) / 10
    others = np.delete(residuals, mislinked)
    assert np.all(others < 1e-6 * expected)


@pytest.mark.parametrize(
    ("dt", "shape", "message"),
    [
        (PRESET.dt[:3], (4, 3, 3), "at least 4"),
        (np.ones((2, 4)), (4, 8, 3), "at least 4"),
        (PRESET.dt, (4, 4, 3), "shape"),
        (PRESET.dt, (4, 5, 2), "shape"),
        (PRESET.dt, (5, 3), "shape"),
    ],
)
def test_trajectory_residuals_reject_too_few_dt_and_wrong_shapes(dt, shape, message):
    with pytest.raises(ValueError, match=message):
        trajectory_residuals(dt, np.zeros(shape))
