"""``synptv run``: a whole virtual experiment, from the flow to a report against truth.

Stages (each a folder of ``out``, reused when its inputs and the synptv version are
unchanged, see :mod:`validation.workflow.stages`):

``dataset/``            simulate and render: plate images, truth.h5, and the particle
                        images only when they are kept
                        (:func:`validation.run.render_dataset.build_dataset`)
``detections/``         the particles detected on every image, once for every rung that
                        reads images (:mod:`ptv.detect.store`); when the dataset is built
                        in the same run they are detected in memory as the images are
                        rendered
``truth/``              sample-truth S2, exact D_LL, reference ε
                        (:mod:`validation.truth.flow_truth`)
``calibrations/``       every calibration method from the plate images, Table 1, Fig. 3
``ptv/<variant>/``      statistics of each rung of the error budget:
                        ``exact`` true trajectories; ``detection`` detected centres,
                        truth-paired, true cameras; ``true-cameras`` the PTV stack with
                        the true cameras; then the PTV stack with each calibration
``report.html``, ``results.json``, ``figures/``   the comparison with truth

The images, the detections and the rungs are computed a chunk of snapshots at a time
(:func:`validation.run.particle_chunks.snapshot_chunks`) on an executor
(:mod:`validation.workflow.parallel`: this process, a local Dask cluster or a scheduler); the
chunks are joined in snapshot order, so the results do not depend on the executor. The
dataset, detection and rung stages keep their finished chunks when interrupted and the
next run goes on from there.

Each PTV folder holds ``results.h5`` and ``summary.json`` (:mod:`ptv.pipeline.results`: the links
kept are those in the analysis volume) and the paper's Fig. 5a/b and 6a/b with the truth
overlaid.
"""

import json
import logging
import shutil
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from importlib.metadata import version
from pathlib import Path

import numpy as np

from ptv.calibration.io import load_calibrations
from ptv.detect.frames import ImageDetector
from ptv.detect.store import DetectionStore, chunk_name, write_chunk, write_index
from ptv.io.dataset import open_dataset
from ptv.pipeline.double_frame import PtvResult
from ptv.pipeline.results import save_results
from ptv.settings import DetectorSettings
from ptv.stats.run_statistics import compute_statistics
from simulator.render.camera_frames import ParticleLighting, local_magnification
from simulator.render.sensor import Sensor
from simulator.rigs import Rig, load_rig
from simulator.target import REALISTIC, Imperfections
from validation.dataset.calibrate import calibrate_dataset
from validation.report.calibration_figures import error_maps
from validation.report.png import save_figure
from validation.report.ptv_figures import save_ptv_figures
from validation.run.detection_record import save_detection
from validation.run.flow_stage import dns_run_flow, ks_run_flow
from validation.run.grid_flow import grid_run_flow
from validation.run.ipr_stage import PREFIX as IPR_PREFIX
from validation.run.ipr_stage import build_ipr_rung
from validation.run.particle_chunks import chunk_detections, render_chunk, snapshot_chunks
from validation.run.ptv_rung import ptv_rung
from validation.run.render_dataset import (
    FORMAT_VERSION,
    DetectionOutput,
    RenderSettings,
    build_dataset,
    particle_job,
)
from validation.run.run_flow import RunFlow
from validation.run.scenario import Scenario, pipeline_settings
from validation.run.truth_rungs import detected_runs, detection_chunk, exact_runs
from validation.truth.flow_truth import flow_truth, population_truth
from validation.truth.matching import score_matching
from validation.truth.sheet_regions import SheetRegions
from validation.truth.truth_file import TruthFile
from validation.workflow.chunk_map import map_chunks
from validation.workflow.clock import StageTime, Stopwatch
from validation.workflow.parallel import Executor, InProcess
from validation.workflow.stages import StageOutcome, is_built, run_stage, stage_key, staging_folder

log = logging.getLogger(__name__)

