"""Tracers in a field file: interpolation in time, and agreement with the DNS itself."""

import h5py
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from simulator.dns.fieldfile import FieldFileWriter
from simulator.dns.grid import dns_setup
from simulator.dns.series_flow import (
    SeriesInterpolator,
    follow_in_series,
    lagrange_weights,
    series_scales,
    snapshot_starts,
)
from simulator.dns.spinup import stationary_flow
from simulator.dns.tracers import follow_tracers

NU, EPSILON = 1e-6, 1e-5


@given(
    start=st.floats(-5, 5),
    gaps=st.lists(st.floats(0.1, 2.0), min_size=3, max_size=3),
    where=st.floats(-0.5, 1.5),
    coefficients=st.lists(st.floats(-3, 3), min_size=4, max_size=4),
)
def test_the_time_weights_are_exact_for_cubics_and_their_derivative(
    start, gaps, where, coefficients
):
    nodes = start + np.concatenate([[0.0], np.cumsum(gaps)])
    t = nodes[0] + where * (nodes[-1] - nodes[0])
    cubic = np.polynomial.Polynomial(coefficients)
    weights, derivative = lagrange_weights(nodes, t)
    scale = 1 + np.abs(cubic(nodes)).max() + abs(t) ** 3
    assert weights @ cubic(nodes) == pytest.approx(cubic(t), abs=1e-9 * scale)
    assert derivative @ cubic(nodes) == pytest.approx(cubic.deriv()(t), abs=1e-8 * scale)


@pytest.fixture(scope="module")
def dns_file(tmp_path_factory):
    """A stationary 32³ flow written at every solver step for 12 steps, its solver, the
    states and the step."""
    setup = dns_setup(NU, EPSILON, 32)
    states = []
    solver, _ = stationary_flow(setup, snapshots=1, rng=0, on_snapshot=states.append)
    h = solver.max_step(states[0])
    path = tmp_path_factory.mktemp("series") / "field.h5"
    with FieldFileWriter(
        path, n=32, box_side=setup.grid.box_side, nu=NU, epsilon=EPSILON
    ) as writer:
        state = states[0]
        writer.append(state.time, solver.velocity(state))
        for _ in range(12):
            state = solver.advance(state, h)
            states.append(state)
            writer.append(state.time, solver.velocity(state))
    return path, solver, states, h


def _subsampled(path, every, target):
    with (
        h5py.File(path) as f,
        FieldFileWriter(
            target, n=32, box_side=float(f.attrs["box_side"]), nu=NU, epsilon=EPSILON
        ) as writer,
    ):
        for j in range(0, f["times"].shape[0], every):
            writer.append(float(f["times"][j]), np.stack([f[c][j] for c in "uvw"]))
    return target


def test_tracers_in_the_file_follow_the_tracers_of_the_dns_to_fourth_order(dns_file, tmp_path):
    path, solver, states, h = dns_file
    x0 = np.random.default_rng(4).uniform(0, solver.grid.box_side, (300, 3))
    times = np.arange(5) * h  # from the file's 4th snapshot: interior windows
    truth, _ = follow_tracers(solver, states[4], x0, times)
    u_rms = np.sqrt(np.mean(truth.velocity**2))
    a_rms = np.sqrt(np.mean(truth.acceleration**2))
    errors, acceleration_error = [], None
    for every in (1, 2, 4):
        file = path if every == 1 else _subsampled(path, every, tmp_path / f"every{every}.h5")
        _, velocity, acceleration = follow_in_series(
            SeriesInterpolator(file), x0, states[4].time, times
        )
        errors.append(np.sqrt(np.mean((velocity - truth.velocity) ** 2)) / u_rms)
        if every == 1:
            acceleration_error = np.sqrt(np.mean((acceleration - truth.acceleration) ** 2))
    # measured on 64³ (docs/dns.md §12): 2e-6, 9e-5, 1.1e-3 of u' at 1, 2, 4 steps;
    # the cubic in time errs as its step to the fourth power (16× per doubling)
    assert errors[0] < 1e-4
    assert errors[2] > 8 * errors[1] > 8 * errors[0]
    # ∂u/∂t from the cubic's derivative: 0.1 % of a_rms at one step on 64³
    assert acceleration_error < 5e-3 * a_rms


def test_a_file_is_refused_by_name_when_it_cannot_serve(dns_file, tmp_path):
    path, *_ = dns_file
    short = tmp_path / "short.h5"
    with (
        h5py.File(path) as f,
        FieldFileWriter(
            short, n=32, box_side=float(f.attrs["box_side"]), nu=NU, epsilon=EPSILON
        ) as writer,
    ):
        for j in range(3):
            writer.append(float(f["times"][j]), np.stack([f[c][j] for c in "uvw"]))
    with pytest.raises(ValueError, match=r"short\.h5: 3 snapshot\(s\).*at least 4"):
        series_scales(short)
    scales = series_scales(path)
    with pytest.raises(ValueError, match="less than the largest"):
        snapshot_starts(scales.times, 5, 2 * (scales.times[-1] - scales.times[0]))
    starts = snapshot_starts(scales.times, 5, scales.file_step)
    assert starts[0] == scales.times[0] and starts[-1] == pytest.approx(
        scales.times[-1] - scales.file_step
    )
    interpolator = SeriesInterpolator(path)
    with pytest.raises(ValueError, match="outside the file's times"):
        follow_in_series(interpolator, np.zeros((1, 3)), scales.times[-1], np.array([0, 1.0]))


def test_the_scales_of_a_file_are_those_of_its_fields(dns_file):
    path, solver, states, _ = dns_file
    scales = series_scales(path)
    velocity = np.stack([solver.velocity(s) for s in states])
    assert scales.u_rms == pytest.approx(np.sqrt(np.mean(velocity**2)), rel=1e-12)
    # the modes' energies sum to the kinetic energy ½⟨|u|²⟩ of the mean snapshot
    energy = 0.5 * np.mean(np.sum(velocity**2, axis=1))
    assert scales.shell_energy.sum() == pytest.approx(energy, rel=1e-9)
