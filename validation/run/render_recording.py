"""Render time-resolved recordings as a lab's high-speed cameras record them.

Layout of a recorded dataset folder (lengths in m, times in s)::

    experiment.json                     the calibration's description: cameras, the
                                        plate, its traverse, the plate images' layout
    calibration/<camera>/plane_<jj>.tif 16-bit plate image at traverse position j
    truth.h5                            the plate's truth (:mod:`validation.truth.truth_file`)
    sequence<s>/experiment.json         recording s as a time-resolved dataset that
                                        ``synptv ptv`` reads (``time_resolved``: frame
                                        rate, frame-number pattern, the multi-Δt steps)
    sequence<s>/images/<camera>/<nnnnnn>.tif   frame n of camera, 16-bit
    sequence<s>/truth.h5                every particle at every frame
                                        (:mod:`validation.truth.recording_truth`)

Each sequence is one realization of the flow (:func:`simulator.recording.follow_recording`,
seeded by the run's seed and s): tracers seeded uniformly in the sheet padded by how far
they travel, so that they enter and leave the sheet as the flow carries them. Its frames
are rendered :data:`FRAMES_PER_CHUNK` at a time on the executor, each camera's sensor
noise seeded by the frame (:func:`frame_rng`), so the images do not depend on how the
work is cut. A folder left half-written is completed: the sequences' particles and the
chunks of frames recorded in their truth.h5 are kept.
"""

import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from simulator.dns.stationary_flow import DnsTracerFlow
from simulator.particles import KSFlow
from simulator.presets import FlowPreset
from simulator.recording import follow_periodic_recording, follow_recording
from simulator.render.camera_frames import ParticleLighting, record_particles, rig_lighting
from simulator.render.sensor import Sensor
from simulator.rigs import Rig
from simulator.target import build_plate, traverse_positions
from validation.run.particle_chunks import write_tiff
from validation.run.render_dataset import (
    RenderSettings,
    calibration_description,
    truth_header,
    write_plates,
)
from validation.run.run_flow import RunFlow
from validation.truth.recording_truth import RecordingTruthWriter, frame_chunks
from validation.truth.truth_file import TruthWriter
from validation.workflow.parallel import Executor, InProcess

#: Frames rendered in one task.
FRAMES_PER_CHUNK = 10
#: The frames' file pattern inside a sequence folder.
IMAGE_PATTERN = "images/{camera}/{n:06d}.tif"

Progress = Callable[[int, int], None]


@dataclass(frozen=True)
class RecordingPlan:
    """What is recorded: the frame rate, the frames of each sequence, the sequences and
    the frame steps of the multi-Δt method.

    Attributes
    ----------
    frame_rate : float
        Hz.
    frames : int
        Frames per sequence.
    sequences : int
        Independent recordings.
    steps : tuple of int
        Frame separations of the Δt values.
    """

    frame_rate: float
    frames: int
    sequences: int
    steps: tuple[int, ...]


def sequence_folder(dataset: Path, s: int) -> Path:
    """The folder of recording s of a recorded dataset."""
    return Path(dataset) / f"sequence{s}"


def frame_rng(seed: int, sequence: int, camera: int, frame: int) -> np.random.Generator:
    """The sensor noise of one frame of one camera."""
    entropy = [int(seed), 4, int(sequence), int(camera), int(frame)]
    return np.random.default_rng(np.random.SeedSequence(entropy))


@dataclass(frozen=True)
class FrameJob:
    """What every chunk of frames of a sequence shares (see :func:`render_frames`)."""

    rig: Rig
    lighting: ParticleLighting
    sensor: Sensor
    seed: int
    sequence: int
    folder: Path


def render_frames(item: tuple[int, list[np.ndarray]], *, job: FrameJob):
    """Render, record and write the frames f0, f0 + 1, … of every camera.

    Parameters
    ----------
    item : (int, list of ndarray (P_f, 3))
        The first frame f0 and the particle positions of each frame, m.
    job : FrameJob

    Returns
    -------
    (dict, dict)
        Per camera, the exact image positions (rows, 2) float32, px, and the lit and
        on-sensor flags (rows,) of the chunk's particle-frames in order.
    """
    f0, positions = item
    xy, visible = {}, {}
    for c, (name, camera) in enumerate(zip(job.rig.camera_names, job.rig.cameras, strict=True)):
        parts_xy, parts_visible = [], []
        for f, x in enumerate(positions, start=f0):
            recorded = record_particles(
                camera,
                x,
                lighting=job.lighting,
                sensor=job.sensor,
                rng=frame_rng(job.seed, job.sequence, c, f),
            )
            write_tiff(job.folder / IMAGE_PATTERN.format(camera=name, n=f), recorded.image)
            parts_xy.append(recorded.xy.astype(np.float32))
            parts_visible.append(recorded.visible)
        xy[name] = np.concatenate(parts_xy)
        visible[name] = np.concatenate(parts_visible)
    return xy, visible


def sequence_description(rig: Rig, plan: RecordingPlan, settings: RenderSettings) -> dict:
    """experiment.json of one recording: what ``synptv ptv`` needs to process it."""
    return {
        "units": "SI (m, s); pixel coordinates: x = column, y = row, (0, 0) = centre of the "
        "top-left pixel",
        "description": f"time-resolved recording: {plan.frames} frames at {plan.frame_rate:.6g} Hz",
        "cameras": {
            name: {"image_size": list(camera.lens.sensor_size)}
            for name, camera in zip(rig.camera_names, rig.cameras, strict=True)
        },
        "acquisition": "time-resolved",
        "time_resolved": {
            "frame_rate": plan.frame_rate,
            "images": IMAGE_PATTERN,
            "steps": list(plan.steps),
            "first": 0,
            "last": plan.frames - 1,
        },
        "bit_depth": settings.sensor.bit_depth,
    }