#: Rungs of the error budget that use the truth (before the calibrated PTV runs).
REFERENCE_VARIANTS = ("exact", "detection", "true-cameras")

ProgressFactory = Callable[[str], Callable[[int, int], None]]


def render_settings(scenario: Scenario) -> RenderSettings:
    """What :func:`validation.run.render_dataset.write_dataset` draws for a scenario."""
    cal, particles = scenario.calibration, scenario.particles
    return RenderSettings(
        frames=particles.frames,
        planes=cal.planes,
        imperfections=REALISTIC if cal.plate == "realistic" else Imperfections(),
        plate_brightness=cal.brightness,
        particles=particles.count,
        spectrum=scenario.flow.spectrum,
        n_modes=scenario.flow.modes,
        unsteadiness=scenario.flow.unsteadiness,
        lighting=ParticleLighting(
            particle_diameter=particles.diameter, electrons_at_reference=particles.electrons
        ),
        sensor=scenario.sensor,
        shared_first_frame=particles.shared_first_frame,
        seed=scenario.seed,
    )


def object_pixel(rig: Rig) -> float:
    """Mean object-side pixel of the rig's cameras at the origin, m (one voxel)."""
    origin = np.zeros((1, 3))
    return float(
        np.mean([c.lens.pixel_pitch / local_magnification(c, origin)[0] for c in rig.cameras])
    )


@dataclass(frozen=True)
class ExperimentStages:
    """The stage folders of a run and what each took (``times``: name →
    :class:`~validation.workflow.clock.StageTime`); the flow's scales (for results.json)
    and a DNS's field stage."""

    dataset: StageOutcome
    detections: StageOutcome
    truth: StageOutcome
    calibrations: StageOutcome
    ptv: dict
    times: dict
    flow: dict
    field: StageOutcome | None = None


def _write_json(path: Path, data) -> None:
    path.write_text(json.dumps(data, indent=2, allow_nan=False) + "\n")


def detect_images_chunk(snapshots: tuple[int, int], *, folder: Path, detector: DetectorSettings):
    """Detections of one chunk of a dataset's particle images (read from its TIFF files)."""
    return ImageDetector(open_dataset(folder, check_files=False), detector).detect_chunk(*snapshots)


def render_detections_chunk(snapshots: tuple[int, int], *, job, folder: Path):
    """Detections of one chunk rendered again in memory (a dataset without images)."""
    return chunk_detections(render_chunk(snapshots, job=job), job, folder)


def run_label(scenario: Scenario) -> str:
    """Which run a figure comes from: the scenario and its seed."""
    return f"scenario {scenario.name} (seed {scenario.seed})"


def rung_label(scenario: Scenario, variant: str, calibrations: Path | None = None) -> str:
    """The suptitle of a rung's figures: the run and the rung (a reference rung, or the
    PTV stack with a calibration method; ``calibrations``: its folder, named when it is
    not the run's own, e.g. a study's calibration from fewer planes)."""
    method = variant.removeprefix(IPR_PREFIX)
    stack = "IPR and the PTV stack" if method != variant else "the PTV stack"
    what = {
        "exact": "true trajectories (no detection, no calibration)",
        "detection": "detected centres, truth-paired, through the true cameras",
        "true-cameras": f"{stack} with the true cameras",
    }.get(method, f"{stack} with the {method} calibration")
    if variant not in REFERENCE_VARIANTS and calibrations is not None:
        if calibrations.name != "calibrations":
            what += f" ({calibrations.name})"
    return f"{run_label(scenario)}, rung {variant}: {what}"


