"""Write a rendered PTV dataset that any PTV software could process (``synptv render``).

Layout of a dataset folder (all lengths in m, times in s)::

    experiment.json                       what a real experiment provides: camera names and
                                          image size, the plate design and its traverse
                                          positions Z_j, the Δt values, the file layout
    calibration/<camera>/plane_<jj>.tif   16-bit plate image at traverse position j
    particles/dt<k>/<camera>/<mmmmmm>_a.tif   frame pair m of the double-frame run at Δt_k:
    particles/dt<k>/<camera>/<mmmmmm>_b.tif   frame a at t, frame b at t + Δt_k (with
                                          ``shared_first_frame``, frame a of snapshot m
                                          is the same image for every k, hard-linked);
                                          only when the particle images are kept
    truth.h5                              the simulator's ground truth (ptv never reads
                                          it; layout in :mod:`validation.truth.truth_file`)

The plate images are rendered one task per camera and plane, the particles one task per
chunk of snapshots (:mod:`validation.run.particle_chunks`), on any
:class:`validation.workflow.parallel.Executor`; each task seeds its randomness from what it
draws, so the dataset is the same whichever executor runs it. :func:`build_dataset`
resumes a folder it left half-written (the parts done are recorded in truth.h5); it can
also detect the particles of every chunk in memory and write them as a detection store
(:mod:`ptv.detect.store`) instead of, or beside, the particle images.
:func:`write_dataset` builds a complete dataset with images under a temporary name and
renames it when complete, so an interrupted run leaves no half-written dataset.
"""

import json
import shutil
import tempfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

from ptv.detect.store import chunk_name, write_chunk
from ptv.settings import DetectorSettings
from simulator.ks_field import DEFAULT_UNSTEADINESS
from simulator.particles import KSFlow
from simulator.presets import FlowPreset
from simulator.render.camera_frames import ParticleLighting, rig_lighting
from simulator.render.plate import render_plate
from simulator.render.sensor import Sensor
from simulator.rigs import Rig
from simulator.spectra import SPECTRA
from simulator.target import (
    REALISTIC,
    Imperfections,
    PhysicalPlate,
    build_plate,
    traverse_positions,
)
from validation.run.particle_chunks import (
    ParticleJob,
    chunk_detections,
    render_chunk,
    snapshot_chunks,
    write_tiff,
)
from validation.run.run_flow import RunFlow
from validation.truth.exact import SpectrumStructure
from validation.truth.truth_file import TruthWriter
from validation.workflow.parallel import Executor, InProcess

#: Version of the dataset layout (experiment.json and truth.h5).
FORMAT_VERSION = 2

Progress = Callable[[int, int], None]


@dataclass(frozen=True)
class RenderSettings:
    """What ``synptv render`` draws.

    Attributes
    ----------
    frames : int
        Frame pairs (independent snapshots) per Δt.
    planes : int
        Traverse positions of the calibration plate, centred on Z = 0 (the rig gives
        the plate and the traverse's step: :attr:`simulator.rigs.Rig.plate`).
    imperfections : Imperfections
        Deviations of the physical plate and traverse (truth kept in truth.h5).
    plate_brightness : float
        Photo-electrons of a fully lit plate pixel.
    particles : int
        Mean number of particles in the illuminated sheet per snapshot.
    spectrum : str
        ``pope`` or ``k41-band``.
    n_modes : int
        KS modes.
    unsteadiness : float
        λ of the KS frequencies ω_n = λ √(k_n³ E(k_n)) (:func:`simulator.ks_field.draw_ks_field`).
    lighting : ParticleLighting
        Tracer size and laser sheet.
    sensor : Sensor
        Camera noise model, shared by particle and plate images.
    shared_first_frame : bool
        True (default): every Δt from the same snapshots, frame a shared
        (:func:`simulator.particles.shared_start`, the paper's time-resolved
        acquisition); False: one independent experiment per Δt
        (:func:`simulator.particles.double_frame`).
    seed : int
        Seed of every random choice.
    centre_noise : float or None
        A points dataset: no particle image is drawn, and each lit particle's exact image
        centre plus white Gaussian noise of this many pixels per axis stands for its
        detection (:attr:`validation.run.particle_chunks.ParticleJob.centre_noise`; for
        what the stack does without images, e.g. ``benchmarks/bench_false_alarms.py``).
        None (default) renders.
    """

    frames: int = 10
    planes: int = 13
    imperfections: Imperfections = REALISTIC
    plate_brightness: float = 4000.0
    particles: int = 1000
    spectrum: str = "pope"
    n_modes: int = 200
    unsteadiness: float = DEFAULT_UNSTEADINESS
    lighting: ParticleLighting = field(default_factory=ParticleLighting)
    sensor: Sensor = field(default_factory=Sensor)
    shared_first_frame: bool = True
    seed: int = 0
    centre_noise: float | None = None


