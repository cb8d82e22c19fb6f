"""Parameter studies on the rendered chain: every point goes through images.

A point renders (or reuses) the scenario's dataset, detects the particles on its
images, calibrates from its plate images, runs the PTV stack with the calibration and
compares what it recovers with the truth, as ``synptv run`` does
(:class:`validation.run.experiment.ExperimentRun`). Each point reuses the stages it does not
change, through their keys: the points of one seed share a work folder (shared by the
studies of one output folder too), and

- ``planes`` renders and detects once and calibrates from 2 … N_Z planes spanning the
  traverse (model-free);
- ``dt`` runs the whole chain once and recomputes the statistics on Δt subsets of the
  same recordings (all of them, the three largest, the smallest and the largest, and
  three or four spread over the set), twice: as if only the subset's Δt had been
  recorded (``dt_population`` "these dt alone": the particles linked at those Δt; with
  fewer than four Δt the trajectory test cannot run and mislinks stay in), and refitted
  on the pairs of every Δt's particles ("every dt": the paper's subset study);
- ``noise`` renders the flow and the plate once and renders the particle images again
  for each read noise of the camera (the detection noise follows);
- ``seeding`` (tracers in the sheet), ``obliquity`` (the windows' obliquity, every
  calibration method of the scenario) and ``density`` (:mod:`validation.studies.density`:
  IPR beside detect-and-match) render each point anew.

Every point gives, per calibration method: the Table 1 metric d of the calibration
against the nominal dot positions (µm, every plane); the model error at random points
of the volume (µm: the calibrations' triangulation of exactly projected points, in the
calibration's frame); the matching yield and ghost fraction (:mod:`validation.truth.matching`);
c₁ against the sample truth of the very pairs its S2 used at the fitted bins nearest
10η, 40η and 100η, and the plateau ε against the same estimator on the exact D_LL, each
with its bootstrap standard error relative to the reference.
"""

import json
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ptv.calibration.io import load_calibrations
from ptv.pipeline.results import load_runs
from ptv.stats.run_statistics import compute_statistics
from ptv.triangulate import triangulate
from simulator.render.sensor import Sensor
from simulator.rigs import Rig, load_rig, rig_from_dict
from validation.dataset.calibrate import dot_positions
from validation.run.experiment import ExperimentRun, object_pixel
from validation.run.ipr_section import check_ipr_memory, sensor_pixels
from validation.run.scenario import OutputSection, Scenario
from validation.studies.calibration_methods import MODEL_VOLUME, plane_subset, with_obliquity
from validation.studies.density import (
    DENSITIES_PPP,
    PPP_RANGE,
    density_scores,
    particles_at,
    statistics_reach,
)
from validation.studies.multi_dt import R_OVER_ETA, spread_indices
from validation.truth.flow_truth import population_truth
from validation.truth.matching import rigid_fit
from validation.truth.truth_file import TruthFile
from validation.workflow.parallel import Executor

#: Plane counts of the plane study (the scenario's traverse always included).
PLANE_COUNTS = (2, 3, 5, 7, 9, 13)
#: Read noise of the camera in the noise study, e⁻ rms.
READ_NOISE_E = (0.0, 4.0, 8.0, 16.0, 32.0)
#: Tracers in the laser sheet in the seeding study.
TRACERS = (500, 1000, 2000, 3000)
#: Window obliquities (°) and their directions (0: in the camera plane, 45: diagonal).
OBLIQUITIES_DEG = (0.0, 5.0, 10.0, 15.0, 20.0)
DIRECTIONS_DEG = (0.0, 45.0)
#: Random points of the model error.
MODEL_POINTS = 2000


@dataclass(frozen=True)
class RenderedPoint:
    """One point of a study on the rendered chain.

    Attributes
    ----------
    id : str
        Name of the point (file names).
    params : dict
        The swept parameter(s), as they go into the table.
    scenario : Scenario
        The point's scenario (its seed included).
    work : str
        Work folder, shared by the points that share their renders.
    planes : int or None
        Calibration planes spanning the traverse (None: all).
    dt : tuple of int or None
        Δt indices the statistics use (None: all).
    sensor : Sensor or None
        Camera of the particle images, when it differs from the scenario's.
    """

    id: str
    params: dict
    scenario: Scenario
    work: str
    planes: int | None = None
    dt: tuple[int, ...] | None = None
    sensor: Sensor | None = None


