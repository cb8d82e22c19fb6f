"""The flow of a run: what its particles follow and what their statistics are checked
against (docs/run.md §7, docs/dns.md §10).

Kinematic simulation needs no stage: each snapshot draws its realization (a field file
of one's own needs none either: :mod:`validation.run.grid_flow`). A DNS is a stage of its
own, ``DIR/flow``: the stationary
field, one snapshot per snapshot of the run, and the exact statistics of every snapshot
(:mod:`simulator.dns.stationary_flow`). It is keyed by the flow's inputs, the number of snapshots
and the seed, so a second run, or a study, reuses it.
"""

import os
from dataclasses import asdict, replace
from importlib.metadata import version
from pathlib import Path

import h5py
import numpy as np

from simulator.dns.fieldfile import read_field_file_parameters
from simulator.dns.stationary_flow import (
    FIELD_FILE,
    STATISTICS_FILE,
    DnsSpec,
    DnsTracerFlow,
    build_stationary_field,
)
from simulator.turbulence import TurbulenceParameters
from validation.run.render_dataset import RenderSettings, ks_flow
from validation.run.run_flow import RunFlow
from validation.run.scenario import Scenario
from validation.truth.exact import ModalStructure
from validation.workflow.stages import StageOutcome, run_stage


def ks_run_flow(scenario: Scenario, settings: RenderSettings) -> RunFlow:
    """Kinematic simulation: no stage, the flow as the scenario gives it."""
    return replace(
        ks_flow(scenario.flow.as_preset(), settings),
        scales=scenario.flow.scales(),
        inputs=scenario.as_dict()["flow"],
    )


def dns_spec(scenario: Scenario) -> DnsSpec:
    """The DNS of a scenario: one field snapshot per snapshot of the run."""
    flow = scenario.flow
    return DnsSpec(
        nu=flow.nu,
        epsilon=flow.epsilon,
        n=flow.grid,
        snapshots=scenario.particles.frames,
        kmax_eta=flow.kmax_eta,
        spacing=flow.spacing,
        seed=scenario.seed,
    )


def dns_run_flow(
    scenario: Scenario, out: Path, *, progress=None, workers: int | None = None
) -> tuple[RunFlow, StageOutcome]:
    """Build (or reuse) the DNS stage ``out/flow`` and the run's flow from it.

    The stage runs alone, before any chunk: its FFTs use ``workers`` threads (default:
    every CPU; the values do not depend on it, the transforms being split by lines).
    """
    spec = dns_spec(scenario)
    workers = workers or os.cpu_count() or 1
    inputs = {"synptv": version("synptv"), "spec": asdict(spec)}
    stage = run_stage(
        out / "flow",
        inputs,
        lambda target: _build_stage(spec, target, progress, workers),
        name="flow",
    )
    measured = read_field_file_parameters(stage.folder / FIELD_FILE)
    parameters = TurbulenceParameters(u_rms=measured.u_rms, epsilon=spec.epsilon, nu=spec.nu)
    preset = scenario.flow.as_preset(parameters)
    with h5py.File(stage.folder / STATISTICS_FILE, "r") as f:
        k, energy = f["shell_k"][()], np.mean(f["shell_energy"][()], axis=0)
    measured_scales = {
        "box_side": measured.box_side,
        "epsilon_dissipation": measured.epsilon,
        "r_lambda_measured": measured.r_lambda,
        "integral_scale": measured.integral_scale,
        "eddy_time": measured.eddy_time,
        "kmax_eta_measured": measured.kmax_eta,
    }
    attrs = {"kind": "dns", "grid": spec.n, "kmax_eta": spec.kmax_eta, **measured_scales}
    tracers = DnsTracerFlow(spec, stage.folder / FIELD_FILE, measured.u_rms)
    flow = RunFlow(
        preset=preset,
        tracers=tracers,
        attrs=attrs,
        exact=ModalStructure(k, energy),
        datasets={"shell_k": k, "shell_energy": energy},
        scales={**scenario.flow.scales(parameters), **measured_scales},
        inputs={**scenario.as_dict()["flow"], "field": stage.key},
        field=stage.folder,
    )
    return flow, stage


def _build_stage(spec: DnsSpec, target: Path, progress, workers: int) -> None:
    target.mkdir()
    build_stationary_field(spec, target, progress=progress, workers=workers)
