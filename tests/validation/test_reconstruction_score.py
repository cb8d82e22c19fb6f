"""Reconstructed particles scored against a truth built here: found, ghosts, errors."""

import numpy as np
import pytest

from validation.run.verdict import ipr_rows
from validation.truth.reconstruction import score_reconstruction
from validation.truth.truth_file import TruthRun

VOXEL = 60e-6


class Orthographic:
    """A camera looking along Z: x = X / 60 µm + 100 px, y = Y / 60 µm + 50 px."""

    def project(self, points):
        points = np.asarray(points, dtype=float).reshape(-1, 3)
        return np.column_stack([points[:, 0] / VOXEL + 100, points[:, 1] / VOXEL + 50])


def truth_run(particles: np.ndarray, visible: np.ndarray) -> TruthRun:
    """One snapshot whose frames a and b both hold ``particles`` (P, 3)."""
    positions = np.stack([particles, particles])[None]  # (1, 2, P, 3)
    exact = Orthographic().project(particles)
    xy = np.stack([exact, exact])[None].astype(np.float32)
    return TruthRun(
        dt=1e-3,
        positions=positions,
        velocity=np.zeros((1, len(particles), 3)),
        xy={"c1": xy, "c2": xy},
        visible={
            "c1": np.stack([visible, visible])[None],
            "c2": np.ones((1, 2, len(particles)), bool),
        },
    )


def _scored(points: dict, run: TruthRun, translation=(0.0, 0.0, 0.0)):
    """:func:`score_reconstruction` of ``points`` against one truth run, two
    orthographic cameras c1 and c2, 1000 px sensors, no rotation."""
    return score_reconstruction(
        points,
        [run],
        ["c1", "c2"],
        [Orthographic(), Orthographic()],
        voxel=VOXEL,
        sensor_pixels=1000.0,
        rotation=np.eye(3),
        translation=np.asarray(translation),
    )


def test_found_ghosts_and_errors_are_counted_as_the_challenge_counts_them():
    rng = np.random.default_rng(1)
    particles = rng.uniform(-0.01, 0.01, (200, 3))
    visible = np.ones(200, dtype=bool)
    visible[:10] = False  # not imaged by c1: not a reference particle
    offset = np.array([6e-6, -8e-6, 0.0])  # 10 µm; 0.1 px along X and 0.133 px along Y
    points = particles[20:] + offset  # particles 0-19 missed (10 of them reference ones)
    ghosts = particles[:5] + np.array([0.0, 0.0, 2 * VOXEL])  # two voxels off: ghosts
    score = _scored({(-1, 0, "a"): np.vstack([points, ghosts])}, truth_run(particles, visible))
    assert score.found == pytest.approx(180 / 190)
    assert score.ghosts == pytest.approx(5 / 185)
    assert score.rms_um == pytest.approx(10.0)
    # the truth stores images as float32 (1e-4 px resolution, validation.truth.truth_file)
    assert score.rms_px == pytest.approx(np.hypot(0.1, 8 / 60), abs=1e-4)
    assert (score.particles, score.points, score.exposures) == (190, 185, 1)
    assert score.ppp == pytest.approx((190 + 200) / (2 * 1000.0))


def test_points_of_a_calibration_frame_are_moved_to_the_world_first():
    rng = np.random.default_rng(2)
    particles = rng.uniform(-0.01, 0.01, (50, 3))
    shift = np.array([0.0, 0.0, 1e-3])  # a traverse origin 1 mm off: 17 voxels
    score = _scored(
        {(0, 0, "b"): particles - shift},
        truth_run(particles, np.ones(50, dtype=bool)),
        translation=shift,
    )
    assert score.found == 1.0 and score.ghosts == 0.0
    assert score.rms_um == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize(
    ("ppp", "found", "ghosts", "rms_px", "failed"),
    [
        (0.05, 0.995, 0.005, 0.05, set()),
        (0.05, 0.985, 0.005, 0.05, {"ipr.found"}),
        (0.05, 0.995, 0.015, 0.05, {"ipr.ghosts"}),
        (0.05, 0.995, 0.005, 0.15, {"ipr.position_error_px"}),
        (0.08, 0.975, 0.025, 0.5, set()),
        (0.08, 0.965, 0.035, 0.5, {"ipr.found", "ipr.ghosts"}),
    ],
)
def test_ipr_checks_take_the_challenge_targets_of_their_density(ppp, found, ghosts, rms_px, failed):
    rows = ipr_rows({"ppp": ppp, "found": found, "ghosts": ghosts, "rms_px": rms_px})
    assert {r["id"] for r in rows if not r["passed"]} == failed
    assert ("ipr.position_error_px" in {r["id"] for r in rows}) == (ppp <= 0.05)