def _tag(point: RenderedPoint) -> str:
    """What distinguishes a point's calibration, detections and rungs in its work folder."""
    return point.id.rsplit("-seed-", 1)[0]


def study_points(
    study: str, scenario: Scenario, seeds: int, values: list | None = None
) -> list[RenderedPoint]:
    """The points of a study for seeds scenario.seed … scenario.seed + seeds − 1.

    Parameters
    ----------
    study : str
        planes, dt, noise, seeding, obliquity or density.
    scenario : Scenario
        The base scenario.
    seeds : int
        Independent repetitions.
    values : list, optional
        The values to sweep instead of the defaults: plane counts (planes), lists of
        Δt indices (dt), or densities in particles per pixel (density).

    Raises
    ------
    ValueError
        An unknown study, values given to another study, values out of range (fewer
        than 2 or more planes than the traverse has; fewer than 2, repeated or unknown
        Δt indices; densities outside 10⁻⁴–0.3), a density study of a scenario without
        ``[ipr]``.
    """
    if values is not None:
        _check_values(study, scenario, values)
    points = []
    for s in range(seeds):
        seeded = scenario.with_seed(scenario.seed + s)
        points.extend(_points(study, seeded, values))
    return points


def _check_values(study: str, scenario: Scenario, values: list) -> None:
    if study == "planes":
        total = scenario.calibration.planes
        bad = [v for v in values if not 2 <= v <= total]
        if bad or not values:
            raise ValueError(
                f"--planes must be counts from 2 to {total} (the traverse), got {values}"
            )
    elif study == "dt":
        k = len(scenario.flow.as_preset().dt)
        for subset in values:
            if len(subset) < 2 or len(set(subset)) != len(subset):
                raise ValueError(f"a Δt subset needs two or more distinct indices, got {subset}")
            if not all(0 <= i < k for i in subset):
                raise ValueError(f"unknown Δt index in {subset}: the indices are 0 … {k - 1}")
    elif study == "density":
        low, high = PPP_RANGE
        bad = [v for v in values if not low <= v <= high]
        if bad or not values:
            raise ValueError(f"--ppp must be densities from {low:g} to {high:g}, got {values}")
    else:
        raise ValueError(f"the {study} study takes no list of values")


