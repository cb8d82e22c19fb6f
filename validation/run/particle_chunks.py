"""A chunk of a rendered run: simulate its snapshots, render every exposure, detect.

The unit of work of a rendered run is a range of snapshots m0 … m1 − 1 at every Δt
(:func:`snapshot_chunks`). :func:`render_chunk` simulates their particles, records every
exposure of every camera (:func:`simulator.render.camera_frames.record_particles`),
optionally writes the images as TIFF in the dataset layout and detects the particles in
memory (:class:`ptv.detect.frames.ChunkDetections`). The images are lossless 16-bit, so the
detections are those that reading the TIFF files back would give.

Everything random is seeded from the run's seed and the item it draws for (the
snapshot's flow and particles by :func:`simulator.particles.follow_snapshots`, each
exposure's sensor noise by :func:`exposure_rng`), so a chunk gives the same bits
whichever process computes it and however the run is cut into chunks.
"""

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import tifffile

from ptv.camera_model import on_image
from ptv.detect import detect_particles
from ptv.detect.frames import ChunkDetections, DetectedCentres, exposures
from ptv.settings import DetectorSettings
from simulator.particles import TracerFlow, double_frame, shared_start
from simulator.render.camera_frames import ParticleLighting, record_particles
from simulator.render.sensor import Sensor
from simulator.rigs import Rig
from validation.truth.truth_file import TruthRun

#: Largest number of snapshots in a chunk.
MAX_CHUNK = 10
#: Fewest chunks a run is cut into when it has enough snapshots (so that every worker
#: of a small cluster gets several).
MIN_CHUNKS = 8


