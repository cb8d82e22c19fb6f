"""A recording's tracers: uniform in the sheet at every frame, entering and leaving it,
and their truth consistent with the trajectories it samples."""

import numpy as np
import pytest

from simulator.particles import Box, KSFlow
from simulator.presets import flow_preset
from simulator.recording import follow_recording
from simulator.spectra import PopeSpectrum

REGION = Box((0.02, 0.02, 0.002))
PARTICLES = 150


@pytest.fixture(scope="module")
def recording():
    preset = flow_preset("lem-10hz")
    flow = KSFlow(PopeSpectrum(preset.parameters), n_modes=60)
    rate = 10 / preset.parameters.tau_eta  # τ = τ_η / 10
    return follow_recording(flow, rate, 40, particles=PARTICLES, region=REGION, rng=3, batch=5000)


def test_the_sheet_holds_its_particles_at_every_frame(recording):
    counts = np.bincount(recording.frame, minlength=len(recording.times))
    # Poisson counts of mean 150 over 40 correlated frames: the mean within 4 of its
    # frame-to-frame σ √150, and no frame emptied or doubled.
    assert abs(counts.mean() - PARTICLES) < 4 * np.sqrt(PARTICLES)
    assert counts.min() > PARTICLES / 2 and counts.max() < 2 * PARTICLES


def test_particles_enter_and_leave(recording):
    first = set(recording.particle[recording.frame == 0])
    last = set(recording.particle[recording.frame == len(recording.times) - 1])
    assert last - first and first - last  # the 2 mm sheet is crossed in ~10 ms


def test_the_truth_is_consistent_along_each_trajectory(recording):
    tau = recording.times[1]
    same = (recording.particle[1:] == recording.particle[:-1]) & (
        recording.frame[1:] == recording.frame[:-1] + 1
    )
    x, u, a = recording.position, recording.velocity, recording.acceleration
    # Hermite's rule, ΔX = τ(u₀ + u₁)/2 − τ²(a₁ − a₀)/12 + O(τ⁵), holds each row's
    # velocity and acceleration to its trajectory: a row of another particle or frame
    # leaves τ²|Δa|/12 ≈ 1e-3 of a step.
    step = x[1:][same] - x[:-1][same]
    hermite = tau * (u[1:][same] + u[:-1][same]) / 2 - tau**2 * (a[1:][same] - a[:-1][same]) / 12
    residual = np.linalg.norm(step - hermite, axis=1)
    length = np.linalg.norm(step, axis=1)
    assert np.median(residual) < 1e-4 * np.median(length)
    assert residual.max() < 2e-3 * length.max()
    # du/dt along the path is the mean acceleration of the ends, to O(τ² ä): 4 % rms at
    # τ = τ_η/10 on KS's fastest modes; a wrong scale of a by 10 % fails.
    du = (u[1:][same] - u[:-1][same]) / tau
    mean_a = (a[1:][same] + a[:-1][same]) / 2
    rms = np.sqrt(np.mean(np.sum(mean_a**2, axis=1)))
    assert np.sqrt(np.mean(np.sum((du - mean_a) ** 2, axis=1))) < 0.08 * rms


def test_rows_are_sorted_by_particle_then_frame(recording):
    order = np.lexsort((recording.frame, recording.particle))
    np.testing.assert_array_equal(order, np.arange(len(order)))
    assert REGION.contains(recording.position).all()


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"frame_rate": 0.0}, "frame_rate"),
        ({"frames": 1}, "frames"),
        ({"particles": 0}, "particles"),
    ],
)
def test_bad_input_is_refused(kwargs, message):
    flow = KSFlow(PopeSpectrum(flow_preset("lem-10hz").parameters), n_modes=10)
    args = {"frame_rate": 1000.0, "frames": 10, "particles": 10} | kwargs
    with pytest.raises(ValueError, match=message):
        follow_recording(
            flow, args["frame_rate"], args["frames"], particles=args["particles"], region=REGION
        )


class _Drift:
    """A periodic stand-in for a DNS: every tracer drifts at U with a wave across it, so
    that X(t) = X₀ + U t + A sin(k·X₀) t² is exact and periodic in X₀ with period L; the
    positions come back folded into the period cell, as a DNS may give them."""

    L = 0.05
    U = np.array([0.3, -0.2, 0.05])
    A = np.array([0.0, 0.0, 0.5])

    def follow_snapshot(self, m, rng, seed_box, n_seed, times):
        x0 = seed_box.sample(n_seed, rng)
        wave = np.sin(2 * np.pi * x0[:, :1] / self.L) * self.A  # (n, 3)
        t = times[:, None, None]
        x = x0 + self.U * t + wave * t**2
        lo = np.asarray(seed_box.centre) - self.L / 2
        return (
            lo + np.mod(x - lo, self.L),
            np.broadcast_to(self.U + 2 * wave * t, x.shape),
            np.broadcast_to(2 * wave, x.shape),
        )


def test_a_periodic_flow_fills_a_region_larger_than_its_box_with_its_images():
    from simulator.recording import follow_periodic_recording

    flow, region = _Drift(), Box((0.1, 0.1, 0.008))  # twice the box across, a tenth deep
    count, frames, rate = 400, 40, 200.0
    recorded = follow_periodic_recording(
        flow, flow.L, rate, frames, particles=count, region=region, rng=1
    )
    assert recorded.seeds == round(count * flow.L**3 / region.volume)
    assert np.all(region.contains(recorded.position))
    # Density: the images tile space at seeds / L³. Across, the region spans two periods,
    # so each seed has exactly 4 images there; in depth a seed's image is in the sheet
    # with p = 8 mm / L: the count of a frame is 4 × Binomial(seeds, p), mean `count`;
    # the mean over frames varies no more than one frame's count (3 standard deviations).
    p = region.size[2] / flow.L
    spread = 4 * np.sqrt(recorded.seeds * p * (1 - p))
    per_frame = np.bincount(recorded.frame, minlength=frames)
    assert abs(per_frame.mean() - count) < 3 * spread
    # Each image is a tracer of its own: one row per (particle, frame), sorted, its frames
    # consecutive (the drift carries it through the sheet once), and its truth that of
    # its seed moved by a whole number of periods.
    key = recorded.particle * frames + recorded.frame
    assert np.all(np.diff(key) > 0)
    tau = 1.0 / rate
    for p in np.unique(recorded.particle)[:200]:
        rows = recorded.particle == p
        assert np.all(np.diff(recorded.frame[rows]) == 1)
        # No fold inside a trajectory: its second differences are a·τ², exactly.
        x, a = recorded.position[rows], recorded.acceleration[rows]
        np.testing.assert_allclose(np.diff(x, 2, axis=0), a[1:-1] * tau**2, atol=1e-12)
    seed = recorded.particle % recorded.seeds
    same = (seed[:, None] == seed[None, :200]) & (
        recorded.frame[:, None] == recorded.frame[None, :200]
    )
    i, j = np.nonzero(same)
    shift = (recorded.position[i] - recorded.position[j]) / flow.L
    np.testing.assert_allclose(shift, np.round(shift), atol=1e-9)
    np.testing.assert_array_equal(recorded.acceleration[i], recorded.acceleration[j])
    assert len(np.unique(recorded.particle)) > recorded.seeds  # images kept, not only seeds