def _points(study: str, scenario: Scenario, values: list | None) -> list[RenderedPoint]:
    """The points of one seed (the scenario's)."""
    seed = scenario.seed
    shared = f"seed-{seed}"
    if study == "planes":
        total = scenario.calibration.planes
        counts = sorted({c for c in PLANE_COUNTS if c <= total} | {total})
        counts = counts if values is None else sorted(set(values))
        return [
            RenderedPoint(f"planes-{c:02d}-seed-{seed}", {"planes": c}, scenario, shared, planes=c)
            for c in counts
        ]
    if study == "dt":
        links = replace(scenario, output=OutputSection(images=False, links=True))
        k = len(scenario.flow.as_preset().dt)
        if values is None:
            subsets = dt_subsets(k)
        else:
            subsets = [("-".join(map(str, sorted(v))), tuple(sorted(v))) for v in values]
        return [
            RenderedPoint(
                f"dt-{name}-seed-{seed}",
                {"dt_subset": name, "dt_indices": list(indices)},
                links,
                shared,
                dt=indices,
            )
            for name, indices in subsets
        ]
    if study == "noise":
        return [
            RenderedPoint(
                f"noise-{e:g}e-seed-{seed}",
                {"read_noise_e": e},
                scenario,
                shared,
                sensor=replace(scenario.sensor, read_noise=e),
            )
            for e in READ_NOISE_E
        ]
    if study == "seeding":
        return [
            RenderedPoint(
                f"seeding-{n}-seed-{seed}",
                {"tracers": n},
                replace(scenario, particles=replace(scenario.particles, count=n)),
                f"seeding-{n}-seed-{seed}",
            )
            for n in TRACERS
        ]
    if study == "density":
        if scenario.ipr is None:
            raise ValueError(
                f"the density study compares IPR with detect-and-match: scenario "
                f"{scenario.name!r} has no [ipr] table (the dense-ci scenario has one)"
            )
        points = []
        pixels = sensor_pixels(load_rig(scenario.rig.name).cameras)
        for ppp in DENSITIES_PPP if values is None else sorted(set(values)):
            n = particles_at(ppp, scenario.rig.name)
            tag = f"density-{ppp:g}-seed-{seed}"
            dense = replace(scenario, particles=replace(scenario.particles, count=n))
            check_ipr_memory(dense, f"{scenario.name} at {ppp:g} ppp", pixels)
            points.append(RenderedPoint(tag, {"ppp": ppp, "tracers": n}, dense, tag))
        return points
    if study == "obliquity":
        return [
            RenderedPoint(
                f"obliquity-{d:g}-{a:g}-seed-{seed}",
                {"direction_deg": d, "obliquity_deg": a},
                scenario,
                f"obliquity-{d:g}-{a:g}-seed-{seed}",
            )
            for d in DIRECTIONS_DEG
            for a in OBLIQUITIES_DEG
        ]
    raise ValueError(f"unknown study {study!r}")


def dt_subsets(k: int) -> list[tuple[str, tuple[int, ...]]]:
    """The Δt subsets of the dt study among K = ``k`` values, named."""
    subsets = [("all", tuple(range(k)))]
    if k >= 4:
        subsets.append(("3-largest", tuple(range(k - 3, k))))
    if k >= 3:
        subsets.append(("smallest-and-largest", (0, k - 1)))
    subsets += [(f"spread-{n}", tuple(spread_indices(k, n))) for n in range(3, k)]
    return subsets


def _rig(point: RenderedPoint) -> Rig:
    """The point's rig: the scenario's, with its windows turned for the obliquity study."""
    rig = load_rig(point.scenario.rig.name)
    if "obliquity_deg" not in point.params:
        return rig
    turned = with_obliquity(rig.spec, point.params["obliquity_deg"], point.params["direction_deg"])
    return rig_from_dict(turned, source=f"{rig.name}, {point.id}")


def evaluate_point(
    point: RenderedPoint,
    folder: Path,
    executor: Executor,
    *,
    progress: Callable[[str], Callable[[int, int], None]] | None = None,
) -> list[dict]:
    """Run (or reuse) the stages of one point and score it against the truth.

    Parameters
    ----------
    point : RenderedPoint
        The point.
    folder : Path
        Where the stages go: ``<folder>/<point.work>`` (a folder shared by the studies
        of one output folder, so that a dt study reuses the images a planes study of
        the same scenario and seed rendered).
    executor : Executor
        Where the chunks are computed.
    progress : callable(stage name) -> callable(done, total), optional
        Progress of the stages.

    Returns
    -------
    list of dict
        One row per calibration method (module docstring).
    """
    scenario = point.scenario
    work = folder / point.work
    run = ExperimentRun(scenario, work, executor, progress, False, rig=_rig(point))
    run.out.mkdir(parents=True, exist_ok=True)
    dataset, detections = run.dataset_and_detections()
    tag = _tag(point)
    if point.sensor is not None:
        detections = run.detections(dataset, sensor=point.sensor, folder=f"detections-{tag}")
    truth = TruthFile(dataset.folder)
    truth_stage = run.truth(dataset, truth)
    total = scenario.calibration.planes
    planes = None if point.planes in (None, total) else plane_subset(total, point.planes)
    methods = scenario.calibration.methods if "obliquity_deg" in point.params else ("model-free",)
    calibrations = run.calibrations(
        dataset,
        methods=methods,
        planes=planes,
        folder="calibrations" if planes is None else f"calibrations-{tag}",
    )
    builder = run.rung_builder(detections, truth_stage, truth)
    truth_dict = json.loads((truth_stage.folder / "truth.json").read_text())
    table1 = json.loads((calibrations.folder / "table1.json").read_text())["table1"]
    rows = []
    if "ppp" in point.params:
        rows = _density_rows(point, run, builder, detections, calibrations, truth_dict, truth)
        methods = scenario.ptv.methods[:1]
    for method in methods:
        stage = run.rung(method, builder, detections, calibrations)
        cameras = load_calibrations(calibrations.folder / f"{method}.h5")
        calibration = {
            "table1_d_um": table1[method]["nominal"]["d_um"],
            "model_error_um": model_error(cameras, truth, dataset.folder) * 1e6,
        }
        reach = statistics_reach(stage.folder) if "ppp" in point.params else {}
        for scores in _rung_scores(stage.folder, truth_dict, run, truth, point.dt):
            if point.dt is None:
                scores.pop("dt_population")
            rows.append(
                {
                    "seed": scenario.seed,
                    **point.params,
                    "method": method,
                    **calibration,
                    **scores,
                    **reach,
                }
            )
    return rows


