"""A small rendered double-frame case for the image-stack claims (docs/claims.md §3).

The paper-stereo rig records a few snapshots of the 10 Hz flow at its largest Δt through
the simulator's refracting cameras with sensor noise; the PTV stack then runs on the
images exactly as in ``synptv run``: :func:`ptv.detect.detect_particles` with the
default :class:`ptv.pipeline.frames.DetectorSettings`, and
:func:`ptv.pipeline.double_frame.measure_snapshot` (matching, linking, median test) with
the default :class:`ptv.pipeline.double_frame.PipelineSettings` and the rig's true
cameras, so that no calibration error enters. Everything the claims compare with comes
from the simulator: the exact image of every particle centre, its spot's σ and
photo-electrons, and the particles' true positions.
"""

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ptv.detect import detect_particles
from ptv.pipeline.double_frame import PipelineSettings, SnapshotMeasurement, measure_snapshot
from ptv.pipeline.frames import ChunkDetections, DetectedCentres, DetectorSettings
from simulator.particles import KSFlow, double_frame
from simulator.presets import flow_preset
from simulator.render.camera_frames import ParticleFrame, ParticleLighting, record_particles
from simulator.render.sensor import Sensor
from simulator.rigs import Rig, load_rig
from simulator.spectra import PopeSpectrum

#: The rendered case: the default scenario's rig, flow, tracer count and brightness.
RIG = "paper-stereo"
FLOW = "lem-10hz"
PARTICLES = 2000
ELECTRONS = 2000.0


@dataclass(frozen=True, eq=False)
class Exposure:
    """One camera's record of one frame, with its detections.

    Attributes
    ----------
    frame : ParticleFrame
        The image and the exact image position, σ (px) and photo-electrons of each
        particle.
    detected : DetectedCentres
        Detected centres (px) and their flags.
    """

    frame: ParticleFrame
    detected: DetectedCentres


@dataclass(frozen=True, eq=False)
class RenderedCase:
    """The rendered case and what the PTV stack measured on it.

    Attributes
    ----------
    rig : Rig
        Cameras (the true ones are the calibration) and sheet.
    dt : float
        Frame separation, s.
    positions : ndarray, shape (M, 2, P, 3)
        True particle positions of snapshot m at t (index 0) and t + Δt (1), m.
    exposures : list of M lists of 2 lists of C Exposure
        ``exposures[m][f][c]``: frame f of snapshot m on camera c.
    measurements : list of M SnapshotMeasurement
        Matched points of both frames and the links, per snapshot.
    sensor : Sensor
        The noise model the images were recorded with.
    settings : PipelineSettings
        The matching and linking settings used.
    """

    rig: Rig
    dt: float
    positions: np.ndarray
    exposures: list
    measurements: list[SnapshotMeasurement]
    sensor: Sensor
    settings: PipelineSettings = field(default_factory=PipelineSettings)


def render_case(snapshots: int, *, seed: int) -> RenderedCase:
    """Render ``snapshots`` double frames and run detection, matching and linking.

    Parameters
    ----------
    snapshots : int
        Frame pairs M.
    seed : int
        Seed of the flow, the particles and the sensor noise.

    Returns
    -------
    RenderedCase
    """
    rig = load_rig(RIG)
    preset = flow_preset(FLOW)
    dt = float(preset.dt[-1])
    sample = double_frame(
        KSFlow(PopeSpectrum(preset.parameters)),
        np.array([dt]),
        particles=PARTICLES,
        snapshots=snapshots,
        region=rig.sheet,
        rng=seed,
    )
    positions = sample.runs[0].positions
    lighting = ParticleLighting(electrons_at_reference=ELECTRONS)
    sensor = Sensor()
    detector = DetectorSettings()
    noise = np.random.default_rng(np.random.SeedSequence([seed, 7]))
    exposures = [
        [
            [
                _expose(camera, positions[m, f], lighting, sensor, detector, noise)
                for camera in rig.cameras
            ]
            for f in range(2)
        ]
        for m in range(snapshots)
    ]
    found = {
        (0, m, "ab"[f]): [e.detected for e in exposures[m][f]]
        for m in range(snapshots)
        for f in range(2)
    }
    source = ChunkDetections(
        folder=Path("rendered-case"),
        cameras=tuple(rig.camera_names),
        dt=np.array([dt]),
        frames=(snapshots,),
        shared_first_frame=False,
        detector=detector.as_dict(),
        snapshots=(0, snapshots),
        found=found,
    )
    settings = PipelineSettings()
    measurements = [
        measure_snapshot(source, 0, m, rig.cameras, settings, keep_matched=True)
        for m in range(snapshots)
    ]
    return RenderedCase(rig, dt, positions, exposures, measurements, sensor, settings)


def _expose(camera, points, lighting, sensor, detector, rng) -> Exposure:
    """Record ``points`` on ``camera`` and detect them as the pipeline does."""
    frame = record_particles(camera, points, lighting=lighting, sensor=sensor, rng=rng)
    found = detect_particles(
        frame.image, threshold_sigmas=detector.threshold_sigmas, saturation=detector.saturation
    )
    return Exposure(frame, DetectedCentres.of(found))