def _camera_attributes(camera) -> dict:
    lens = camera.lens
    attrs = {
        "center": np.asarray(camera.center),
        "rotation_world_to_camera": np.asarray(camera.rotation),
        "focal_length": lens.focal_length,
        "image_distance": lens.fx * lens.pixel_pitch,
        "pixel_pitch": lens.pixel_pitch,
        "sensor_size": np.asarray(lens.sensor_size),
        "principal_point": np.asarray(lens.camera_matrix()[:2, 2]),
        "distortion_k1_k2_k3_p1_p2": np.asarray(
            [lens.k1, lens.k2, lens.k3, lens.p1, lens.p2], dtype=float
        ),
        "tilt_tau_x_tau_y": np.asarray([lens.tau_x, lens.tau_y]),
        "f_number": lens.f_number,
    }
    if camera.interfaces is not None:
        attrs["window_normal"] = np.asarray(camera.interfaces.normal)
        attrs["window_offsets"] = np.asarray(camera.interfaces.offsets)
        attrs["window_indices"] = np.asarray(camera.interfaces.indices)
    return attrs


def calibration_description(rig: Rig, plate, settings: RenderSettings) -> dict:
    """What a real experiment provides to calibrate: camera names and image size, the
    nominal target, the traverse, the plate images' layout, the bit depth."""
    return {
        "format_version": FORMAT_VERSION,
        "units": "SI (m, s); pixel coordinates: x = column, y = row, (0, 0) = centre of the "
        "top-left pixel",
        "cameras": {
            name: {
                "image_size": list(camera.lens.sensor_size),
                "pixel_pitch": camera.lens.pixel_pitch,
                "focal_length": camera.lens.focal_length,
            }
            for name, camera in zip(rig.camera_names, rig.cameras, strict=True)
        },
        "target": rig.plate.as_dict(),
        "traverse_z": [float(z) for z in plate.z_nominal],
        "calibration_images": "calibration/{camera}/plane_{j:02d}.tif",
        "bit_depth": settings.sensor.bit_depth,
    }


def _experiment_description(
    rig: Rig, plate, dt: np.ndarray, settings: RenderSettings, *, images: bool
) -> dict:
    """What a real experiment provides: the nominal target, the traverse, Δt, file layout."""
    description = calibration_description(rig, plate, settings)
    bit_depth = description.pop("bit_depth")
    return {
        **description,
        "dt": [float(d) for d in dt],
        "frames_per_dt": settings.frames,
        "acquisition": "double frame: frame a shared by every dt"
        if settings.shared_first_frame
        else "double frame: one independent run per dt",
        "shared_first_frame": settings.shared_first_frame,
        "particle_images": "particles/dt{k}/{camera}/{m:06d}_{a|b}.tif" if images else None,
        "bit_depth": bit_depth,
    }


def ks_flow(preset: FlowPreset, settings: RenderSettings) -> RunFlow:
    """Kinematic simulation of the settings' spectrum, modes and unsteadiness."""
    if settings.spectrum not in SPECTRA:
        raise ValueError(f"unknown spectrum {settings.spectrum!r}; known: {', '.join(SPECTRA)}")
    spectrum = SPECTRA[settings.spectrum](preset.parameters)
    tracers = KSFlow(spectrum, n_modes=settings.n_modes, unsteadiness=settings.unsteadiness)
    attrs = {
        "spectrum": settings.spectrum,
        "n_modes": settings.n_modes,
        "unsteadiness": settings.unsteadiness,
    }
    return RunFlow(preset, tracers, attrs, SpectrumStructure(spectrum))