def _ptv_figures(result: PtvResult, folder: Path, truth: dict, label: str) -> None:
    def column(key: str) -> np.ndarray:
        return np.array([np.nan if v is None else v for v in truth[key]])

    r, s2 = column("r"), column("s2_sample")
    # Axes set by the truth, the same for every rung of the run: S2 (raw and noise-free)
    # over the bins from a third of its smallest to three times its largest value, ε
    # from a fifth to five times the reference, ⟨q⟩ up to 1.5 times the truth's largest
    # S2 Δt², with the separations of Fig. 5b chosen among the bins the truth fills.
    bins = result.settings.statistics
    r_axis = (bins.r_min * 1e3, bins.r_max * 1e3)
    known = np.isfinite(s2) & (s2 > 0)
    s2_limits = q_limit = None
    if known.any():
        s2_limits = (r_axis, (s2[known].min() / 3, s2[known].max() * 3))
        q_limit = 1.5 * s2[known].max() * result.statistics.dt.max() ** 2 * 1e12
    eps = truth["epsilon_exact_d_ll"]
    save_ptv_figures(
        result,
        folder,
        s2_limits=s2_limits,
        epsilon_limits=(r_axis, (eps / 5, eps * 5)),
        separations=known,
        q_limit=q_limit,
        label=label,
        reference_s2=(r, s2, "sample truth (exact velocities)"),
        epsilon_reference=(r, column("s2_exact"), "ε(r) of the exact D_LL"),
        epsilon_levels=[
            (truth["epsilon_exact_d_ll"], "plateau of the exact D_LL (the check's reference)"),
            (truth["epsilon_input"], "input ε"),
        ],
    )