def _density_rows(point, run, builder, detections, calibrations, truth_dict, truth) -> list:
    """The rows of a density point's IPR rungs (:mod:`validation.studies.density`)."""
    rows = []
    for variant in run.ipr_variants:
        stage = run.rung(variant, builder, detections, calibrations)
        for scores in _rung_scores(stage.folder, truth_dict, run, truth, None):
            scores.pop("dt_population")
            rows.append(
                {
                    "seed": point.scenario.seed,
                    **point.params,
                    "method": variant,
                    **scores,
                    **density_scores(stage.folder),
                    **statistics_reach(stage.folder),
                }
            )
    return rows


def _rung_scores(
    folder: Path, truth: dict, run: ExperimentRun, truth_file: TruthFile, dt: tuple | None
) -> list[dict]:
    """Matching, c₁ and ε of a rung's stage folder (one dict); on a Δt subset, two: the
    subset's Δt as if they alone had been recorded ("these dt alone"), and the subset
    refitted on the particles of every Δt ("every dt", the paper's subset study)."""
    matching = json.loads((folder / "matching.json").read_text())
    population = json.loads((folder / "population.json").read_text())
    every = np.array([np.nan if v is None else v for v in population["s2_sample"]])
    if dt is None or len(dt) == len(truth_file.dt):
        summary = json.loads((folder / "summary.json").read_text())
        sf, plateau = summary["structure_function"], summary["epsilon"]["plateau"]
        fit = tuple(np.array(sf[key], dtype=float) for key in ("r", "s2", "se_s2"))
        fitted = np.array(sf["fitted"], dtype=bool)
        epsilon = None if plateau is None else (plateau["epsilon"], plateau["se_epsilon"])
        measured = [("every dt", fit, fitted, epsilon, every)]
    else:
        runs = load_runs(folder / "results.h5")
        measured = [
            ("these dt alone", *_alone(runs, run, truth_file, dt, matching)),
            ("every dt", *_refit(runs, run, truth_file, dt), every),
        ]
    exact = truth["epsilon_exact_d_ll"]
    rows = []
    for name, fit, fitted, epsilon, reference in measured:
        c1, se = c1_errors(*fit, reference, fitted, truth["parameters"]["eta"])
        rows.append(
            {
                "dt_population": name,
                "yield": matching["yield"],
                "ghosts": matching["ghost_fraction"],
                "c1_rel_err": c1,
                "c1_rel_se": se,
                "epsilon_rel_err": None if epsilon is None else epsilon[0] / exact - 1,
                "epsilon_rel_se": None if epsilon is None else epsilon[1] / exact,
            }
        )
    return rows


def _fit_of(sf, plateau):
    """(r, c₁, se), fitted bins and (ε, se) or None of a fit and its plateau."""
    epsilon = None if plateau is None else (plateau.epsilon, plateau.se_epsilon)
    return (sf.r, sf.s2, sf.se_s2), sf.fitted, epsilon