def truth_header(rig: Rig, preset: FlowPreset, flow: RunFlow):
    """Writes the flow, the cameras and the rig into a new truth.h5."""

    def write(truth: h5py.File) -> None:
        truth.attrs["rig"] = json.dumps(rig.spec)
        group = truth.create_group("flow")
        for key, value in preset.parameters.as_dict().items():
            group.attrs[key] = value
        group.attrs["preset"] = preset.name
        group.attrs["dt"] = np.asarray(preset.dt, dtype=float)
        group.attrs["dt_over_tau_eta"] = np.asarray(preset.dt_over_tau_eta, dtype=float)
        for key, value in flow.attrs.items():
            group.attrs[key] = value
        for key, value in flow.datasets.items():
            group[key] = value
        for name, camera in zip(rig.camera_names, rig.cameras, strict=True):
            group = truth.create_group(f"cameras/{name}")
            for key, value in _camera_attributes(camera).items():
                group.attrs[key] = value

    return write


@dataclass(frozen=True)
class PlateJob:
    """What every plate image of a dataset shares (see :func:`render_plate_image`)."""

    rig: Rig
    plate: PhysicalPlate
    brightness: float
    sensor: Sensor
    seed: int


def render_plate_image(item: tuple[int, int], *, job: PlateJob):
    """Plate image j of camera c, recorded by the sensor (noise seeded by c and j).

    Returns
    -------
    (ndarray uint16 (H, W), ndarray (D, 2), ndarray (D, 2), ndarray bool (D,))
        The image, the image of each dot centre, the centroid of its light, whether the
        whole dot is on the sensor.
    """
    c, j = item
    rendered = render_plate(
        job.plate, job.rig.cameras[c], j, full_brightness=job.brightness, defocus=True
    )
    rng = np.random.default_rng(np.random.SeedSequence([job.seed, 1, c, j]))
    image = job.sensor.record(rendered.image, rng)
    return image, rendered.projected, rendered.centroid, rendered.on_sensor


def particle_job(
    rig: Rig,
    preset: FlowPreset,
    settings: RenderSettings,
    *,
    flow: RunFlow | None = None,
    detector: DetectorSettings | None = None,
    images: Path | None = None,
) -> ParticleJob:
    """The :class:`validation.run.particle_chunks.ParticleJob` of a dataset's particles
    (``flow``: default the KS flow of the settings, :func:`ks_flow`)."""
    flow = ks_flow(preset, settings) if flow is None else flow
    return ParticleJob(
        rig=rig,
        flow=flow.tracers,
        dt=np.asarray(preset.dt, dtype=float),
        frames=settings.frames,
        particles=settings.particles,
        lighting=rig_lighting(settings.lighting, rig),
        sensor=settings.sensor,
        shared_first_frame=settings.shared_first_frame,
        seed=settings.seed,
        detector=detector,
        images=images,
        centre_noise=settings.centre_noise,
    )


@dataclass(frozen=True)
class DetectionOutput:
    """Where and how :func:`build_dataset` detects the particles of every chunk.

    Attributes
    ----------
    folder : Path
        The detection store's folder (chunk files written there as they finish).
    detector : DetectorSettings
        Threshold and saturation.
    """

    folder: Path
    detector: DetectorSettings


def write_plates(
    target: Path,
    rig: Rig,
    plate: PhysicalPlate,
    settings: RenderSettings,
    todo: list[tuple[int, int]],
    truth: TruthWriter,
    executor: Executor,
    tick: Callable[[], None],
) -> None:
    """Render the plate images ``todo`` ((camera, plane) pairs) of a dataset into
    ``target/calibration`` and their dots' truth into ``truth``; ``tick`` after each."""
    dots = {
        "z_nominal": plate.z_nominal,
        "z_actual": np.array([p.z_actual for p in plate.poses]),
        "dots_world": np.stack([plate.dot_centres(j) for j in range(len(plate.poses))]),
        "dot_indices": rig.plate.indices,
    }
    job = PlateJob(rig, plate, settings.plate_brightness, settings.sensor, settings.seed)
    for i, (image, *dot_truth) in executor.map(render_plate_image, todo, shared={"job": job}):
        c, j = todo[i]
        write_tiff(target / "calibration" / rig.camera_names[c] / f"plane_{j:02d}.tif", image)
        truth.write_plate(c, j, *dot_truth, dots)
        tick()