class ExperimentRun:
    """The stages of one scenario under a folder: what runs them, their times.

    ``synptv run`` builds them all (:func:`run_stages`); the studies on the rendered
    chain (:mod:`validation.studies.rendered`) build the ones a point needs, under folder
    names of their own, and reuse the others through their keys.
    """

    def __init__(self, scenario, out, executor, progress, keep_images, *, rig=None) -> None:
        self.scenario = scenario
        self.out = Path(out)
        self.executor = executor
        self.progress = progress
        self.images = keep_images or scenario.output.images or scenario.ipr is not None
        self.rig = load_rig(scenario.rig.name) if rig is None else rig
        self.settings = pipeline_settings(scenario)
        self.render = render_settings(scenario)
        self.field: StageOutcome | None = None
        self.flow = ks_run_flow(scenario, self.render) if scenario.flow.kind == "ks" else None
        self.chunks = snapshot_chunks(self.render.frames)
        self.detector = DetectorSettings(saturation=float(scenario.sensor.max_dn))
        self.times: dict[str, StageTime] = {}
        # The PTV options every statistics stage reads; which calibrations run is not one.
        analysis = {k: v for k, v in scenario.as_dict()["ptv"].items() if k != "methods"}
        self.settings_inputs = {
            "synptv": version("synptv"),
            "ptv": analysis,
            "seed": scenario.seed,
        }

    @property
    def ipr_variants(self) -> tuple[str, ...]:
        """The IPR rungs (none without ``[ipr]``)."""
        return () if self.scenario.ipr is None else self.scenario.ipr.variants()

    def bar(self, name: str):
        return self.progress(name) if self.progress is not None else None

    def prepare_flow(self) -> RunFlow:
        """The run's flow: for a DNS, its stage is built (or reused) now."""
        if self.flow is None:
            with Stopwatch() as watch:
                if self.scenario.flow.kind == "grid":
                    self.flow = grid_run_flow(self.scenario.flow, self.scenario.particles.frames)
                else:
                    self.flow, self.field = dns_run_flow(
                        self.scenario, self.out, progress=self.bar("flow")
                    )
            reused = self.field is not None and self.field.reused
            self.times["flow"] = (self.field.time if reused else None) or watch.time
            log.info("%s", self.scenario.flow.describe(self.flow.preset.parameters))
        return self.flow

    @property
    def preset(self):
        """The flow's u′, ε, ν and Δt set (:class:`simulator.presets.FlowPreset`)."""
        return self.prepare_flow().preset

    def timed(self, name, folder, inputs, build, *, resume=False) -> StageOutcome:
        """The stage ``name`` reused or built (:func:`run_stage`); its times kept."""
        with Stopwatch() as watch:
            outcome = run_stage(folder, inputs, build, name=name, resume=resume)
        # A reused stage built before its times were kept: this run's (tiny) time.
        self.times[name] = outcome.time or StageTime(
            watch.time.wall_s, watch.time.cpu_s, outcome.reused
        )
        log.info("stage %s %s", name, "reused" if outcome.reused else "built")
        return outcome

    def particle_inputs(self) -> dict:
        """What the rendered particles (and plates) depend on."""
        d = self.scenario.as_dict()
        return {
            "synptv": version("synptv"),
            "format_version": FORMAT_VERSION,
            "seed": self.scenario.seed,
            "flow": self.prepare_flow().inputs,
            "rig": self.rig.spec,
            "calibration": {k: v for k, v in d["calibration"].items() if k != "methods"},
            "particles": d["particles"],
            "sensor": d["sensor"],
        }

    def detect_inputs(self, sensor: Sensor | None = None) -> dict:
        """What a detection stage depends on (with ``sensor``: the particle images
        rendered again with that sensor instead of the scenario's)."""
        inputs = {
            "synptv": version("synptv"),
            "particles": stage_key(self.particle_inputs()),
            "detector": self.detector.as_dict(),
        }
        if sensor is not None:
            inputs["particle_sensor"] = asdict(sensor)
        return inputs

    def dataset_and_detections(self) -> tuple[StageOutcome, StageOutcome]:
        """Render the dataset, detecting its particles on the way when the detection
        stage is to be built too; then complete the detection stage."""
        detect_folder = self.out / "detections"
        detect_key = stage_key(self.detect_inputs())
        fused = None
        if not is_built(detect_folder, detect_key):
            target = staging_folder(detect_folder, detect_key) / detect_folder.name
            fused = DetectionOutput(target, self.detector)
        dataset = self.timed(
            "render",
            self.out / "dataset",
            {**self.particle_inputs(), "images": self.images},
            lambda target: build_dataset(
                target,
                self.rig,
                self.preset,
                self.render,
                flow=self.flow,
                images=self.images,
                detections=fused,
                executor=self.executor,
                progress=self.bar("render"),
            ),
            resume=True,
        )
        return dataset, self.detections(dataset)

    def detections(
        self, dataset: StageOutcome, *, sensor: Sensor | None = None, folder: str = "detections"
    ) -> StageOutcome:
        """The detection stage: the chunks not detected yet are detected, and the store
        is indexed. With ``sensor``, the particle images are rendered again in memory
        with it (same particles, same flow, plate images untouched)."""
        return self.timed(
            "detect",
            self.out / folder,
            self.detect_inputs(sensor),
            lambda target: self.complete_detections(target, dataset.folder, sensor),
            resume=True,
        )

    def complete_detections(self, target: Path, dataset: Path, sensor: Sensor | None) -> None:
        """Detect the chunks not detected yet (from the images when the dataset has
        them and the sensor is the scenario's, else rendering them again in memory) and
        write the store's index."""
        target.mkdir(exist_ok=True)
        todo = [c for c in self.chunks if not (target / chunk_name(*c)).is_file()]
        if self.images and sensor is None:
            fn, shared = detect_images_chunk, {"folder": dataset, "detector": self.detector}
        else:
            render = self.render if sensor is None else replace(self.render, sensor=sensor)
            job = particle_job(
                self.rig, self.preset, render, flow=self.flow, detector=self.detector
            )
            fn, shared = render_detections_chunk, {"job": job, "folder": dataset}
        frames = (self.render.frames,) * len(self.preset.dt)
        tick = self.bar("detect")
        for done, (i, found) in enumerate(self.executor.map(fn, todo, shared=shared), 1):
            write_chunk(target / chunk_name(*todo[i]), found, frames=frames)
            if tick is not None:
                tick(done, len(todo))
        write_index(
            target,
            cameras=self.rig.camera_names,
            dt=np.asarray(self.preset.dt),
            frames=frames,
            shared_first_frame=self.render.shared_first_frame,
            detector=self.detector.as_dict(),
            chunks=self.chunks,
            source=str(dataset),
        )

    def truth(self, dataset: StageOutcome, truth: TruthFile) -> StageOutcome:
        """Sample truth, exact D_LL and the reference ε."""

        def build(target: Path) -> None:
            target.mkdir()
            reference = flow_truth(
                truth.snapshots_at_t(self.chunks, progress=self.bar("truth")),
                self.preset.parameters,
                self.flow.exact,
                self.settings.statistics,
            )
            _write_json(target / "truth.json", reference.as_dict())

        inputs = {"dataset": dataset.key, **self.settings_inputs}
        return self.timed("truth", self.out / "truth", inputs, build)

    def calibrations(
        self,
        dataset: StageOutcome,
        *,
        methods: tuple[str, ...] | None = None,
        planes: list[int] | None = None,
        folder: str = "calibrations",
    ) -> StageOutcome:
        """Calibrations (default: every method of the scenario, from every plane),
        Table 1 on every plane and Fig. 3."""
        methods = self.scenario.calibration.methods if methods is None else methods
        under_test = [m for m in methods if m == self.scenario.ptv.methods[0]]

        def build(target: Path) -> None:
            result = calibrate_dataset(
                dataset.folder,
                methods=methods,
                out=target,
                fit_planes=planes,
                progress=self.bar("calibrate"),
                required=under_test,
            )
            table1 = {
                "table1": result.table1,
                "max_plane_residual_px": result.max_plane_residual_px,
            }
            if result.failed:  # baselines that could not fit a camera (docs/run.md §5)
                table1["failed"] = result.failed
            _write_json(target / "table1.json", table1)
            maps = {m: e["nominal"] for m, e in result.errors.items()}
            title = (
                "Triangulated dots against their nominal positions (the paper's Fig. 3)\n"
                f"{run_label(self.scenario)}, calibrated from "
                + ("every plane" if planes is None else f"planes {_plane_list(planes)}")
            )
            save_figure(error_maps(maps, title=title), target / "fig3_error_maps.png")

        inputs = {"dataset": dataset.key, "methods": list(methods)}
        if planes is not None:
            inputs["planes"] = list(planes)
        return self.timed("calibrate", self.out / folder, inputs, build)

    def rung_builder(self, detections: StageOutcome, truth_stage: StageOutcome, truth):
        """What builds the rungs on these detections, against this truth."""
        store = DetectionStore(detections.folder)
        truth_dict = json.loads((truth_stage.folder / "truth.json").read_text())
        return RungBuilder(self, store, truth, truth_dict)

    def rung(
        self,
        variant: str,
        builder: "RungBuilder",
        detections: StageOutcome,
        calibrations: StageOutcome | None,
        folder: Path | None = None,
    ) -> StageOutcome:
        """The stage of one rung (a reference variant, or the PTV stack with the
        calibration method ``variant`` from ``calibrations``) in ``folder`` (default:
        ``ptv/<variant>-<key>``, a folder of its own for every set of inputs)."""
        inputs = {
            "detections": detections.key,
            "variant": variant,
            "links": self.scenario.output.links,
            **self.settings_inputs,
        }
        if variant not in REFERENCE_VARIANTS:
            inputs["calibration"] = calibrations.key
        if variant.startswith(IPR_PREFIX):
            inputs["ipr"] = asdict(self.scenario.ipr)
        if folder is None:
            folder = self.out / "ptv" / f"{variant}-{stage_key(inputs)[:12]}"
        return self.timed(
            f"ptv {variant}",
            folder,
            inputs,
            lambda target: builder.build(
                target, variant, None if calibrations is None else calibrations.folder
            ),
            resume=True,
        )

    def rungs(self, detections, truth_stage, calibrations, truth: TruthFile) -> dict:
        """Every rung of the error budget, one stage each (none for a baseline whose
        calibration failed)."""
        builder = self.rung_builder(detections, truth_stage, truth)
        failed = json.loads((calibrations.folder / "table1.json").read_text()).get("failed", {})
        return {
            variant: self.rung(
                variant, builder, detections, calibrations, self.out / "ptv" / variant
            )
            for variant in (*REFERENCE_VARIANTS, *self.scenario.ptv.methods, *self.ipr_variants)
            if variant.removeprefix(IPR_PREFIX) not in failed
        }


