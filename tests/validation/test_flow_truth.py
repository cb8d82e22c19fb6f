"""The truth of the particles a measurement used: association, ghosts, frames, noise."""

import numpy as np
from scipy.spatial.transform import Rotation

from ptv.settings import StatisticsSettings
from ptv.stats.pairs import pair_sums
from ptv.stats.run_statistics import S2Population
from validation.truth.flow_truth import population_truth
from validation.truth.truth_file import TruthRun

SETTINGS = StatisticsSettings(r_min=1e-3, r_max=30e-3, n_bins=8)
DT = (1e-4, 3e-4)


def _truth(rng, snapshots=3, particles=400) -> list[TruthRun]:
    """Runs sharing frame a: positions at t, and at t + Δt_k moved by u·Δt_k."""
    x = rng.uniform(-0.03, 0.03, (snapshots, particles, 3)) * [1, 1, 0.1]
    u = rng.normal(size=(snapshots, particles, 3)) * 0.2
    return [
        TruthRun(dt=dt, positions=np.stack([x, x + u * dt], axis=1), velocity=u, xy={}, visible={})
        for dt in DT
    ]


class _Truth:
    """The runs in memory, read a range of snapshots at a time as a TruthFile is."""

    def __init__(self, runs):
        self._runs = runs
        self.dt = np.array([run.dt for run in runs])

    def runs(self, m0, m1):
        return [
            TruthRun(run.dt, run.positions[m0:m1], run.velocity[m0:m1], {}, {}, first=m0)
            for run in self._runs
        ]


def _population_truth(population, truth, **kwargs):
    """population_truth reading the truth one snapshot at a time."""
    chunks = [(m, m + 1) for m in range(len(truth[0].positions))]
    return population_truth(population, _Truth(truth), chunks, SETTINGS, **kwargs)


def _moves(truth, m, rows):
    return np.stack([run.positions[m, 1, rows] - run.positions[m, 0, rows] for run in truth], 1)


def test_the_truth_of_a_subset_is_that_of_its_true_particles_without_the_ghosts():
    rng = np.random.default_rng(2)
    truth = _truth(rng)
    kept = [rng.choice(400, 300, replace=False) for _ in range(3)]
    measured, moved = [], []
    for m, rows in enumerate(kept):
        points = truth[0].positions[m, 0, rows] + rng.normal(size=(len(rows), 3)) * 10e-6
        ghosts = rng.uniform(-0.03, 0.03, (20, 3)) * [1, 1, 0.1] + [0, 0, 0.5]  # far off
        measured.append(np.concatenate([points, ghosts]))
        noisy = _moves(truth, m, rows) + rng.normal(size=(len(rows), len(DT), 3)) * 5e-6
        moved.append(np.concatenate([noisy, np.zeros((20, len(DT), 3))]))
    population = S2Population(np.arange(3), tuple(measured), tuple(moved), trajectory_outliers=0)
    result = _population_truth(population, truth, radius=100e-6)
    bins = SETTINGS.bins
    expected = pair_sums(truth[0].positions[0, 0, kept[0]], truth[0].velocity[0, kept[0]], bins)
    for m in (1, 2):
        expected = expected + pair_sums(
            truth[0].positions[m, 0, kept[m]], truth[0].velocity[m, kept[m]], bins
        )
    assert result.particles == 960 and result.associated == 900
    assert np.allclose(result.s2_sample, expected.mean[:, 0], rtol=1e-12, equal_nan=True)
    assert np.all(result.se_s2_sample[np.isfinite(result.s2_sample)] > 0)
    # 900 × 2 Δt × 3 components of N(0, 5 µm): the RMS within 10 % (3.4 standard errors).
    assert result.displacement_noise.shape == (len(DT), 3)
    assert np.allclose(result.displacement_noise, 5e-6, rtol=0.1)
    assert result.dt.tolist() == list(DT)


def test_positions_in_another_frame_are_brought_to_the_world_first():
    rng = np.random.default_rng(3)
    truth = _truth(rng, snapshots=2)
    rotation = Rotation.from_rotvec([0.002, -0.001, 0.003]).as_matrix()  # ~0.2°
    translation = np.array([40e-6, -25e-6, 60e-6])
    # Calibration-frame positions and displacements: X_cal = Rᵀ (X_world − t).
    measured = tuple((truth[0].positions[m, 0] - translation) @ rotation for m in range(2))
    moved = tuple(_moves(truth, m, slice(None)) @ rotation for m in range(2))
    population = S2Population(np.arange(2), measured, moved, trajectory_outliers=0)
    lost = _population_truth(population, truth, radius=20e-6)
    found = _population_truth(
        population, truth, radius=20e-6, rotation=rotation, translation=translation
    )
    assert found.associated == 800 and lost.associated < 100
    assert found.displacement_noise.max() < 1e-12  # exact displacements, rotated back