def test_beyond_the_densest_target_the_ipr_rows_are_reported_only():
    rows = ipr_rows({"ppp": 0.16, "found": 0.5, "ghosts": 0.3, "rms_px": 1.0})
    assert all(r["passed"] and "informative" in r for r in rows)


def _moving_run(a: np.ndarray, b: np.ndarray) -> TruthRun:
    """One snapshot whose particles move from ``a`` to ``b`` (P, 3), seen by both."""
    xy = np.stack([Orthographic().project(a), Orthographic().project(b)])[None]
    seen = np.ones((1, 2, len(a)), bool)
    return TruthRun(
        dt=1e-3,
        positions=np.stack([a, b])[None],
        velocity=np.zeros((1, len(a), 3)),
        xy={"c1": xy.astype(np.float32), "c2": xy.astype(np.float32)},
        visible={"c1": seen, "c2": seen},
    )


def test_depth_neighbour_and_displacement_scores_follow_where_the_errors_were_put():
    """Particles on a line of images 0.5 px apart at one end (overlapping) and 10 px
    apart elsewhere, at depths spread over 20 mm; the points of the deepest fifth are
    off by 12 µm, the overlapping particles are missed, one ghost lies in the shallowest
    slab, and frame b's points are off by 6 µm along X: each shows where it was put."""
    n = 100
    x = np.concatenate([np.arange(10) * 0.5, 20 + np.arange(n - 10) * 10.0]) * VOXEL
    z = np.linspace(-0.01, 0.01, n)
    a = np.column_stack([x, np.zeros(n), z])
    b = a + np.array([30e-6, 0.0, 0.0])
    deep = z > 0.006
    err = np.where(deep[:, None], [0.0, 12e-6, 0.0], 0.0)
    kept = np.arange(n) >= 10  # the ten overlapping particles are missed
    ghost = np.array([[0.5, 0.5, -0.0099]])  # far from every particle, shallowest slab
    points = {
        (-1, 0, "a"): np.vstack([(a + err)[kept], ghost]),
        (0, 0, "b"): (b + err + np.array([6e-6, 0.0, 0.0]))[kept],
    }
    score = _scored(points, _moving_run(a, b))
    depth = score.by_depth
    assert len(depth) == 5
    assert depth[0]["z_mm"][0] == pytest.approx(-10.0) and depth[-1]["z_mm"][1] == pytest.approx(
        10.0
    )
    # the deepest slab (6-10 mm) holds exactly the 12 µm errors (frame a: 12, b: 12 and 6)
    assert depth[-1]["rms_um"] == pytest.approx(np.sqrt((144 + 144 + 36) / 2))
    assert depth[1]["rms_um"] == pytest.approx(np.sqrt(36 / 2))
    assert depth[0]["ghosts"] == pytest.approx(1 / depth[0]["points"])
    assert all(row["ghosts"] == 0.0 for row in depth[1:])
    # the overlapping images (0.5 px apart) are the missed ones; every other one found
    close, *rest = score.by_neighbour
    assert close["distance_px"] == [0.0, 1.0]
    assert close["particles"] == 2 * 10 and close["found"] == 0.0
    assert sum(row["particles"] for row in rest) == 2 * (n - 10)
    assert all(row["found"] == 1.0 for row in rest if row["particles"])
    # (b − a) against the truth: the 6 µm of frame b, found in both frames
    assert score.displacement_pairs == n - 10
    assert score.displacement_rms_um == pytest.approx(6.0)