def snapshot_chunks(frames: int) -> list[tuple[int, int]]:
    """Snapshot ranges (m0, m1) of a run of ``frames`` snapshots, in order.

    At most :data:`MAX_CHUNK` snapshots each and at least :data:`MIN_CHUNKS` chunks when
    there are that many snapshots; they depend on the snapshot count alone, so a resumed
    run finds the chunks it had finished.
    """
    size = max(1, min(MAX_CHUNK, -(-frames // MIN_CHUNKS)))
    return [(m0, min(m0 + size, frames)) for m0 in range(0, frames, size)]


def exposure_rng(seed: int, camera: int, k: int, m: int, frame: str) -> np.random.Generator:
    """The sensor noise of one exposure: camera index, Δt index (−1 for a shared frame
    a), snapshot and frame."""
    entropy = [int(seed), 2, int(camera), int(k) + 1, int(m), "ab".index(frame)]
    return np.random.default_rng(np.random.SeedSequence(entropy))


def particle_path(folder: Path, k: int, camera: str, m: int, frame: str) -> Path:
    """File of one particle image in the dataset layout."""
    return folder / "particles" / f"dt{k}" / camera / f"{m:06d}_{frame}.tif"


def write_tiff(path: Path, image: np.ndarray) -> None:
    """A 16-bit TIFF (zlib level 1), written under a temporary name and renamed."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.partial")
    tifffile.imwrite(
        tmp, image, photometric="minisblack", compression="zlib", compressionargs={"level": 1}
    )
    os.replace(tmp, path)


def _link_or_copy(source: Path, target: Path) -> None:
    """Hard-link ``target`` to ``source`` (replacing it), or copy where links fail."""
    target.parent.mkdir(parents=True, exist_ok=True)
    target.unlink(missing_ok=True)
    try:
        os.link(source, target)
    except OSError:
        tmp = target.with_name(f".{target.name}.{os.getpid()}.partial")
        tmp.write_bytes(source.read_bytes())
        os.replace(tmp, target)


@dataclass(frozen=True)
class ParticleJob:
    """What every chunk of a rendered run shares.

    Attributes
    ----------
    rig : Rig
        Cameras and laser sheet.
    flow : TracerFlow
        The flow the tracers follow (:mod:`simulator.particles`).
    dt : ndarray, shape (K,)
        Frame separations, s.
    frames : int
        Snapshots M per Δt.
    particles : int
        Mean number of particles in the sheet.
    lighting : ParticleLighting
        Tracers and laser sheet.
    sensor : Sensor
        Camera noise model.
    shared_first_frame : bool
        Frame a of snapshot m shared by every Δt (else one experiment per Δt).
    seed : int
        The run's seed.
    detector : DetectorSettings or None
        Detect the particles with these settings (None: do not).
    images : Path or None
        Write the particle images under this dataset folder (None: keep them in memory
        only). Workers write them, so they must see this folder.
    centre_noise : float or None
        Draw no image: each lit particle's exact image centre on a camera that sees it,
        plus white Gaussian noise of this many pixels per axis, stands for its detection
        (a points run: the stack without images, for what matching, linking and the
        statistics do alone; :func:`point_exposure`). None renders and detects.
    """

    rig: Rig
    flow: TracerFlow
    dt: np.ndarray
    frames: int
    particles: int
    lighting: ParticleLighting
    sensor: Sensor
    shared_first_frame: bool
    seed: int
    detector: DetectorSettings | None = None
    images: Path | None = None
    centre_noise: float | None = None


@dataclass(frozen=True, eq=False)
class RenderedChunk:
    """What :func:`render_chunk` gives back.

    Attributes
    ----------
    snapshots : (int, int)
        m0, m1.
    truth : list of K TruthRun
        The chunk's particles per Δt (``first`` = m0).
    detections : dict or None
        :attr:`ptv.detect.frames.ChunkDetections.found` of the chunk (None without a detector).
    """

    snapshots: tuple[int, int]
    truth: list[TruthRun]
    detections: dict | None


def simulate_chunk(job: ParticleJob, m0: int, m1: int):
    """The exact particles of snapshots m0 … m1 − 1 (a DoubleFrameSample)."""
    simulate = shared_start if job.shared_first_frame else double_frame
    return simulate(
        job.flow,
        job.dt,
        particles=job.particles,
        snapshots=job.frames,
        region=job.rig.sheet,
        rng=job.seed,
        first=m0,
        count=m1 - m0,
    )


def render_chunk(snapshots: tuple[int, int], *, job: ParticleJob) -> RenderedChunk:
    """Simulate, render (and write, and detect) snapshots m0 … m1 − 1 of a run.

    Parameters
    ----------
    snapshots : (int, int)
        m0, m1.
    job : ParticleJob
        The run.

    Returns
    -------
    RenderedChunk
    """
    m0, m1 = snapshots
    sample = simulate_chunk(job, m0, m1)
    names = job.rig.camera_names
    runs = sample.runs
    shape = {k: run.positions.shape[:3] for k, run in enumerate(runs)}  # (n, 2, P_k)
    # Image positions as truth.h5 keeps them (float32): half the data to send back.
    xy = [{c: np.empty((*shape[k], 2), np.float32) for c in names} for k in range(len(runs))]
    visible = [{c: np.empty(shape[k], dtype=bool) for c in names} for k in range(len(runs))]
    found: dict = {}
    order = exposures(
        [job.frames] * len(runs), range(m0, m1), shared_first_frame=job.shared_first_frame
    )
    for c, (name, camera) in enumerate(zip(names, job.rig.cameras, strict=True)):
        for k, m, frame in order:
            f = "ab".index(frame)
            positions = runs[max(k, 0)].positions[m - m0, f]
            rng = exposure_rng(job.seed, c, k, m, frame)
            if job.centre_noise is not None:
                recorded = point_exposure(camera, positions, job.lighting, job.centre_noise, rng)
                for kk in range(len(runs)) if k < 0 else (k,):
                    xy[kk][name][m - m0, f] = recorded.xy
                    visible[kk][name][m - m0, f] = recorded.visible
                found.setdefault((k, m, frame), []).append(recorded.detected)
                continue
            recorded = record_particles(
                camera, positions, lighting=job.lighting, sensor=job.sensor, rng=rng
            )
            for kk in range(len(runs)) if k < 0 else (k,):
                xy[kk][name][m - m0, f] = recorded.xy
                visible[kk][name][m - m0, f] = recorded.visible
            if job.images is not None:
                _write_exposure(job.images, len(runs), k, name, m, frame, recorded.image)
            if job.detector is not None:
                detected = detect_particles(
                    recorded.image,
                    threshold_sigmas=job.detector.threshold_sigmas,
                    saturation=job.detector.saturation,
                )
                found.setdefault((k, m, frame), []).append(DetectedCentres.of(detected))
    truth = [
        TruthRun(
            dt=float(dt),
            positions=run.positions,
            velocity=run.velocity[:, 0],
            xy=xy[k],
            visible=visible[k],
            first=m0,
        )
        for k, (dt, run) in enumerate(zip(job.dt, runs, strict=True))
    ]
    detected = job.detector is not None or job.centre_noise is not None
    return RenderedChunk((m0, m1), truth, found if detected else None)


@dataclass(frozen=True, eq=False)
class PointExposure:
    """One exposure of a points run (:attr:`ParticleJob.centre_noise`).

    Attributes
    ----------
    xy : ndarray, shape (P, 2)
        Exact image centre of every particle, px (NaN where unlit or not imaged).
    visible : ndarray of bool, shape (P,)
        Lit and on the sensor.
    detected : DetectedCentres
        The visible particles' centres plus the noise, in random order.
    """

    xy: np.ndarray
    visible: np.ndarray
    detected: DetectedCentres


def point_exposure(
    camera, positions: np.ndarray, lighting: ParticleLighting, noise: float, rng
) -> PointExposure:
    """The detections a perfect detector with ``noise`` px of centre noise per axis would
    give of the lit particles at ``positions`` (P, 3), m, that ``camera`` images on its
    sensor: their exact centres (``camera.project``) plus white Gaussian noise, shuffled
    so that no order carries the particles' identities."""
    lit = lighting.lit_at(positions)
    xy = np.full((len(positions), 2), np.nan)
    if lit.any():
        xy[lit] = camera.project(positions[lit])
    visible = on_image(xy, camera.lens.sensor_size)
    centres = xy[visible] + rng.normal(0.0, noise, (int(visible.sum()), 2))
    centres = centres[rng.permutation(len(centres))]
    flags = np.zeros(len(centres), dtype=np.uint8)
    return PointExposure(xy, visible, DetectedCentres(centres, flags))


def _write_exposure(folder: Path, n_dt: int, k: int, camera: str, m: int, frame: str, image):
    """Write one exposure; a shared frame a once, hard-linked into every Δt's folder."""
    if k >= 0:
        write_tiff(particle_path(folder, k, camera, m, frame), image)
        return
    first = particle_path(folder, 0, camera, m, frame)
    write_tiff(first, image)
    for kk in range(1, n_dt):
        _link_or_copy(first, particle_path(folder, kk, camera, m, frame))


def chunk_detections(chunk: RenderedChunk, job: ParticleJob, folder: Path) -> ChunkDetections:
    """The detections of a rendered chunk as :class:`ptv.detect.frames.ChunkDetections` of the
    dataset at ``folder``."""
    return ChunkDetections(
        folder=folder,
        cameras=tuple(job.rig.camera_names),
        dt=np.asarray(job.dt),
        frames=(job.frames,) * len(job.dt),
        shared_first_frame=job.shared_first_frame,
        detector=job.detector.as_dict(),
        snapshots=chunk.snapshots,
        found=chunk.detections,
    )
