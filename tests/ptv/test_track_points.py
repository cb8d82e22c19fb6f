"""Two-pass linking of a recording's points (``ptv.pipeline.time_resolved.track_points``).

Particles on straight paths 2 mm apart, 40 µm a frame, with Gaussian noise of σ per
component: the first pass's prediction misses give σ back, and the second pass links
with 2σ where that is below the settings' 30 µm, every particle in one track.
"""

import numpy as np
import pytest

from ptv.pipeline.time_resolved import (
    MISS_NOISE_FACTOR,
    prediction_noise,
    track_points,
    track_radii,
)
from ptv.settings import PipelineSettings

RATE = 4000.0
FRAMES = 40


def straight_frames(sigma: float, rng) -> list[np.ndarray]:
    grid = np.stack(np.meshgrid(*[np.arange(8) * 2e-3] * 2, indexing="ij"), -1).reshape(-1, 2)
    start = np.column_stack([grid, np.zeros(len(grid))])
    velocity = rng.normal(0, 1, size=start.shape) * 40e-6 * RATE / np.sqrt(3)
    return [start + velocity * f / RATE + rng.normal(0, sigma, start.shape) for f in range(FRAMES)]


@pytest.mark.parametrize("sigma", [2e-6, 5e-6])
def test_the_second_pass_follows_the_noise_the_tracks_show(sigma):
    rng = np.random.default_rng(3)
    frames = straight_frames(sigma, rng)
    settings = PipelineSettings(max_speed=1.0)
    linked = track_points(frames, RATE, settings)
    # rms/√6 of 64 × 38 misses per component, the largest of three: within 5 % of σ
    # (a χ² of 2432 degrees of freedom has a relative spread of 2.9 %; the largest of
    # three sits about one spread above).
    assert linked.miss_noise == pytest.approx(sigma, rel=0.06)
    measured = PipelineSettings(max_speed=1.0, position_noise=MISS_NOISE_FACTOR * linked.miss_noise)
    one_frame = track_radii(RATE, measured)[1]
    assert linked.predicted_radius == pytest.approx(one_frame)
    assert linked.tracks.n_tracks == 64
    assert np.all(linked.tracks.lengths == FRAMES)


def test_too_few_misses_leave_the_settings_radius():
    rng = np.random.default_rng(4)
    frames = straight_frames(2e-6, rng)[:3]
    settings = PipelineSettings(max_speed=1.0)
    linked = track_points(frames, RATE, settings)
    assert linked.miss_noise is None
    assert linked.predicted_radius == pytest.approx(track_radii(RATE, settings)[1])
    assert prediction_noise(linked.tracks) is None
