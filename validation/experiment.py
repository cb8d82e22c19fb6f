"""``synptv run``: a whole virtual experiment, from the flow to a report against truth.

Stages (each a folder of ``out``, reused when its inputs and the synptv version are
unchanged, see :mod:`validation.stages`):

``dataset/``            simulate and render (:func:`validation.dataset.write_dataset`)
``detections/``         the particles detected on every image, once for every rung that
                        reads images (:mod:`ptv.detect.store`)
``truth/``              sample-truth S2, exact D_LL, reference ε (:mod:`validation.flow_truth`)
``calibrations/``       every calibration method from the plate images, Table 1, Fig. 3
``ptv/<variant>/``      statistics of each rung of the error budget:
                        ``exact`` true trajectories; ``detection`` detected centres,
                        truth-paired, true cameras; ``true-cameras`` the PTV stack with
                        the true cameras; then the PTV stack with each calibration
``report.html``, ``results.json``, ``figures/``   the comparison with truth

Each PTV folder holds ``results.h5`` and ``summary.json`` (:mod:`ptv.results`) and the
paper's Fig. 5a/b and 6a/b with the truth overlaid.
"""

import json
import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from importlib.metadata import version
from pathlib import Path

import numpy as np

from ptv.calibration.io import load_calibrations
from ptv.dataset import open_dataset
from ptv.detect.peaklocking import peak_locking
from ptv.detect.store import DetectionStore, chunk_name, write_chunk, write_index
from ptv.frames import DetectorSettings, ImageDetector
from ptv.pipeline import PtvResult, run_pipeline
from ptv.results import save_results
from ptv.stats.run_statistics import compute_statistics
from simulator.presets import flow_preset
from simulator.render.camera_frames import ParticleLighting, local_magnification
from simulator.rigs import Rig, load_rig
from simulator.target import REALISTIC, Imperfections
from validation.calibrate_dataset import calibrate_dataset
from validation.dataset import FORMAT_VERSION, RenderSettings, write_dataset
from validation.figures import error_maps, save_figure
from validation.flow_truth import flow_truth, population_truth
from validation.matching_quality import score_matching
from validation.ptv_figures import save_ptv_figures
from validation.report_figures import peak_locking_figure
from validation.scenario import Scenario, pipeline_settings
from validation.stages import StageOutcome, run_stage
from validation.truth_runs import detected_runs, exact_runs, read_truth

log = logging.getLogger(__name__)

#: Rungs of the error budget that use the truth (before the calibrated PTV runs).
REFERENCE_VARIANTS = ("exact", "detection", "true-cameras")

ProgressFactory = Callable[[str], Callable[[int, int], None]]


