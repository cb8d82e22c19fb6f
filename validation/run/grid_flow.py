"""A run on a periodic field file of one's own (``[flow] kind = "grid"``, docs/dns.md §12).

No stage: the tracers follow the file (:mod:`simulator.dns.series_flow`), which the
inputs of the stages that read the particles name by its SHA-256.
"""

import hashlib
import logging
from pathlib import Path

import numpy as np

from simulator.dns.series_flow import SeriesTracerFlow, series_scales, snapshot_starts
from simulator.turbulence import TurbulenceParameters
from validation.run.flow_section import FlowSection
from validation.run.run_flow import RunFlow
from validation.truth.exact import ModalStructure

log = logging.getLogger(__name__)


def file_digest(path: Path) -> str:
    """SHA-256 of a file, hex."""
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def grid_run_flow(flow: FlowSection, frames: int) -> RunFlow:
    """A periodic field file (``kind = "grid"``): the run's M snapshots spread evenly
    over the file, each followed over the Δt set (:mod:`simulator.dns.series_flow`).

    Parameters
    ----------
    flow : FlowSection
        A ``grid`` flow (its file's path resolved).
    frames : int
        The run's snapshots M.

    Raises
    ------
    ValueError
        Naming the file: a missing file, what
        :func:`simulator.dns.series_flow.series_scales` refuses, or a file shorter than
        the largest Δt.
    """
    path = Path(flow.file)
    if not path.is_file():
        raise ValueError(f"{path}: no such file")
    scales = series_scales(path)
    parameters = TurbulenceParameters(u_rms=scales.u_rms, epsilon=scales.epsilon, nu=scales.nu)
    preset = flow.as_preset(parameters)
    try:
        starts = snapshot_starts(scales.times, frames, float(preset.dt[-1]))
    except ValueError as err:
        raise ValueError(f"{path}: {err}") from None
    spacing = starts[1] - starts[0] if len(starts) > 1 else np.inf
    if spacing < scales.eddy_time:
        log.warning(
            "%s: the %d snapshots of the run are %.2g eddy times T_L apart in the file: they "
            "are not independent, and the bootstrap errors read low",
            path,
            len(starts),
            spacing / scales.eddy_time,
        )
    measured = {
        "box_side": scales.box_side,
        "integral_scale": scales.integral_scale,
        "eddy_time": scales.eddy_time,
        "file_step": scales.file_step,
        "file_snapshots": len(scales.times),
        "snapshot_spacing": float(spacing) if np.isfinite(spacing) else None,
    }
    digest = file_digest(path)
    attrs = {"kind": "grid", "file": str(path), "sha256": digest, "n": scales.n}
    attrs.update({k: v for k, v in measured.items() if v is not None})
    return RunFlow(
        preset=preset,
        tracers=SeriesTracerFlow(path.resolve(), starts, scales.u_rms),
        attrs=attrs,
        exact=ModalStructure(scales.shell_k, scales.shell_energy),
        datasets={"shell_k": scales.shell_k, "shell_energy": scales.shell_energy},
        scales={**flow.scales(parameters), **measured},
        inputs={**flow.as_dict(), "sha256": digest},
    )
