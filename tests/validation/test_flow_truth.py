"""The sample truth over the pairs a measurement used: association, ghosts, frames."""

import numpy as np
from scipy.spatial.transform import Rotation

from ptv.pipeline import PipelineSettings, S2Population
from ptv.stats.pairs import pair_sums
from validation.flow_truth import population_truth
from validation.truth_runs import TruthRun

SETTINGS = PipelineSettings(r_min=1e-3, r_max=30e-3, n_bins=8)


def _truth(rng, snapshots=3, particles=400) -> TruthRun:
    x = rng.uniform(-0.03, 0.03, (snapshots, 2, particles, 3)) * [1, 1, 0.1]
    u = rng.normal(size=(snapshots, particles, 3)) * 0.2
    return TruthRun(dt=1e-4, positions=x, velocity=u, xy={}, visible={})


def test_the_truth_of_a_subset_is_that_of_its_true_particles_without_the_ghosts():
    rng = np.random.default_rng(2)
    truth = _truth(rng)
    kept = [rng.choice(400, 300, replace=False) for _ in range(3)]
    measured = []
    for m, rows in enumerate(kept):
        points = truth.positions[m, 0, rows] + rng.normal(size=(len(rows), 3)) * 10e-6
        ghosts = rng.uniform(-0.03, 0.03, (20, 3)) * [1, 1, 0.1] + [0, 0, 0.5]  # far off
        measured.append(np.concatenate([points, ghosts]))
    population = S2Population(np.arange(3), tuple(measured), trajectory_outliers=0)
    result = population_truth(population, truth, SETTINGS, radius=100e-6)
    expected = pair_sums(truth.positions[0, 0, kept[0]], truth.velocity[0, kept[0]], SETTINGS.bins)
    for m in (1, 2):
        expected = expected + pair_sums(
            truth.positions[m, 0, kept[m]], truth.velocity[m, kept[m]], SETTINGS.bins
        )
    assert result.particles == 960 and result.associated == 900
    assert np.allclose(result.s2_sample, expected.mean[:, 0], rtol=1e-12, equal_nan=True)
    assert np.all(result.se_s2_sample[np.isfinite(result.s2_sample)] > 0)


def test_positions_in_another_frame_are_brought_to_the_world_first():
    rng = np.random.default_rng(3)
    truth = _truth(rng, snapshots=2)
    rotation = Rotation.from_rotvec([0.002, -0.001, 0.003]).as_matrix()  # ~0.2°
    translation = np.array([40e-6, -25e-6, 60e-6])
    # Calibration-frame positions: X_cal = Rᵀ (X_world − t).
    measured = tuple((truth.positions[m, 0] - translation) @ rotation for m in range(2))
    population = S2Population(np.arange(2), measured, trajectory_outliers=0)
    lost = population_truth(population, truth, SETTINGS, radius=20e-6)
    found = population_truth(
        population, truth, SETTINGS, radius=20e-6, rotation=rotation, translation=translation
    )
    assert found.associated == 800 and lost.associated < 100