def _refit(runs, run, truth_file, dt):
    """The fit on Δt subset ``dt`` of the pairs of every Δt's particles."""
    use = np.zeros(len(runs), dtype=bool)
    use[list(dt)] = True
    statistics = compute_statistics(
        runs,
        run.settings.statistics,
        shared_first_frame=truth_file.shared_first_frame,
        subsets={"chosen": use},
    )
    chosen = statistics.subsets["chosen"]
    return _fit_of(chosen.structure, chosen.plateau)


def _alone(runs, run, truth_file, dt, matching):
    """The fit, fitted bins, plateau and the sample truth of the pairs used, of the
    subset's links alone (the particles linked at these Δt: with fewer than four, the
    trajectory test of :mod:`ptv.stats.run_statistics` cannot run)."""
    settings = run.settings.statistics
    statistics = compute_statistics(
        [runs[k] for k in dt], settings, shared_first_frame=truth_file.shared_first_frame
    )
    reference = population_truth(
        statistics.population,
        _SubsetTruth(truth_file, dt),
        run.chunks,
        settings,
        radius=object_pixel(run.rig),
        rotation=np.array(matching["frame_rotation"]),
        translation=np.array(matching["frame_translation_m"]),
    )
    return (*_fit_of(statistics.structure, statistics.plateau), reference.s2_sample)


class _SubsetTruth:
    """A TruthFile read through a subset of its Δt."""

    def __init__(self, truth: TruthFile, dt: tuple[int, ...]):
        self.truth = truth
        self.indices = list(dt)
        self.dt = truth.dt[self.indices]

    def runs(self, m0: int, m1: int):
        runs = self.truth.runs(m0, m1)
        return [runs[k] for k in self.indices]


def c1_errors(
    r: np.ndarray,
    c1: np.ndarray,
    se: np.ndarray,
    reference: np.ndarray,
    fitted: np.ndarray,
    eta: float,
) -> tuple[dict, dict]:
    """c₁/reference − 1 and its standard error at the fitted bins nearest r/η = 10, 40,
    100 (:data:`validation.studies.multi_dt.R_OVER_ETA`), keyed "10", "40", "100"
    (None where no bin is fitted)."""
    usable = np.flatnonzero(fitted & np.isfinite(r) & np.isfinite(reference) & (reference > 0))
    errors, ses = {}, {}
    for n in R_OVER_ETA:
        if usable.size:
            b = usable[np.argmin(np.abs(np.log(r[usable] / (n * eta))))]
            errors[str(n)] = float(c1[b] / reference[b] - 1)
            ses[str(n)] = float(se[b] / reference[b])
        else:
            errors[str(n)] = ses[str(n)] = None
    return errors, ses


def model_error(calibrations: dict, truth: TruthFile, dataset: Path) -> float:
    """Mean 3-D error of the calibrations at random points of the volume, m.

    The points are drawn in the world, imaged exactly by the true cameras and
    triangulated with the calibrations; the result is compared with the points brought
    into the calibration's frame (the nominal plate's: the rigid transform that best
    maps the true dot centres onto their nominal positions).
    """
    world, nominal = dot_positions(dataset)
    rotation, translation = rigid_fit(world.reshape(-1, 3), nominal.reshape(-1, 3))
    rng = np.random.default_rng(np.random.SeedSequence([17, MODEL_POINTS]))
    points = MODEL_VOLUME.sample(MODEL_POINTS, rng)
    cameras = truth.rig.cameras
    pixels = [camera.project(points) for camera in cameras]
    seen = np.all([np.isfinite(p).all(axis=1) for p in pixels], axis=0)
    ordered = [calibrations[name] for name in truth.rig.camera_names]
    found = triangulate(ordered, [p[seen] for p in pixels]).points
    expected = points[seen] @ rotation.T + translation
    return float(np.mean(np.linalg.norm(found - expected, axis=1)))