def build_dataset(
    target: Path,
    rig: Rig,
    preset: FlowPreset,
    settings: RenderSettings,
    *,
    flow: RunFlow | None = None,
    images: bool = True,
    detections: DetectionOutput | None = None,
    executor: Executor | None = None,
    progress: Progress | None = None,
) -> Path:
    """Simulate and render a dataset into ``target``, resuming what is there.

    Parameters
    ----------
    target : Path
        The dataset folder (created; a folder this function left unfinished is
        completed: parts recorded as written are not computed again).
    rig : Rig
        Cameras and sheet.
    preset : FlowPreset
        Flow and Δt set.
    settings : RenderSettings
        Sizes, plate, lighting, sensor and seed.
    flow : RunFlow, optional
        The flow (default: the KS flow of ``settings``, :func:`ks_flow`).
    images : bool
        Write the particle images (the plate images and truth.h5 always are).
    detections : DetectionOutput, optional
        Also detect the particles of every exposure in memory and write the chunks of a
        detection store (:mod:`ptv.detect.store`; its index is the caller's to write).
    executor : Executor, optional
        Where the images are rendered (default: this process).
    progress : callable(done, total), optional
        Called after each plate image and each chunk of snapshots.

    Returns
    -------
    Path
        ``target``.
    """
    executor = InProcess() if executor is None else executor
    flow = ks_flow(preset, settings) if flow is None else flow
    job = particle_job(
        rig,
        preset,
        settings,
        flow=flow,
        detector=None if detections is None else detections.detector,
        images=target if images else None,
    )
    target.mkdir(parents=True, exist_ok=True)
    plate = build_plate(
        rig.plate,
        traverse_positions(settings.planes, rig.plane_spacing),
        imperfections=settings.imperfections,
        rng=settings.seed,
    )
    chunks = snapshot_chunks(settings.frames)
    names = rig.camera_names
    truth = TruthWriter(
        target / "truth.h5",
        header=truth_header(rig, preset, flow),
        cameras=names,
        planes=settings.planes,
        chunks=chunks,
        frames=settings.frames,
        shared_first_frame=settings.shared_first_frame,
    )
    plates_done, chunks_done = truth.done()
    if detections is not None:
        detections.folder.mkdir(parents=True, exist_ok=True)
        chunks_done &= [(detections.folder / chunk_name(*c)).is_file() for c in chunks]
    plates = [(c, j) for c in range(len(names)) for j in range(settings.planes)]
    todo_plates = [p for p in plates if not plates_done[p]]
    todo_chunks = [i for i in range(len(chunks)) if not chunks_done[i]]
    total = len(plates) + len(chunks)
    done = [total - len(todo_plates) - len(todo_chunks)]

    def tick() -> None:
        done[0] += 1
        if progress is not None:
            progress(done[0], total)

    write_plates(target, rig, plate, settings, todo_plates, truth, executor, tick)
    frames = (settings.frames,) * len(job.dt)
    for i, rendered in executor.map(
        render_chunk, [chunks[i] for i in todo_chunks], shared={"job": job}
    ):
        if detections is not None:
            found = chunk_detections(rendered, job, target)
            write_chunk(detections.folder / chunk_name(*rendered.snapshots), found, frames=frames)
        truth.write_chunk(todo_chunks[i], rendered.truth)
        tick()
    truth.finish()
    description = _experiment_description(rig, plate, job.dt, settings, images=images)
    (target / "experiment.json").write_text(json.dumps(description, indent=2))
    return target


def write_dataset(
    out: Path,
    rig: Rig,
    preset: FlowPreset,
    settings: RenderSettings,
    *,
    executor: Executor | None = None,
    progress: Progress | None = None,
) -> Path:
    """Simulate, render and write a complete dataset folder, images included.

    Parameters
    ----------
    out : Path
        Destination folder; must not exist. Built under a temporary name beside it and
        renamed when complete.
    rig, preset, settings, executor, progress :
        As :func:`build_dataset`.

    Returns
    -------
    Path
        ``out``.
    """
    out = Path(out)
    if out.exists():
        raise ValueError(f"output folder {str(out)!r} already exists; choose a new one")
    out.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{out.name}.partial-", dir=out.parent))
    try:
        build_dataset(
            staging / out.name, rig, preset, settings, executor=executor, progress=progress
        )
        (staging / out.name).rename(out)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return out
