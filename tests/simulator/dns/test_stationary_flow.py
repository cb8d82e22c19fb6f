"""A stationary DNS as the flow of an experiment: its stage files and its tracers."""

import h5py
import numpy as np
import pytest

from simulator.dns.fieldfile import read_field_file, read_field_file_parameters
from simulator.dns.stationary_flow import (
    FIELD_FILE,
    STATISTICS_FILE,
    DnsSpec,
    DnsTracerFlow,
    build_stationary_field,
)
from simulator.particles import Box, follow_snapshots

SPEC = DnsSpec(nu=1e-6, epsilon=1e-5, n=32, snapshots=2, spacing=1.0, seed=3)


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    target = tmp_path_factory.mktemp("flow")
    build_stationary_field(SPEC, target)
    return target


def test_the_stage_holds_one_field_and_its_statistics_per_snapshot(folder):
    series = read_field_file(folder / FIELD_FILE)
    assert series.velocity.shape == (2, 3, 32, 32, 32)
    measured = read_field_file_parameters(folder / FIELD_FILE)
    # the window's scales: the box from ν, ε, N, k_max η; snapshots one T_L apart
    assert measured.box_side == pytest.approx(SPEC.setup().grid.box_side)
    assert np.diff(series.times)[0] == pytest.approx(measured.eddy_time, rel=0.5)
    with h5py.File(folder / STATISTICS_FILE) as f:
        assert f["s3"].shape[0] == 2 and f["shell_energy"].shape[0] == 2
        # Σ of the modes' energies is the kinetic energy of the snapshot
        energy = 0.5 * np.mean(np.sum(series.velocity[0] ** 2, axis=0))
        assert f["shell_energy"][0].sum() == pytest.approx(energy, rel=1e-9)


def test_tracers_start_on_the_snapshot_and_carry_its_velocity(folder):
    flow = DnsTracerFlow(SPEC, folder / FIELD_FILE, u_rms=0.006)
    region = Box((0.02, 0.02, 0.004))
    times = np.array([0.0, 0.01, 0.03])
    first = follow_snapshots(flow, times, particles=50, snapshots=2, region=region, rng=7)
    again = follow_snapshots(flow, times, particles=50, snapshots=2, region=region, rng=7, first=1)
    assert np.array_equal(first.positions[1:], again.positions)  # snapshot 1 alone, same bits
    # The velocity at t is the snapshot's field at the tracers, to the spline's accuracy
    series = read_field_file(folder / FIELD_FILE)
    x = first.positions[0, 0]
    box = series.box_side
    n = np.rint(np.mod(x, box) / (box / 32)).astype(int) % 32
    nearest = series.velocity[0][:, n[:, 0], n[:, 1], n[:, 2]].T
    u_rms = np.sqrt(np.mean(series.velocity[0] ** 2))
    # within half a grid spacing of its node the field differs by |∇u|Δx/2 ~ u'Δx/λ, a
    # fraction of u' (Δx = 1.6 mm, λ ≈ 7 mm); another snapshot's field differs by √2 u'
    error = np.sqrt(np.mean((first.velocity[0, 0] - nearest) ** 2))
    assert error < 0.5 * u_rms
    # displacements over Δt agree with the velocity to first order
    d = first.positions[0, 1] - first.positions[0, 0]
    assert np.allclose(d, first.velocity[0, 0] * times[1], atol=0.1 * u_rms * times[1] + 1e-12)


def test_a_recording_of_the_dns_keeps_every_trajectory_whole(folder):
    """A recording (simulator.recording.follow_periodic_recording) of the box's tracers
    and their periodic images across a sheet two boxes wide: every trajectory is
    continuous (its second differences are a·τ² to the time step's accuracy, not a fold
    of the box, L = 25 mm) and its velocity the centred difference of its positions."""
    from simulator.recording import follow_periodic_recording

    flow = DnsTracerFlow(SPEC, folder / FIELD_FILE, u_rms=0.006)
    side = SPEC.setup().grid.box_side
    region = Box((2 * side, 2 * side, 0.004))
    tau = 0.03  # s, τ_η/10
    recorded = follow_periodic_recording(
        flow, side, 1 / tau, 12, particles=100, region=region, rng=2
    )
    assert np.all(region.contains(recorded.position))
    worst, velocity_error, scale = 0.0, 0.0, 0.0
    for p in np.unique(recorded.particle):
        rows = recorded.particle == p
        x, u, a = (v[rows] for v in (recorded.position, recorded.velocity, recorded.acceleration))
        if len(x) < 3:
            continue
        assert np.all(np.diff(recorded.frame[rows]) == 1)
        worst = max(worst, np.abs(np.diff(x, 2, axis=0) - a[1:-1] * tau**2).max())
        velocity_error = max(velocity_error, np.abs((x[2:] - x[:-2]) / (2 * tau) - u[1:-1]).max())
        scale = max(scale, np.abs(u).max())
    # a·τ² is about 10 µm here and its change over a frame a fraction of it
    assert worst < 1e-5
    assert velocity_error < 0.05 * scale
