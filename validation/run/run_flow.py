"""What a run's particles follow and what their statistics are checked against, whatever
the kind of flow (:mod:`validation.run.flow_stage`, :mod:`validation.run.grid_flow`)."""

from dataclasses import dataclass
from pathlib import Path

from simulator.presets import FlowPreset
from validation.dataset.render import DatasetFlow
from validation.truth.exact import ExactStructure


@dataclass(frozen=True)
class RunFlow:
    """The flow of a run.

    Attributes
    ----------
    preset : FlowPreset
        u′, ε, ν (u′ measured for a DNS) and the Δt set.
    dataset : DatasetFlow
        What the particles follow and what truth.h5 records of the flow.
    exact : ExactStructure
        Its exact D_LL.
    scales : dict
        The flow and its scales for results.json (``flow``).
    inputs : dict
        What the particles depend on (for the keys of the stages that read them).
    field : Path or None
        A DNS's folder (its field and statistics files); None for KS.
    """

    preset: FlowPreset
    dataset: DatasetFlow
    exact: ExactStructure
    scales: dict
    inputs: dict
    field: Path | None = None
