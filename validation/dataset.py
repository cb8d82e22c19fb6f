"""Write a rendered PTV dataset that any PTV software could process (``synptv render``).

Layout of a dataset folder (all lengths in m, times in s)::

    experiment.json                       what a real experiment provides: camera names and
                                          image size, the plate design and its traverse
                                          positions Z_j, the Δt values, the file layout
    calibration/<camera>/plane_<jj>.tif   16-bit plate image at traverse position j
    particles/dt<k>/<camera>/<mmmmmm>_a.tif   frame pair m of the double-frame run at Δt_k:
    particles/dt<k>/<camera>/<mmmmmm>_b.tif   frame a at t, frame b at t + Δt_k (with
                                          ``shared_first_frame``, frame a of snapshot m
                                          is the same image for every k)
    truth.h5                              the simulator's ground truth (ptv never reads it)

``truth.h5`` holds ``/cameras/<camera>`` (attributes: pupil centre, rotation, lens and
window parameters), ``/flow`` (attributes: u', ε, ν, the preset, the spectrum),
``/plate`` (``z_nominal`` (N_Z,), ``z_actual`` (N_Z,), ``dots_world`` (N_Z, D, 3) and per
camera ``<camera>/dots_xy`` (N_Z, D, 2) image of each dot centre, ``<camera>/dots_centroid``
(N_Z, D, 2) centroid of each dot's light, ``<camera>/dots_on_sensor`` (N_Z, D) whole dot
on the sensor) and ``/particles/dt<k>`` (attribute ``dt``;
``positions`` (M, 2, P, 3) at t and t + Δt, ``velocity`` (M, P, 3) at t, and per camera
``<camera>/xy`` (M, 2, P, 2) and ``<camera>/visible`` (M, 2, P)).

The folder is written under a temporary name beside the destination and renamed when
complete, so an interrupted run leaves no half-written dataset.
"""

import json
import os
import shutil
import tempfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np
import tifffile

from simulator.flow import DEFAULT_UNSTEADINESS
from simulator.particles import double_frame, shared_start
from simulator.presets import FlowPreset
from simulator.render.camera_frames import ParticleLighting, record_particles
from simulator.render.plate import render_plate
from simulator.render.sensor import Sensor
from simulator.rigs import Rig
from simulator.spectra import SPECTRA
from simulator.target import REALISTIC, Imperfections, PlateDesign, build_plate, traverse_positions

FORMAT_VERSION = 1

Progress = Callable[[int, int], None]


@dataclass(frozen=True)
class RenderSettings:
    """What ``synptv render`` draws.

    Attributes
    ----------
    frames : int
        Frame pairs (independent snapshots) per Δt.
    planes : int
        Traverse positions of the calibration plate, 1 mm apart, centred on Z = 0.
    plate : PlateDesign
        The calibration plate.
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
    """

    frames: int = 10
    planes: int = 13
    plate: PlateDesign = field(default_factory=PlateDesign)
    imperfections: Imperfections = REALISTIC
    plate_brightness: float = 4000.0
    particles: int = 1000
    spectrum: str = "pope"
    n_modes: int = 200
    lighting: ParticleLighting = field(default_factory=ParticleLighting)
    sensor: Sensor = field(default_factory=Sensor)
    shared_first_frame: bool = True
    seed: int = 0


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


def _write_tiff(path: Path, image: np.ndarray) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tifffile.imwrite(
        path, image, photometric="minisblack", compression="zlib", compressionargs={"level": 1}
    )


def _write_plates(staging: Path, truth: h5py.File, rig: Rig, plate, settings, tick) -> None:
    """Plate images per camera and plane, and the dots' truth."""
    group = truth.create_group("plate")
    group.create_dataset("z_nominal", data=plate.z_nominal)
    group.create_dataset("z_actual", data=np.array([p.z_actual for p in plate.poses]))
    group.create_dataset(
        "dots_world", data=np.stack([plate.dot_centres(j) for j in range(len(plate.poses))])
    )
    group.create_dataset("dot_indices", data=settings.plate.indices)
    rng = np.random.default_rng(settings.seed + 1)
    for name, camera in zip(rig.camera_names, rig.cameras, strict=True):
        projected, centroid, on_sensor = [], [], []
        for j in range(len(plate.poses)):
            rendered = render_plate(
                plate, camera, j, full_brightness=settings.plate_brightness, defocus=True
            )
            image = settings.sensor.record(rendered.image, rng)
            _write_tiff(staging / "calibration" / name / f"plane_{j:02d}.tif", image)
            projected.append(rendered.projected)
            centroid.append(rendered.centroid)
            on_sensor.append(rendered.on_sensor)
            tick()
        group.create_dataset(f"{name}/dots_xy", data=np.stack(projected))
        group.create_dataset(f"{name}/dots_centroid", data=np.stack(centroid))
        group.create_dataset(f"{name}/dots_on_sensor", data=np.stack(on_sensor))


def _link_or_copy(source: Path, target: Path) -> None:
    """Hard-link ``target`` to ``source``, or copy it where links are not possible."""
    target.parent.mkdir(parents=True, exist_ok=True)
    try:
        os.link(source, target)
    except OSError:
        shutil.copyfile(source, target)


