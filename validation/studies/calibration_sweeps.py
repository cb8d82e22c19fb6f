"""Calibration sweeps as Dask points: plane count and window obliquity.

One point is one plane count, or one (direction, obliquity) of the rig's windows.
Dots are exact projections through the windows plus Gaussian centre noise (no images).
The plate follows the scenario (``calibration.planes`` traverse positions, a
``realistic`` or ``ideal`` plate). Every point of a sweep draws the same plate, the
same dot noise and the same test points from the scenario seed (common random
numbers), so differences between points come from the swept parameter alone.
"""

from simulator.rigs import load_rig, rig_from_dict
from simulator.target import (
    REALISTIC,
    Imperfections,
    PhysicalPlate,
    PlateDesign,
    build_plate,
    traverse_positions,
)
from validation.run.scenario import Scenario, scenario_from_dict
from validation.studies.calibration_methods import obliquity_rows, plane_count_errors
from validation.studies.runner import Sweep, SweepPoint, seed_sequence
from validation.truth.calibration_errors import synthetic_plane_dots

#: Plane counts of the plane study (those above the scenario's traverse are dropped;
#: the full traverse is always included).
PLANE_COUNTS = (2, 3, 5, 7, 9, 13)
#: Window obliquities (°) and their directions (0: in the camera plane, 45: diagonal).
OBLIQUITIES_DEG = (0.0, 5.0, 10.0, 15.0, 20.0)
DIRECTIONS_DEG = (0.0, 45.0)


def scenario_plate(scenario: Scenario) -> PhysicalPlate:
    """The scenario's plate and traverse (its imperfections drawn from its seed)."""
    cal = scenario.calibration
    return build_plate(
        PlateDesign(),
        traverse_positions(cal.planes),
        imperfections=REALISTIC if cal.plate == "realistic" else Imperfections(),
        rng=seed_sequence(scenario.seed, "calibration study", "plate"),
    )


def planes_sweep(scenario: Scenario, *, noise_px: float) -> Sweep:
    """Plane counts from 2 to the scenario's traverse, model-free, on its rig.

    Parameters
    ----------
    scenario : Scenario
        Rig, plate, traverse and seed.
    noise_px : float
        Dot-centre noise, px.
    """
    total = scenario.calibration.planes
    counts = sorted({c for c in PLANE_COUNTS if c <= total} | {total})
    return Sweep(
        "planes",
        planes_task,
        scenario.as_dict(),
        _options(scenario, noise_px),
        tuple(SweepPoint(f"planes-{c:02d}", {"planes": c}) for c in counts),
    )


def obliquity_sweep(scenario: Scenario, *, noise_px: float) -> Sweep:
    """Window obliquity 0–20° in the camera plane and diagonally, every scenario method."""
    return Sweep(
        "obliquity",
        obliquity_task,
        scenario.as_dict(),
        _options(scenario, noise_px),
        tuple(
            SweepPoint(f"direction-{d:g}-obliquity-{a:g}", {"direction_deg": d, "obliquity_deg": a})
            for d in DIRECTIONS_DEG
            for a in OBLIQUITIES_DEG
        ),
    )


def _options(scenario: Scenario, noise_px: float) -> dict:
    """The options every point shares: dot noise, plate kind and the rig description."""
    if not noise_px >= 0:
        raise ValueError(f"--noise (dot-centre noise) must be >= 0 px, got {noise_px}")
    return {
        "noise_px": float(noise_px),
        "plate": scenario.calibration.plate,
        "rig": load_rig(scenario.rig.name).spec,
    }


def planes_task(settings: dict, options: dict, point: dict) -> dict:
    """One plane count: Table 1 and model errors of the model-free calibration.

    Parameters
    ----------
    settings : dict
        The scenario (:meth:`Scenario.as_dict`).
    options : dict
        ``noise_px`` (dot-centre noise, px) and ``rig`` (the rig description); ``plate``
        repeats the scenario's plate kind for the record.
    point : dict
        ``planes``: the number of planes, spanning the traverse.

    Returns
    -------
    dict
        ``rows``: one row of :func:`validation.studies.calibration_methods.plane_count_errors`
        (µm; the ratios to the full traverse are added over the whole sweep).
    """
    scenario = scenario_from_dict(settings)
    rig = rig_from_dict(options["rig"], source=scenario.rig.name)
    plate = scenario_plate(scenario)
    dots = synthetic_plane_dots(
        rig.cameras,
        plate,
        noise_px=options["noise_px"],
        rng=seed_sequence(scenario.seed, "planes", "dots"),
    )
    row = plane_count_errors(
        rig, plate, dots, point["planes"], rng=seed_sequence(scenario.seed, "planes", "points")
    )
    return {"rows": [row]}


def obliquity_task(settings: dict, options: dict, point: dict) -> dict:
    """One window obliquity: every method's Table 1 and model errors.

    Parameters
    ----------
    settings : dict
        The scenario (:meth:`Scenario.as_dict`); its ``calibration.methods`` are fitted.
    options : dict
        ``noise_px`` (dot-centre noise, px) and ``rig`` (the rig description whose
        windows are re-tilted).
    point : dict
        ``direction_deg`` and ``obliquity_deg``, °.

    Returns
    -------
    dict
        ``rows``: one row per method, as
        :func:`validation.studies.calibration_methods.obliquity_rows`.
    """
    scenario = scenario_from_dict(settings)
    rows = obliquity_rows(
        options["rig"],
        scenario_plate(scenario),
        point["obliquity_deg"],
        point["direction_deg"],
        methods=scenario.calibration.methods,
        noise_px=options["noise_px"],
        rng=seed_sequence(scenario.seed, "obliquity", "noise and points"),
    )
    return {"rows": rows}
