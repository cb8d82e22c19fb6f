"""Snell's law recomputed without the simulator, and the optics claim built on it."""

import numpy as np
import pytest

from validation.claims import ClaimContext, run_claims
from validation.truth.refraction import N_PMMA, N_WATER, snell_miss, stated_indices

NORMAL = np.array([0.0, 0.0, 1.0])
OFFSETS = np.array([0.1, 0.12])  # 20 mm of glass from Z = 0.1 m, water beyond
INDICES = (1.0, N_PMMA, N_WATER)


def test_a_ray_at_normal_incidence_is_not_bent():
    point = np.array([[0.0, 0.0, 0.3]])
    miss = snell_miss(np.zeros(3), np.array([[0.0, 0.0, 1.0]]), NORMAL, OFFSETS, INDICES, point)
    assert miss == pytest.approx([0.0], abs=1e-15)


def test_a_slanted_ray_meets_the_point_snells_law_puts_on_it():
    # Closed form: lateral offsets h tan θ per layer with n sin θ constant.
    theta = np.deg2rad(20.0)
    heights = (0.1, 0.02, 0.05)
    lateral = sum(
        h * np.tan(np.arcsin(np.sin(theta) / n)) for h, n in zip(heights, INDICES, strict=True)
    )
    direction = np.array([[np.sin(theta), 0.0, np.cos(theta)]])
    on_ray = np.array([[lateral, 0.0, sum(heights)]])
    off_ray = on_ray + np.array([[1e-6, 0.0, 0.0]])
    assert snell_miss(np.zeros(3), direction, NORMAL, OFFSETS, INDICES, on_ray)[0] < 1e-15
    wrong = (1.0, 1.52, N_WATER)
    assert snell_miss(np.zeros(3), direction, NORMAL, OFFSETS, wrong, on_ray)[0] > 1e-5
    assert snell_miss(np.zeros(3), direction, NORMAL, OFFSETS, INDICES, off_ray)[0] > 9e-7


def test_a_rig_file_s_stated_indices_override_the_physical_defaults():
    assert stated_indices({"window": {"water_path": 0.15}}) == (1.0, N_PMMA, N_WATER)
    assert stated_indices({"window": {"n_glass": 1.52}}, {"n_water": 1.34}) == (1.0, 1.52, 1.34)


def test_the_simulated_rigs_refract_by_snells_law():
    (result,) = run_claims(ClaimContext("quick"), ids=["optics.snell"])
    assert result.passed and result.value < 1e-3  # µm
