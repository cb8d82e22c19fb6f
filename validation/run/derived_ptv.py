"""The PTV analysis ranges a scenario leaves out, derived from its rig and its flow.

A scenario that gives no ``[ptv] analysis_volume``, ``r_range`` or ``plateau`` gets them
from the rig's laser sheet (width W, height H, thickness T) and the flow's Kolmogorov
length η and integral length L_int = u′³/ε:

- analysis volume 0.7 W × 0.7 H × 0.8 T: the well-lit core of the sheet, away from its
  dim wings and the edges of the cameras' common view (70 × 70 × 8 mm on the paper's
  100 × 100 × 10 mm sheet);
- r range from 10η to r_max = min(half the analysis volume's smaller side, L_int): no
  bin below the dissipative range's start, none beyond what the volume holds in every
  direction of the sheet's plane;
- plateau from 40η to min(L_int / 2, 0.6 r_max): the inertial range, the same
  40η … L_int / 2 in which c1 is checked against the truth (``[checks]``), kept clear
  of the last bins where few pairs fit in the volume.

A DNS has no L_int before it runs, and its periodic box (half of it 22η at 64³, 45η at
128³) leaves no 40η … L_int/2 range: a DNS scenario gives its r range and plateau
(validation/run/scenario.py refuses one that does not). A field file is read only later:
its r range and plateau keep the paper-flow defaults (0.5–35 mm, 2–20 mm) with a
warning that they were not derived.
"""

import logging
from dataclasses import replace

import numpy as np

from validation.run.scenario_fields import ScenarioError

__all__ = ["DERIVED_FIELDS", "derive_ptv_ranges"]

log = logging.getLogger(__name__)

#: The [ptv] fields derived when a scenario leaves them out.
DERIVED_FIELDS = ("analysis_volume", "r_range", "plateau")
#: Analysis volume as fractions of the sheet's width, height and thickness.
SHEET_FRACTION = (0.7, 0.7, 0.8)
#: r range and plateau starts, in η.
R_MIN_ETA = 10.0
PLATEAU_MIN_ETA = 40.0
#: Plateau end as fractions of L_int and of r_max.
PLATEAU_MAX_L_INT = 0.5
PLATEAU_MAX_R = 0.6


def derive_ptv_ranges(scenario, given: set[str], sheet_size, scales: dict | None, source: str):
    """The scenario with the [ptv] fields it leaves out derived (module docstring).

    Parameters
    ----------
    scenario : validation.run.scenario.Scenario
        As read, with the paper-flow defaults in the fields left out.
    given : set of str
        The [ptv] fields its file gives.
    sheet_size : sequence of 3 float
        The rig's sheet: width, height, thickness, m.
    scales : dict or None
        The flow's ``eta`` and ``L_int``, m (None: not known before the run).
    source : str
        The file, for messages.

    Returns
    -------
    Scenario

    Raises
    ------
    ScenarioError
        A derived range that comes out empty (a flow whose 40η exceeds what the sheet holds).
    """
    ptv = scenario.ptv
    values = {}
    if "analysis_volume" not in given:
        values["analysis_volume"] = tuple(
            round(float(f * s), 9) for f, s in zip(SHEET_FRACTION, sheet_size, strict=True)
        )
    volume = values.get("analysis_volume", ptv.analysis_volume)
    missing = [name for name in ("r_range", "plateau") if name not in given]
    if scales is None:
        for name in missing:
            lo, hi = getattr(ptv, name)
            log.warning(
                "%s: ptv.%s = %g–%g mm is the paper flow's default, not derived: this flow's "
                "integral length is known only once it is run; set it to this flow's ranges",
                source,
                name,
                lo * 1e3,
                hi * 1e3,
            )
    else:
        eta, l_int = scales["eta"], scales["L_int"]
        r_max = min(0.5 * min(volume[0], volume[1]), l_int)
        plateau_max = min(PLATEAU_MAX_L_INT * l_int, PLATEAU_MAX_R * r_max)
        derived = {
            "r_range": (R_MIN_ETA * eta, r_max),
            "plateau": (PLATEAU_MIN_ETA * eta, plateau_max),
        }
        for name in missing:
            lo, hi = derived[name]
            if not 0 < lo < hi:
                raise ScenarioError(
                    f"{source}: ptv.{name} derived from the flow (η = {eta * 1e3:.3g} mm) and "
                    "the analysis volume comes out empty "
                    f"({lo * 1e3:.3g}–{hi * 1e3:.3g} mm): set it"
                )
            values[name] = (float(lo), float(hi))
    if values:
        shown = (
            f"ptv.{k} = {np.round(np.asarray(v) * 1e3, 3).tolist()} mm" for k, v in values.items()
        )
        log.info("%s: derived %s", source, ", ".join(shown))
    return replace(scenario, ptv=replace(ptv, **values))
