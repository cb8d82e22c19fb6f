"""The Δt³ bias of c₁ against the truth of its pairs, and its paired error."""

import numpy as np
import pytest

from ptv.bins import LogBins
from simulator.particles import Box, ParticleSnapshots
from validation.truth.dt3_bias import c1_bias

REGION = Box((0.04, 0.04, 0.01))
BINS = LogBins(2e-3, 20e-3, 6)
TIMES = np.array([0.0, 0.01, 0.02, 0.03, 0.04])


def _trajectories(curvature: float, seed: int = 0) -> ParticleSnapshots:
    """Particles with random velocities u (σ = 10 mm/s) moving as x0 + ut + κu t²/2:
    an acceleration a = κu, so that on the same pairs, exactly,
    ⟨q⟩(Δt) = S2 (Δt² + κΔt³ + κ²Δt⁴/4) with S2 the sample truth."""
    rng = np.random.default_rng(seed)
    m, n = 30, 400
    x0 = rng.uniform(-0.02, 0.02, (m, 1, n, 3)) * np.array([1, 1, 0.25])
    u = rng.normal(0.0, 0.01, (m, 1, n, 3))
    t = TIMES[None, :, None, None]
    positions = x0 + u * t + curvature * u * t**2 / 2
    velocity = np.broadcast_to(u * (1 + curvature * t), positions.shape)
    return ParticleSnapshots(TIMES, positions, np.array(velocity), curvature * velocity)


def test_straight_trajectories_give_no_bias_and_the_paired_error_cancels_the_sampling():
    sample = _trajectories(0.0)
    result = c1_bias(
        TIMES,
        sample.positions,
        sample.positions[:, 0],
        sample.velocity[:, 0],
        np.arange(1, 5),
        region=REGION,
        bins=BINS,
        binning="start",
        n_boot=50,
        rng=np.random.SeedSequence(1),
    )
    ok = result["fitted"]
    assert ok.sum() >= 4
    # q = (δu_L Δt)² exactly: c₁ is the truth of the same pairs, in every replicate too
    assert np.abs(result["bias"][ok]).max() < 1e-9
    assert np.abs(result["se"][ok]).max() < 1e-9


def test_a_cubic_term_biases_c1_by_the_gamma_of_the_fits_weights():
    # κΔt_max = 0.08: the Δt⁴ term adds κ²δ/4 to the bias κγ, δ/γ ≈ Δt_max, i.e. about
    # κΔt_max/4 = 2 % of it; the check allows 5 %
    kappa = 2.0
    sample = _trajectories(kappa, seed=2)
    result = c1_bias(
        TIMES,
        sample.positions,
        sample.positions[:, 0],
        sample.velocity[:, 0],
        np.arange(1, 5),
        region=REGION,
        bins=BINS,
        binning="start",
        n_boot=50,
        rng=np.random.SeedSequence(3),
    )
    ok = result["fitted"]
    predicted = kappa * result["gamma_weighted"][ok]
    assert np.all(predicted > 0)
    assert result["bias"][ok] == pytest.approx(predicted, rel=0.05)
    # the unweighted γ of the set would predict more: the weights favour the small Δt
    dt = TIMES[1:]
    design = np.stack([dt**2, np.ones_like(dt)], axis=1)
    (gamma, _), *_ = np.linalg.lstsq(design, dt**3, rcond=None)
    assert np.all(result["gamma_weighted"][ok] <= gamma * (1 + 1e-9))
