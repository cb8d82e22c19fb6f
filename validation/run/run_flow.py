"""The flow of a run: what its particles follow, what truth.h5 records of it and what its
statistics are checked against, whatever the kind of flow (KS:
:func:`validation.run.render_dataset.ks_flow`; DNS: :mod:`validation.run.flow_stage`;
a DNS file: :mod:`validation.run.grid_flow`)."""

import dataclasses
from dataclasses import dataclass
from pathlib import Path

from simulator.particles import TracerFlow
from simulator.presets import FlowPreset
from validation.truth.exact import ExactStructure


@dataclass(frozen=True)
class RunFlow:
    """The flow of a run.

    Attributes
    ----------
    preset : FlowPreset
        u′, ε, ν (u′ measured for a DNS) and the Δt set.
    tracers : TracerFlow
        What follows each snapshot's particles (:mod:`simulator.particles`).
    attrs : dict
        Attributes of truth.h5's ``/flow`` beside the scales (KS: spectrum, n_modes,
        unsteadiness).
    exact : ExactStructure
        Its exact D_LL.
    datasets : dict of ndarray
        Datasets of ``/flow`` (a DNS: ``shell_k``, ``shell_energy``).
    scales : dict
        The flow and its scales for results.json (``flow``; empty outside a run).
    inputs : dict
        What the particles depend on, for the keys of the stages that read them (empty
        outside a run).
    field : Path or None
        A DNS's folder (its field and statistics files); None for KS.
    """

    preset: FlowPreset
    tracers: TracerFlow
    attrs: dict
    exact: ExactStructure
    datasets: dict = dataclasses.field(default_factory=dict)
    scales: dict = dataclasses.field(default_factory=dict)
    inputs: dict = dataclasses.field(default_factory=dict)
    field: Path | None = None