def render_settings(scenario: Scenario) -> RenderSettings:
    """What :func:`validation.dataset.write_dataset` draws for a scenario."""
    cal, particles = scenario.calibration, scenario.particles
    return RenderSettings(
        frames=particles.frames,
        planes=cal.planes,
        imperfections=REALISTIC if cal.plate == "realistic" else Imperfections(),
        plate_brightness=cal.brightness,
        particles=particles.count,
        spectrum=scenario.flow.spectrum,
        n_modes=scenario.flow.modes,
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
    """The stage folders of a run and how long each took (0 when reused)."""

    dataset: StageOutcome
    detections: StageOutcome
    truth: StageOutcome
    calibrations: StageOutcome
    ptv: dict
    seconds: dict


def snapshot_chunks(frames: int) -> list[tuple[int, int]]:
    """Ranges (m0, m1) of snapshots processed together: at most 10, at least 8 chunks
    when there are that many snapshots (chunks depend on the frame count alone, so a
    resumed run finds the same ones)."""
    size = max(1, min(10, -(-frames // 8)))
    return [(m0, min(m0 + size, frames)) for m0 in range(0, frames, size)]


def _write_detections(detector: ImageDetector, target: Path, progress) -> None:
    """Detect every image of a dataset into a detection store at ``target``."""
    target.mkdir()
    chunks = snapshot_chunks(max(detector.frames))
    for i, (m0, m1) in enumerate(chunks):
        chunk = detector.detect_chunk(m0, m1)
        write_chunk(target / chunk_name(m0, m1), chunk, frames=detector.frames)
        if progress is not None:
            progress(i + 1, len(chunks))
    write_index(
        target,
        cameras=detector.cameras,
        dt=detector.dt,
        frames=detector.frames,
        shared_first_frame=detector.shared_first_frame,
        detector=detector.detector,
        chunks=chunks,
        source=str(detector.folder),
    )


def _write_json(path: Path, data) -> None:
    path.write_text(json.dumps(data, indent=2, allow_nan=False) + "\n")


def _ptv_figures(result: PtvResult, folder: Path, truth: dict) -> None:
    r = np.array([np.nan if v is None else v for v in truth["r"]])
    s2 = np.array([np.nan if v is None else v for v in truth["s2_sample"]])
    save_ptv_figures(
        result,
        folder,
        reference_s2=(r, s2, "sample truth (exact velocities)"),
        reference_epsilon=truth["epsilon_exact_d_ll"],
    )


def _save_ptv(result: PtvResult, folder: Path, truth: dict, calibration: str) -> None:
    save_results(result, folder, calibration=calibration)
    _ptv_figures(result, folder, truth)


def run_stages(
    scenario: Scenario, out: Path, *, progress: ProgressFactory | None = None
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

    Returns
    -------
    ExperimentStages
    """

    def bar(name: str):
        return progress(name) if progress is not None else None

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    rig = load_rig(scenario.rig.name)
    preset = flow_preset(scenario.flow.preset)
    settings = pipeline_settings(scenario)
    seconds = {}

    def timed(name, folder, inputs, build) -> StageOutcome:
        start = time.perf_counter()
        outcome = run_stage(folder, inputs, build, name=name)
        seconds[name] = 0.0 if outcome.reused else time.perf_counter() - start
        log.info("stage %s %s", name, "reused" if outcome.reused else "built")
        return outcome

    render_inputs = {
        "synptv": version("synptv"),
        "format_version": FORMAT_VERSION,
        "seed": scenario.seed,
        "flow": scenario.as_dict()["flow"],
        "rig": rig.spec,
        "calibration": {
            k: v for k, v in scenario.as_dict()["calibration"].items() if k != "methods"
        },
        "particles": scenario.as_dict()["particles"],
        "sensor": scenario.as_dict()["sensor"],
    }
    dataset = timed(
        "render",
        out / "dataset",
        render_inputs,
        lambda target: write_dataset(
            target, rig, preset, render_settings(scenario), progress=bar("render")
        ),
    )
    data = open_dataset(dataset.folder)
    detector = ImageDetector(data, DetectorSettings())
    detections = timed(
        "detect",
        out / "detections",
        {"synptv": version("synptv"), "dataset": dataset.key, "detector": detector.detector},
        lambda target: _write_detections(detector, target, bar("detect")),
    )
    store = DetectionStore(detections.folder)
    # The PTV options every statistics stage reads; which calibrations run is not one.
    analysis = {k: v for k, v in scenario.as_dict()["ptv"].items() if k != "methods"}
    settings_inputs = {"synptv": version("synptv"), "ptv": analysis, "seed": scenario.seed}
    truth_rig, truth_runs = read_truth(dataset.folder)
    # With a shared first frame every run holds the same particles at t.
    sampled = truth_runs[:1] if data.shared_first_frame else truth_runs

    def build_truth(target: Path) -> None:
        target.mkdir()
        reference = flow_truth(
            sampled, preset.parameters, scenario.flow.spectrum, settings.statistics
        )
        _write_json(target / "truth.json", reference.as_dict())

    truth = timed("truth", out / "truth", {"dataset": dataset.key, **settings_inputs}, build_truth)
    truth_dict = json.loads((truth.folder / "truth.json").read_text())

    def build_calibrations(target: Path) -> None:
        result = calibrate_dataset(
            dataset.folder,
            methods=scenario.calibration.methods,
            out=target,
            progress=bar("calibrate"),
        )
        _write_json(
            target / "table1.json",
            {"table1": result.table1, "max_plane_residual_px": result.max_plane_residual_px},
        )
        maps = {m: e["nominal"] for m, e in result.errors.items()}
        title = "Triangulated dots against their nominal positions (the paper's Fig. 3)"
        save_figure(
            error_maps(maps, title=title),
            target / "fig3_error_maps.png",
        )

    calibrations = timed(
        "calibrate",
        out / "calibrations",
        {"dataset": dataset.key, "methods": list(scenario.calibration.methods)},
        build_calibrations,
    )
    # The reference rungs have no links, so nothing for the trajectory test to catch; on
    # noise-free trajectories it would only drop the particles of largest jerk.
    unlinked = replace(
        settings, statistics=replace(settings.statistics, trajectory_threshold=None)
    )

    def statistics(runs):
        return compute_statistics(
            runs, unlinked.statistics, shared_first_frame=data.shared_first_frame
        )

    voxel = object_pixel(truth_rig)

    def save_population(result: PtvResult, folder: Path, rotation=None, translation=None):
        """population.json: the sample truth over the pairs this measurement's S2 used
        (its X(t) brought from the calibration frame to the world by the rigid
        ``rotation`` and ``translation`` the matching score found)."""
        population = result.statistics.population
        if population is None:
            return
        reference = population_truth(
            population,
            truth_runs,
            settings.statistics,
            radius=voxel,
            rotation=rotation,
            translation=translation,
        )
        _write_json(folder / "population.json", reference.as_dict())

    cameras_true = dict(zip(truth_rig.camera_names, truth_rig.cameras, strict=True))
    ptv = {}
    for variant in (*REFERENCE_VARIANTS, *scenario.ptv.methods):
        inputs = {"detections": detections.key, "variant": variant, **settings_inputs}
        if variant not in REFERENCE_VARIANTS:
            inputs["calibration"] = calibrations.key

        def build(target: Path, variant=variant) -> None:
            target.mkdir()
            tick = bar(f"ptv {variant}")
            if variant == "exact":
                runs = exact_runs(truth_runs, unlinked)
                result = PtvResult(store, data.cameras, unlinked, runs, statistics(runs))
                _save_ptv(result, target, truth_dict, "none: true trajectories")
                return
            if variant == "detection":
                count = [0]
                total = sum(data.frames)

                def step() -> None:
                    count[0] += 1
                    if tick is not None:
                        tick(count[0], total)

                cams = [cameras_true[name] for name in data.cameras]
                runs, quality = detected_runs(store, truth_runs, cams, unlinked, tick=step)
                result = PtvResult(store, data.cameras, unlinked, runs, statistics(runs))
                _save_ptv(result, target, truth_dict, "true cameras, truth-paired detections")
                _save_detection(quality, target)
                save_population(result, target)
                return
            if variant == "true-cameras":
                cams, label = cameras_true, "true cameras"
            else:
                path = calibrations.folder / f"{variant}.h5"
                cams, label = load_calibrations(path), str(path)
            result = run_pipeline(store, cams, settings, progress=tick)
            _save_ptv(result, target, truth_dict, label)
            ordered = [cams[name] for name in data.cameras]
            quality = score_matching(store, truth_runs, ordered, settings, voxel=voxel)
            _write_json(target / "matching.json", quality.as_dict())
            save_population(result, target, quality.rotation, quality.translation)

        ptv[variant] = timed(f"ptv {variant}", out / "ptv" / variant, inputs, build)
    return ExperimentStages(dataset, detections, truth, calibrations, ptv, seconds)


def _save_detection(quality, folder: Path) -> None:
    """detection.json and the fractional-position histograms (peak-locking diagnostic)."""
    locking = {name: peak_locking(xy) for name, xy in quality.detected_xy.items()}
    _write_json(
        folder / "detection.json",
        {
            "cameras": list(quality.cameras),
            "rms_error_px": quality.rms_error_px.tolist(),
            "found": quality.found.tolist(),
            "spurious": quality.spurious.tolist(),
            "position_noise_m": quality.position_noise.tolist(),
            "dt": quality.dt.tolist(),
            "displacement_noise_m": quality.displacement_noise.tolist(),
            "peak_locking": {
                name: {
                    "amplitude_px": pl.amplitude.tolist(),
                    "p_chi2": pl.p_chi2.tolist(),
                    "locked": pl.locked(),
                    "counts": pl.counts.tolist(),
                    "edges": pl.edges.tolist(),
                }
                for name, pl in locking.items()
            },
        },
    )
    save_figure(peak_locking_figure(locking), folder / "peak_locking.png")