def _write_particles(staging: Path, truth: h5py.File, rig: Rig, sample, settings, tick) -> None:
    """Particle frame pairs per Δt and camera, and the particles' truth.

    With a shared first frame, frame a of snapshot m is recorded once per camera (one
    exposure, one noise draw), written for the first Δt and hard-linked for the others
    (copied where the file system has no hard links).
    """
    rng = np.random.default_rng(settings.seed + 2)
    groups = []
    for k, (dt, run) in enumerate(zip(sample.dt, sample.runs, strict=True)):
        group = truth.create_group(f"particles/dt{k}")
        group.attrs["dt"] = dt
        group.create_dataset("positions", data=run.positions, compression="gzip")
        group.create_dataset("velocity", data=run.velocity[:, 0], compression="gzip")
        groups.append(group)

    def record(camera, points):
        return record_particles(
            camera, points, lighting=settings.lighting, sensor=settings.sensor, rng=rng
        )

    for name, camera in zip(rig.camera_names, rig.cameras, strict=True):
        # Independent runs seed different particle counts (the margin grows with Δt).
        xy = [np.empty((*run.positions.shape[:3], 2)) for run in sample.runs]
        visible = [np.empty(run.positions.shape[:3], dtype=bool) for run in sample.runs]
        for m in range(settings.frames):
            shared = shared_path = None
            if sample.shared_first_frame:
                shared = record(camera, sample.runs[0].positions[m, 0])
                tick()
            for k, run in enumerate(sample.runs):
                for f, label in enumerate("ab"):
                    path = staging / "particles" / f"dt{k}" / name / f"{m:06d}_{label}.tif"
                    if f == 0 and shared is not None:
                        frame = shared
                        if shared_path is None:
                            _write_tiff(path, frame.image)
                            shared_path = path
                        else:
                            _link_or_copy(shared_path, path)
                    else:
                        frame = record(camera, run.positions[m, f])
                        tick()
                        _write_tiff(path, frame.image)
                    xy[k][m, f], visible[k][m, f] = frame.xy, frame.visible
        for k, group in enumerate(groups):
            group.create_dataset(f"{name}/xy", data=xy[k], compression="gzip")
            group.create_dataset(f"{name}/visible", data=visible[k], compression="gzip")


def _experiment_description(rig: Rig, plate, dt: np.ndarray, settings: RenderSettings) -> dict:
    """What a real experiment provides: the nominal target, the traverse, Δt, file layout."""
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
        "target": settings.plate.as_dict(),
        "traverse_z": [float(z) for z in plate.z_nominal],
        "calibration_images": "calibration/{camera}/plane_{j:02d}.tif",
        "dt": [float(d) for d in dt],
        "frames_per_dt": settings.frames,
        "acquisition": "double frame: frame a shared by every dt"
        if settings.shared_first_frame
        else "double frame: one independent run per dt",
        "shared_first_frame": settings.shared_first_frame,
        "particle_images": "particles/dt{k}/{camera}/{m:06d}_{a|b}.tif",
        "bit_depth": settings.sensor.bit_depth,
    }


def write_dataset(
    out: Path,
    rig: Rig,
    preset: FlowPreset,
    settings: RenderSettings,
    *,
    progress: Progress | None = None,
) -> Path:
    """Simulate, render and write a dataset folder (layout in the module docstring).

    Parameters
    ----------
    out : Path
        Destination folder; must not exist.
    rig : Rig
        Cameras and sheet.
    preset : FlowPreset
        Flow and Δt set.
    settings : RenderSettings
        Sizes, plate, lighting, sensor and seed.
    progress : callable(done, total), optional
        Called after each simulated snapshot and each rendered image.

    Returns
    -------
    Path
        ``out``.
    """
    out = Path(out)
    if out.exists():
        raise ValueError(f"output folder {str(out)!r} already exists; choose a new one")
    if settings.spectrum not in SPECTRA:
        raise ValueError(f"unknown spectrum {settings.spectrum!r}; known: {', '.join(SPECTRA)}")
    out.parent.mkdir(parents=True, exist_ok=True)
    cameras = len(rig.cameras)
    runs = len(preset.dt)
    images = (runs + 1 if settings.shared_first_frame else 2 * runs) * settings.frames * cameras
    simulated = settings.frames * (1 if settings.shared_first_frame else runs)
    total = simulated + images + settings.planes * cameras
    done = [0]

    def tick() -> None:
        done[0] += 1
        if progress is not None:
            progress(done[0], total)

    plate = build_plate(
        settings.plate,
        traverse_positions(settings.planes),
        imperfections=settings.imperfections,
        rng=settings.seed,
    )
    simulate = shared_start if settings.shared_first_frame else double_frame
    sample = simulate(
        SPECTRA[settings.spectrum](preset.parameters),
        preset.dt,
        particles=settings.particles,
        snapshots=settings.frames,
        region=rig.sheet,
        n_modes=settings.n_modes,
        unsteadiness=DEFAULT_UNSTEADINESS,
        rng=settings.seed,
        progress=lambda _done, _total: tick(),
    )
    staging = Path(tempfile.mkdtemp(prefix=f".{out.name}.partial-", dir=out.parent))
    try:
        with h5py.File(staging / "truth.h5", "w") as truth:
            truth.attrs["format_version"] = FORMAT_VERSION
            truth.attrs["rig"] = json.dumps(rig.spec)
            flow = truth.create_group("flow")
            for key, value in preset.parameters.as_dict().items():
                flow.attrs[key] = value
            flow.attrs["preset"] = preset.name
            flow.attrs["spectrum"] = settings.spectrum
            flow.attrs["n_modes"] = settings.n_modes
            for name, camera in zip(rig.camera_names, rig.cameras, strict=True):
                group = truth.create_group(f"cameras/{name}")
                for key, value in _camera_attributes(camera).items():
                    group.attrs[key] = value
            _write_plates(staging, truth, rig, plate, settings, tick)
            _write_particles(staging, truth, rig, sample, settings, tick)
        description = _experiment_description(rig, plate, sample.dt, settings)
        (staging / "experiment.json").write_text(json.dumps(description, indent=2))
        staging.rename(out)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    return out
