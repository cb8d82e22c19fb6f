"""The PTV analysis ranges a scenario leaves out, derived from its rig and its flow.

A scenario that gives no ``[ptv] analysis_size``, ``r_min``, ``r_max`` or ``plateau`` gets them
from the rig's laser sheet (width W, height H, thickness T) and the flow's Kolmogorov
length η and integral length L_int = u′³/ε:

- analysis volume 0.7 W × 0.7 H × 0.8 T: the well-lit core of the sheet, away from its
  dim wings and the edges of the cameras' common view (70 × 70 × 8 mm on the paper's
  100 × 100 × 10 mm sheet);
- r_min = 10η and r_max = min(half the analysis volume's smaller side, L_int): no
  bin below the dissipative range's start, none beyond what the volume holds in every
  direction of the sheet's plane;
- plateau from 40η to min(L_int / 2, 0.6 r_max): the inertial range, the same
  40η … L_int / 2 in which c1 is checked against the truth (``[checks]``), kept clear
  of the last bins where few pairs fit in the volume. Where 40η lies beyond that end (a
  slow flow whose η is large against the volume), the widest plateau the volume allows
  is taken instead, from 10η to the same end, with a warning; the
  report names it as starting below 40η (:func:`validation.run.verdict.plateau_row`).

A DNS has no L_int before it runs, and its periodic box (half of it 22η at 64³, 45η at
128³) leaves no 40η … L_int/2 range: a DNS scenario gives its r range and plateau
(validation/run/scenario.py refuses one that does not). A field file is read only later:
its r range and plateau keep the paper-flow defaults (0.5–35 mm, 2–20 mm) with a
warning that they were not derived.
"""

import logging
from dataclasses import replace

import numpy as np

from ptv.pipeline.double_frame import AMBIGUITY_WARNING
from ptv.settings import PipelineSettings
from validation.run.scenario_fields import ScenarioError

__all__ = ["DERIVED_FIELDS", "derive_ptv_ranges", "independent_pair_ambiguity"]

log = logging.getLogger(__name__)