class RungBuilder:
    """Builds the stage of one rung of the error budget."""

    def __init__(
        self, run: ExperimentRun, store: DetectionStore, truth: TruthFile, truth_dict: dict
    ):
        self.run = run
        self.store = store
        self.truth = truth
        self.truth_dict = truth_dict
        # Every rung draws its bootstrap in the same blocks (so that the rungs' replicates
        # pair up), as long as the correlation of the sample truth's successive snapshots
        # asks (truth.json); the stack would otherwise measure it on each rung's own data.
        block = truth_dict.get("snapshot_correlation", {}).get("block")
        settings = run.settings
        if block is not None:
            statistics = replace(settings.statistics, snapshot_block=block)
            settings = replace(settings, statistics=statistics)
        self.settings = settings
        # The reference rungs have no links, so nothing for the trajectory test to catch;
        # on noise-free trajectories it would only drop the particles of largest jerk.
        self.unlinked = replace(
            settings, statistics=replace(settings.statistics, trajectory_threshold=None)
        )
        self.voxel = object_pixel(truth.rig)
        self.regions = SheetRegions.of_dataset(truth)
        self.true_cameras = dict(zip(truth.rig.camera_names, truth.rig.cameras, strict=True))

    def reference_result(self, runs) -> PtvResult:
        """The statistics of a reference rung's runs, as a PtvResult."""
        statistics = compute_statistics(
            runs, self.unlinked.statistics, shared_first_frame=self.store.shared_first_frame
        )
        return PtvResult(self.store, self.store.cameras, self.unlinked, runs, statistics)

    def build(self, target: Path, variant: str, calibrations: Path | None) -> None:
        target.mkdir(exist_ok=True)
        cache = target / "chunks"
        tick = self.run.bar(f"ptv {variant}")
        label = rung_label(self.run.scenario, variant, calibrations)
        if variant == "exact":
            runs = exact_runs(self.truth, self.run.chunks, self.unlinked, progress=tick)
            result = self.reference_result(runs)
            self.save(result, target, "none: true trajectories", label)
        elif variant == "detection":
            self.detection(target, cache, tick, label)
        elif variant.startswith(IPR_PREFIX):
            build_ipr_rung(self, target, variant, calibrations, cache, tick, label)
        else:
            if variant == "true-cameras":
                cams, described = self.true_cameras, "true cameras"
            else:
                path = calibrations / f"{variant}.h5"
                cams, described = load_calibrations(path), str(path)
            ordered = [cams[name] for name in self.store.cameras]
            result, frame_a = ptv_rung(
                self.store,
                ordered,
                self.settings,
                self.run.chunks,
                executor=self.run.executor,
                cache=cache,
                progress=tick,
            )
            self.save(result, target, described, label)
            scored = self.truth.runs(0, len(frame_a))[0]
            quality = score_matching(
                frame_a,
                scored,
                self.store.cameras,
                self.settings,
                voxel=self.voxel,
                regions=self.regions,
            )
            _write_json(target / "matching.json", quality.as_dict())
            self.save_population(result, target, quality.rotation, quality.translation)
        shutil.rmtree(cache, ignore_errors=True)

    def detection(self, target: Path, cache: Path, tick, label: str) -> None:
        """Detected centres, truth-paired, through the true cameras."""
        cams = [self.true_cameras[name] for name in self.store.cameras]
        chunks = map_chunks(
            self.run.executor,
            detection_chunk,
            self.run.chunks,
            lambda c: (self.store.chunk(c[0]), self.truth.runs(*c)),
            shared={"cameras": cams, "settings": self.unlinked},
            cache=cache,
            name="detection",
            progress=tick,
        )
        runs, quality = detected_runs(chunks, self.truth.dt, self.store.cameras)
        result = self.reference_result(runs)
        self.save(result, target, "true cameras, truth-paired detections", label)
        save_detection(quality, target, label)
        self.save_population(result, target)

    def save(self, result: PtvResult, folder: Path, calibration: str, label: str) -> None:
        """results.h5 and summary.json (``calibration``: what they say the cameras
        were), and the figures, titled ``label``."""
        links = self.run.scenario.output.links
        save_results(result, folder, calibration=calibration, links=links)
        _ptv_figures(result, folder, self.truth_dict, label)

    def save_population(self, result: PtvResult, folder: Path, rotation=None, translation=None):
        """population.json: the sample truth over the pairs this measurement's S2 used
        (its X(t) brought from the calibration frame to the world by the rigid
        ``rotation`` and ``translation`` the matching score found)."""
        statistics = result.statistics
        population = statistics.population
        if population is None:
            return
        replicates = None
        if statistics.bootstrap is not None and statistics.structure.s2_boot is not None:
            replicates = (statistics.bootstrap, statistics.structure.s2_boot)
        reference = population_truth(
            population,
            self.truth,
            self.run.chunks,
            self.settings.statistics,
            radius=self.voxel,
            rotation=rotation,
            translation=translation,
            replicates=replicates,
        )
        _write_json(folder / "population.json", reference.as_dict())