def _write_sequence(
    folder: Path,
    s: int,
    rig: Rig,
    preset: FlowPreset,
    flow: RunFlow,
    settings: RenderSettings,
    plan: RecordingPlan,
    executor: Executor,
    tick: Callable[[], None],
) -> None:
    """Follow, render and write recording s into ``folder``; ``tick`` after each chunk."""
    chunks = frame_chunks(plan.frames, FRAMES_PER_CHUNK)
    truth = RecordingTruthWriter(folder / "truth.h5", rig.camera_names, chunks)
    if not truth.started():
        folder.mkdir(parents=True, exist_ok=True)
        recorded = _follow(flow, plan, settings, rig, s)
        truth.create(recorded, plan.frame_rate, s, truth_header(rig, preset, flow))
    todo = truth.todo()
    for _ in range(len(chunks) - len(todo)):
        tick()
    lighting = rig_lighting(settings.lighting, rig)
    job = FrameJob(rig, lighting, settings.sensor, settings.seed, s, folder)
    items = [(chunks[i][0], truth.positions(i)) for i in todo]
    for i, (xy, visible) in executor.map(render_frames, items, shared={"job": job}):
        truth.write_chunk(todo[i], xy, visible)
        tick()
    truth.finish()
    description = sequence_description(rig, plan, settings)
    (folder / "experiment.json").write_text(json.dumps(description, indent=2))


def _follow(flow: RunFlow, plan: RecordingPlan, settings: RenderSettings, rig: Rig, s: int):
    """The tracers of recording s: kinematic simulation, or a DNS's snapshot s with its
    periodic images (:mod:`simulator.recording`)."""
    rng = np.random.SeedSequence([settings.seed, 3, s])
    if isinstance(flow.tracers, KSFlow):
        return follow_recording(
            flow.tracers,
            plan.frame_rate,
            plan.frames,
            particles=settings.particles,
            region=rig.sheet,
            rng=rng,
        )
    if isinstance(flow.tracers, DnsTracerFlow):
        return follow_periodic_recording(
            flow.tracers,
            flow.tracers.spec.setup().grid.box_side,
            plan.frame_rate,
            plan.frames,
            particles=settings.particles,
            region=rig.sheet,
            rng=rng,
            snapshot=s,
        )
    raise ValueError("a recording follows a kinematic simulation or a DNS")


def _plates_written(path: Path) -> bool:
    """Whether a recorded dataset's truth.h5 holds every plate image's truth (its record
    of parts is dropped once complete)."""
    try:
        with h5py.File(path, "r") as f:
            return "plate" in f and "progress" not in f
    except OSError:
        return False


def build_recording_dataset(
    target: Path,
    rig: Rig,
    preset: FlowPreset,
    flow: RunFlow,
    settings: RenderSettings,
    plan: RecordingPlan,
    *,
    executor: Executor | None = None,
    progress: Progress | None = None,
) -> Path:
    """Render the plate images and every recording into ``target``, resuming what is there.

    Parameters
    ----------
    target : Path
        The dataset folder (created, or completed).
    rig : Rig
        Cameras and sheet.
    preset : FlowPreset
        The flow's scales (written to the truth).
    flow : RunFlow
        A kinematic-simulation flow, or a DNS's (recording s starts at its snapshot s).
    settings : RenderSettings
        Plate, traverse, tracers in the sheet, lighting, sensor, seed (``frames`` and
        ``shared_first_frame`` are the frame pairs' and not used).
    plan : RecordingPlan
        Frame rate, frames, sequences, steps.
    executor : Executor, optional
        Where the images are rendered (default: this process).
    progress : callable(done, total), optional
        Called after each plate image and each chunk of frames.

    Returns
    -------
    Path
        ``target``.
    """
    executor = InProcess() if executor is None else executor
    target.mkdir(parents=True, exist_ok=True)
    plate = build_plate(
        rig.plate,
        traverse_positions(settings.planes, rig.plane_spacing),
        imperfections=settings.imperfections,
        rng=settings.seed,
    )
    chunks = len(frame_chunks(plan.frames, FRAMES_PER_CHUNK))
    planes = len(rig.cameras) * settings.planes
    total = planes + plan.sequences * chunks
    done = [0]

    def tick() -> None:
        done[0] += 1
        if progress is not None:
            progress(done[0], total)

    if not _plates_written(target / "truth.h5"):
        plates = TruthWriter(
            target / "truth.h5",
            header=truth_header(rig, preset, flow),
            cameras=rig.camera_names,
            planes=settings.planes,
            chunks=[],
            frames=0,
            shared_first_frame=False,
        )
        written, _ = plates.done()
        todo = [(c, j) for c, j in zip(*np.nonzero(~written), strict=True)]
        done[0] += planes - len(todo)
        write_plates(target, rig, plate, settings, todo, plates, executor, tick)
        plates.finish()
    else:
        done[0] += planes
    for s in range(plan.sequences):
        folder = sequence_folder(target, s)
        if (folder / "experiment.json").is_file():  # written last: the sequence is whole
            done[0] += chunks
            continue
        _write_sequence(folder, s, rig, preset, flow, settings, plan, executor, tick)
    description = calibration_description(rig, plate, settings)
    description["acquisition"] = (
        f"time-resolved: {plan.sequences} recording(s) in sequence<s>/, each a dataset of its own"
    )
    (target / "experiment.json").write_text(json.dumps(description, indent=2))
    return target