#: The [ptv] fields derived when a scenario leaves them out.
DERIVED_FIELDS = ("analysis_size", "r_min", "r_max", "plateau")
#: Analysis volume as fractions of the sheet's width, height and thickness.
SHEET_FRACTION = (0.7, 0.7, 0.8)
#: r_min and the plateau's start, in η.
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
        A derived range that comes out empty (a flow whose 10η exceeds what the sheet
        holds).
    """
    ptv = scenario.ptv
    values = {}
    if "analysis_size" not in given:
        values["analysis_size"] = tuple(
            round(float(f * s), 9) for f, s in zip(SHEET_FRACTION, sheet_size, strict=True)
        )
    volume = values.get("analysis_size", ptv.analysis_size)
    missing = [name for name in ("r_min", "r_max", "plateau") if name not in given]
    if scales is None:
        for name in missing:
            mm = "–".join(f"{v * 1e3:g}" for v in np.atleast_1d(getattr(ptv, name)))
            log.warning(
                "%s: ptv.%s = %s mm is the paper flow's default, not derived: this flow's "
                "integral length is known only once it is run; set it to this flow's ranges",
                source,
                name,
                mm,
            )
    else:
        eta, l_int = scales["eta"], scales["L_int"]
        r_max = min(0.5 * min(volume[0], volume[1]), l_int)
        plateau_max = min(PLATEAU_MAX_L_INT * l_int, PLATEAU_MAX_R * r_max)
        derived = {
            "r_min": R_MIN_ETA * eta,
            "r_max": r_max,
            "plateau": (PLATEAU_MIN_ETA * eta, plateau_max),
        }
        lo, hi = derived["plateau"]
        if "plateau" in missing and not lo < hi and R_MIN_ETA * eta < hi:
            log.warning(
                "%s: ptv.plateau derived from the flow would start at 40η = %.3g mm, beyond "
                "the %.3g mm the analysis volume allows; it takes the widest plateau the "
                "volume allows, from 10η = %.3g mm (below 40η: ε(r) there is not yet "
                "inertial; the checks compare like with like, the exact trajectories' ε over "
                "the same range)",
                source,
                lo * 1e3,
                hi * 1e3,
                R_MIN_ETA * eta * 1e3,
            )
            derived["plateau"] = (R_MIN_ETA * eta, hi)
        values.update({name: derived[name] for name in missing})
        ranges = (
            ("r_min and ptv.r_max", ("r_min", "r_max")),
            ("plateau", ("plateau",)),
        )
        for where, names in ranges:
            if not set(names) & set(missing):
                continue
            lo, hi = np.ravel([values.get(name, getattr(ptv, name)) for name in names])
            if not 0 < lo < hi:
                raise ScenarioError(
                    f"{source}: ptv.{where} derived from the flow (η = {eta * 1e3:.3g} mm) "
                    "and the analysis volume comes out empty "
                    f"({lo * 1e3:.3g}–{hi * 1e3:.3g} mm): set it"
                )
        values = {
            name: tuple(map(float, value)) if isinstance(value, tuple) else float(value)
            for name, value in values.items()
        }
    if values:
        shown = (
            f"ptv.{k} = {np.round(np.asarray(v) * 1e3, 3).tolist()} mm" for k, v in values.items()
        )
        log.info("%s: derived %s", source, ", ".join(shown))
    return replace(scenario, ptv=replace(ptv, **values))


#: The link ambiguity (a second particle within the link radius) above which the links
#: of independent frame pairs are warned about before the run: the run's own limit,
#: which it warns about after.
AMBIGUITY_LIMIT = AMBIGUITY_WARNING


def independent_pair_ambiguity(scenario, sheet_size, u_rms: float, source: str) -> np.ndarray:
    """How ambiguous the links of independent frame pairs will be at each Δt, known
    before the run, with a warning naming the Δt beyond the limit.

    Independent pairs (``[particles] shared_first_frame = false``) are linked within
    max_speed·Δt + 5σ_b of X(t) at every Δt, with no smaller Δt to predict from
    (docs/ptv.md §4). With max_speed ≈ 5u′ (the measured one is |U| + 5 max_i σ_i, σ_i
    the rms of one component's velocity, and |U| ≈ 0 here) and the tracers spread
    uniformly through the sheet at density n, a second particle falls within the radius r
    with probability 1 − exp(−n·(4/3)πr³).

    Parameters
    ----------
    scenario : Scenario
        Its particle count, Δt set and position noise.
    sheet_size : sequence of 3 float
        The rig's sheet, m.
    u_rms : float
        The flow's u′, m/s.
    source : str
        The file, for the warning.

    Returns
    -------
    ndarray, shape (K,)
        The expected ambiguity at each Δt.
    """
    dt = np.asarray(scenario.flow.as_preset().dt, dtype=float)
    density = scenario.particles.count / float(np.prod(sheet_size))
    radius = 5 * u_rms * dt + 5 * PipelineSettings().position_noise
    ambiguity = 1 - np.exp(-density * 4 / 3 * np.pi * radius**3)
    over = np.flatnonzero(ambiguity > AMBIGUITY_LIMIT)
    if over.size:
        fits = dt[ambiguity <= AMBIGUITY_LIMIT]
        log.warning(
            "%s: independent frame pairs (shared_first_frame = false): at Δt = %s ms the link "
            "radius (about %s mm) will reach the particles' spacing (%.3g mm) and about %s %% "
            "of the links will have a second candidate; the largest Δt this seeding links "
            "unambiguously is %s. Share the first frame, seed fewer particles or shorten Δt.",
            source,
            ", ".join(f"{v * 1e3:.3g}" for v in dt[over]),
            ", ".join(f"{v * 1e3:.2g}" for v in radius[over]),
            0.554 * density ** (-1 / 3) * 1e3,
            ", ".join(f"{100 * v:.0f}" for v in ambiguity[over]),
            f"{fits.max() * 1e3:.3g} ms" if fits.size else "below the smallest Δt",
        )
    return ambiguity