def run_stages(
    scenario: Scenario,
    out: Path,
    *,
    progress: ProgressFactory | None = None,
    executor: Executor | None = None,
    keep_images: bool = False,
) -> ExperimentStages:
    """Run (or reuse) every stage of a scenario under ``out``.

    Parameters
    ----------
    scenario : Scenario
        What to simulate and measure.
    out : Path
        Output folder (created).
    progress : callable(stage name) -> callable(done, total), optional
        A progress callback per stage.
    executor : Executor, optional
        Where the chunks are computed (default: this process).
    keep_images : bool
        Write the particle images into the dataset (also when the scenario's
        ``[output] images`` is false).

    Returns
    -------
    ExperimentStages
        The stage folders (``ptv``: variant → its folder), the time each took and the
        flow's scales; ``synptv run`` then writes its report from them
        (:func:`validation.run.run_report.write_report`). A scenario with
        ``[recording]`` runs through :mod:`validation.run.recording_run` instead.

    Examples
    --------
    ``stages = validation.run_scenario(validation.load_scenario("ci"), "synptv-ci")``
    runs every stage in minutes on two cores (run again: every stage ``reused``):

    >>> import validation
    >>> scenario = validation.load_scenario("ci")
    >>> scenario.recording is None, scenario.ptv.methods  # frame pairs; PTV calibrations
    (True, ('model-free',))
    """
    executor = InProcess() if executor is None else executor
    run = ExperimentRun(scenario, out, executor, progress, keep_images)
    run.out.mkdir(parents=True, exist_ok=True)
    run.prepare_flow()
    dataset, detections = run.dataset_and_detections()
    truth = TruthFile(dataset.folder)
    truth_stage = run.truth(dataset, truth)
    calibrations = run.calibrations(dataset)
    ptv = run.rungs(detections, truth_stage, calibrations, truth)
    return ExperimentStages(
        dataset,
        detections,
        truth_stage,
        calibrations,
        ptv,
        run.times,
        flow=run.flow.scales,
        field=run.field,
    )


def _plane_list(planes: list[int]) -> str:
    """Plane indices as a short list: "0, 6, 12"."""
    return ", ".join(str(j) for j in planes)
