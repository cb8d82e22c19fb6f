"""``synptv run`` on a scenario with ``[recording]``: a time-resolved experiment.

Stages (folders of ``out``, reused when their inputs are unchanged,
:mod:`validation.workflow.stages`):

``dataset/``          the plate images and every recording, rendered
                      (:func:`validation.run.render_recording.build_recording_dataset`)
``calibrations/``     every calibration method from the plate images (as frame-pair
                      runs do)
``tracks/<variant>/`` per recording (``sequence<s>/``) the PTV of a lab
                      (:func:`ptv.pipeline.time_resolved.run_recording`: detect, match,
                      track, and the multi-Δt statistics of its frame pairs) with the
                      true cameras and with each calibration; then the tracks fitted,
                      scored against the true trajectories and the Lagrangian
                      statistics against the flow's exact values
                      (:mod:`validation.run.recording_scores`)
``report.html``, ``results.json``, ``figures/``   what :mod:`validation.report.recording_report`
                      writes
"""

import json
import logging
from dataclasses import asdict, dataclass, replace
from pathlib import Path

from ptv.calibration.io import load_calibrations
from ptv.detect.frames import ImageDetector
from ptv.io.dataset import open_dataset
from ptv.pipeline.results import save_results
from ptv.pipeline.time_resolved import run_recording
from ptv.pipeline.track_csv import save_tracks_csv
from validation.run.experiment import ExperimentRun
from validation.run.recording_scores import score_sequences
from validation.run.render_recording import (
    RecordingPlan,
    build_recording_dataset,
    sequence_folder,
)
from validation.run.scenario import Scenario
from validation.truth.recording_truth import read_recording_truth
from validation.workflow.parallel import Executor, InProcess
from validation.workflow.stages import StageOutcome

log = logging.getLogger(__name__)

#: The tracks computed besides the calibrations': through the rig's true cameras.
TRUE_CAMERAS = "true-cameras"


@dataclass(frozen=True)
class RecordingStages:
    """The stage folders of a recorded run, what each took (``times``: name →
    :class:`~validation.workflow.clock.StageTime`), and the flow's scales."""

    dataset: StageOutcome
    calibrations: StageOutcome
    tracks: dict
    times: dict
    flow: dict
    plan: RecordingPlan


def recording_plan(scenario: Scenario, tau_eta: float) -> RecordingPlan:
    """What a scenario's ``[recording]`` records, for a flow of Kolmogorov time
    ``tau_eta`` (s)."""
    r = scenario.recording
    return RecordingPlan(
        frame_rate=r.rate(tau_eta), frames=r.frames, sequences=r.sequences, steps=r.steps
    )


def _write_json(path: Path, data) -> None:
    path.write_text(json.dumps(data, indent=2, allow_nan=False))


class RecordingRun:
    """The stages of a recorded scenario under a folder (module docstring)."""

    def __init__(self, scenario: Scenario, out: Path, executor: Executor, progress) -> None:
        self.run = ExperimentRun(scenario, out, executor, progress, keep_images=True)
        self.scenario = scenario
        self.plan = recording_plan(scenario, self.run.preset.parameters.tau_eta)

    def dataset(self) -> StageOutcome:
        """The plate images and the recordings."""
        run = self.run
        inputs = {**run.particle_inputs(), "recording": asdict(self.plan)}
        return run.timed(
            "render",
            run.out / "dataset",
            inputs,
            lambda target: build_recording_dataset(
                target,
                run.rig,
                run.preset,
                run.flow,
                run.render,
                self.plan,
                executor=run.executor,
                progress=run.bar("render"),
            ),
            resume=True,
        )

    def tracks(
        self, dataset: StageOutcome, calibrations: StageOutcome, variant: str
    ) -> StageOutcome:
        """The tracks of every recording with the true cameras or a calibration, and
        their scores."""
        run = self.run
        inputs = {
            "dataset": dataset.key,
            "variant": variant,
            "recording": asdict(self.scenario.recording),
            "detector": run.detector.as_dict(),
            **run.settings_inputs,
        }
        if variant != TRUE_CAMERAS:
            inputs["calibration"] = calibrations.key

        def build(target: Path) -> None:
            if variant == TRUE_CAMERAS:
                cams = dict(zip(run.rig.camera_names, run.rig.cameras, strict=True))
                described = "true cameras"
            else:
                path = calibrations.folder / f"{variant}.h5"
                cams, described = load_calibrations(path), str(path)
            through = "true cameras" if variant == TRUE_CAMERAS else f"{variant} calibration"
            target.mkdir()
            settings = run.settings
            if self.scenario.recording.max_acceleration is not None:
                settings = replace(
                    settings, max_acceleration=self.scenario.recording.max_acceleration
                )
            sequences = []
            for s in range(self.plan.sequences):
                folder = sequence_folder(dataset.folder, s)
                detector = ImageDetector(open_dataset(folder), run.detector)
                result = run_recording(
                    detector, cams, settings, progress=run.bar(f"tracks {variant} {s}")
                )
                out = target / folder.name
                out.mkdir()
                save_results(result, out, calibration=described, links=False)
                save_tracks_csv(result, out)
                sequences.append((result, read_recording_truth(folder)))
            scores = score_sequences(
                sequences,
                tau_eta=run.preset.parameters.tau_eta,
                fit_window=self.scenario.recording.fit_window,
                seed=self.scenario.seed,
                figures=target,
                label=f"{self.scenario.name}: tracks through the {through}",
            )
            _write_json(target / "scores.json", scores)

        return run.timed(f"tracks {variant}", run.out / "tracks" / variant, inputs, build)


def run_recording_stages(
    scenario: Scenario,
    out: Path,
    *,
    progress=None,
    executor: Executor | None = None,
) -> RecordingStages:
    """Run (or reuse) every stage of a recorded scenario under ``out``.

    Parameters
    ----------
    scenario : Scenario
        With ``recording``.
    out : Path
        Output folder (created).
    progress : callable(stage name) -> callable(done, total), optional
        A progress callback per stage.
    executor : Executor, optional
        Where the frames are rendered (default: this process).

    Returns
    -------
    RecordingStages
    """
    executor = InProcess() if executor is None else executor
    Path(out).mkdir(parents=True, exist_ok=True)
    recorded = RecordingRun(scenario, Path(out), executor, progress)
    dataset = recorded.dataset()
    calibrations = recorded.run.calibrations(dataset)
    failed = json.loads((calibrations.folder / "table1.json").read_text()).get("failed", {})
    tracks = {
        variant: recorded.tracks(dataset, calibrations, variant)
        for variant in (TRUE_CAMERAS, *scenario.ptv.methods)
        if variant not in failed
    }
    return RecordingStages(
        dataset,
        calibrations,
        tracks,
        recorded.run.times,
        flow=recorded.run.flow.scales,
        plan=recorded.plan,
    )
