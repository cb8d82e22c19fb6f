"""Double-frame links and the trajectory test against the truth."""

import numpy as np
import pytest

from ptv.tracking.linking import link, search_radius, trajectory_residuals
from simulator.particles import SHEET, KSFlow, double_frame
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
    sample = double_frame(
        KSFlow(PopeSpectrum(PRESET.parameters)), [dt], particles=2000, snapshots=1, rng=0
    )
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


def test_ambiguous_counts_links_not_particles_left_unlinked():
    # Three particles, two targets, every pair within the radius: two links, both with
    # another candidate; the third particle, unlinked, is no ambiguous link.
    a = np.array([[0.0, 0, 0], [0.05, 0, 0], [0.1, 0, 0]])
    b = np.array([[0.02, 0, 0], [0.08, 0, 0]])
    links = link(a, b, radius=0.2)
    assert len(links) == 2 and links.ambiguous == 2


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
