"""The DNS mutations, out of every claim's reach, fail the required checks of a DNS run
they name (``Mutation.run_checks``; docs/claims.md §5), shown on a 32³ flow (slow: a
flow spun up twice: 3 min on two cores shared with other work).

The run's checks are computed as ``synptv run`` computes them
(:mod:`validation.run.dns_checks`) from what its flow stage writes
(:func:`simulator.dns.stationary_flow.build_stationary_field`) and from tracers followed
with the flow from every snapshot over dns-ci's Δt set
(:class:`simulator.dns.stationary_flow.DnsTracerFlow`), seeded in the whole box.
"""

import numpy as np
import pytest

from simulator.dns.fieldfile import read_snapshot
from simulator.dns.stationary_flow import (
    FIELD_FILE,
    DnsSpec,
    DnsTracerFlow,
    build_stationary_field,
    separation_shifts,
    snapshot_statistics,
)
from simulator.particles import Box
from validation.mutations import MUTATIONS, mutation
from validation.mutations.report import kill_table
from validation.mutations.runner import Outcome
from validation.run import dns_checks

NU, EPSILON = 1e-6, 1e-5
#: dns-ci's Δt set, in τ_η.
DT_TAU_ETA = np.array([0.04, 0.08, 0.12, 0.17, 0.21])
TRACERS = 2000
ETA, TAU_ETA = (NU**3 / EPSILON) ** 0.25, (NU / EPSILON) ** 0.5


def _flow(folder, snapshots: int):
    spec = DnsSpec(nu=NU, epsilon=EPSILON, n=32, snapshots=snapshots, spacing=1.0, seed=0)
    run = build_stationary_field(spec, folder)
    return spec, run.parameters


def _tracers(spec, folder, parameters):
    """Positions (M, T, P, 3) over 0 and the Δt set, and velocities at t (M, P, 3)."""
    times = np.concatenate([[0.0], DT_TAU_ETA * TAU_ETA])
    flow = DnsTracerFlow(spec, folder / FIELD_FILE, parameters.u_rms)
    side = parameters.box_side
    box = Box((side, side, side), (side / 2, side / 2, side / 2))
    positions, velocity = [], []
    for m, rng in enumerate(np.random.default_rng(1).spawn(spec.snapshots)):
        p, v, _ = flow.follow_snapshot(m, rng, box, TRACERS, times)
        positions.append(p)
        velocity.append(v[0])
    return times, np.array(positions), np.array(velocity)


@pytest.fixture(scope="module")
def honest(tmp_path_factory):
    """A 32³ flow of 12 snapshots one T_L apart, its tracers and its checks."""
    folder = tmp_path_factory.mktemp("honest")
    spec, parameters = _flow(folder, 12)
    times, positions, velocity = _tracers(spec, folder, parameters)
    field = dns_checks.field_statistics(folder)
    return {
        "spec": spec,
        "folder": folder,
        "parameters": parameters,
        "tracers": (times, positions, velocity),
        "field": field,
        "checks": dns_checks.field_checks(field, parameters.eddy_time),
        "flux": dns_checks.tracer_flux(field, times, positions, velocity, eta=ETA, seed=0),
    }


def test_every_mutation_out_of_the_claims_names_the_run_checks_that_kill_it():
    for chosen in MUTATIONS:
        if not chosen.expected:
            assert chosen.run_checks, f"{chosen.name}: neither claims nor run checks kill it"
    assert mutation("dns-acceleration-gradient-transposed").run_checks == ("dns.tracer_flux",)
    assert "dns.energy_budget" in mutation("dns-forcing-doubled").run_checks


def test_the_claims_runner_reports_them_as_killed_by_run_checks():
    chosen = mutation("dns-forcing-doubled")
    outcome = Outcome(chosen, (), ("stats.epsilon_recovered",), {}, 0.1)
    assert outcome.status == "run checks"
    assert outcome.ok
    assert any("the run's dns.energy_budget" in line for line in kill_table([outcome]))


@pytest.mark.slow
def test_the_honest_flow_passes_the_tracer_flux_check(honest):
    flux = honest["flux"]
    assert flux["passed"], flux
    assert flux["field"] > 0.2  # ⟨δu·δa⟩/(−2ε) near its peak at 10η
    assert flux["acceleration_fit"]["relative"] < 1e-2


@pytest.mark.slow
def test_the_transposed_gradient_fails_the_tracer_flux_check(honest):
    """The flow and the tracers' positions do not pass through the acceleration code, so
    only the statistics the flow stage writes change: they are recomputed from the same
    snapshots under the mutation, as the stage computes them."""
    spec, folder = honest["spec"], honest["folder"]
    solver = spec.solver()
    shifts = separation_shifts(spec.n)
    field = dict(honest["field"])
    with mutation("dns-acceleration-gradient-transposed").applied():
        rows = []
        for m in range(spec.snapshots):
            time, velocity = read_snapshot(folder / FIELD_FILE, m)
            state = solver.state(velocity, time=time)
            rows.append(snapshot_statistics(solver, state, shifts, spec.band))
        field["du_da"] = np.stack([row["du_da"] for row in rows])
        field["dul_dal"] = np.stack([row["dul_dal"] for row in rows])
        times, positions, velocity = honest["tracers"]
        flux = dns_checks.tracer_flux(field, times, positions, velocity, eta=ETA, seed=0)
    assert abs(flux["field"]) < 0.1  # ⟨δu·δa⟩ ≈ ½∂_t⟨|δu|²⟩ ≈ 0
    assert not flux["passed"]
    assert abs(flux["difference"]) > 1.5 * flux["tolerance"]


@pytest.mark.slow
def test_the_doubled_forcing_fails_the_energy_budget_and_karman_howarth(honest, tmp_path):
    budget = honest["checks"]["energy_budget"]["dissipation_over_injection"]
    assert abs(budget - 1) < 0.05  # 10 T_L at 32³: the energy's drift, a few percent
    with mutation("dns-forcing-doubled").applied():
        _, parameters = _flow(tmp_path, 4)
    field = dns_checks.field_statistics(tmp_path)
    checks = dns_checks.field_checks(field, parameters.eddy_time)
    assert checks["energy_budget"]["dissipation_over_injection"] > 1.5
    assert not checks["energy_budget"]["passed"]
    assert not checks["karman_howarth"]["passed"]
