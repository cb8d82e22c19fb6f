"""Small rendered double-frame cases for the image-stack claims (docs/claims.md §3).

A rig records a few snapshots of a flow at its largest Δt through the simulator's
refracting cameras with sensor noise; the PTV stack then runs on the images exactly as
in ``synptv run``: :func:`ptv.detect.detect_particles` with the default
:class:`ptv.settings.DetectorSettings`, and
:func:`ptv.pipeline.double_frame.measure_snapshot` (matching, linking, median test) with
the default :class:`ptv.settings.PipelineSettings` (min_cameras from the camera
count, max_speed measured on the case's own links:
:func:`ptv.pipeline.resolve.resolve_settings`) and the rig's true cameras, so that
no calibration error enters. Everything the claims compare with comes from the
simulator: the exact image of every particle centre, its spot's σ and photo-electrons,
and the particles' true positions.

Three cases (:data:`PAPER_CASE`, :data:`SLOW_CASE`, :data:`CROWDED_CASE`): the default
scenario's (paper-stereo, the 10 Hz flow); the slow-4cam scenario's (four cameras, a lab
flow ten times slower), on which a setting that does not follow the flow shows; and the
default's rig and flow crowded, where matching, linking and the median test choose
among several candidates.
"""

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ptv.detect import detect_particles
from ptv.detect.frames import ChunkDetections, DetectedCentres
from ptv.pipeline.double_frame import SnapshotMeasurement, measure_snapshot
from ptv.pipeline.resolve import resolve_settings
from ptv.settings import DetectorSettings, PipelineSettings
from simulator.particles import KSFlow, double_frame
from simulator.presets import flow_preset
from simulator.render.camera_frames import ParticleFrame, ParticleLighting, record_particles
from simulator.render.sensor import Sensor
from simulator.rigs import Rig, load_rig
from simulator.spectra import PopeSpectrum
from simulator.turbulence import TurbulenceParameters


@dataclass(frozen=True)
class CaseSpec:
    """What a rendered case records: a rig, a flow at one Δt, tracers and their light.

    Attributes
    ----------
    rig : str
        Rig preset.
    parameters : TurbulenceParameters
        The flow (u′, ε, ν).
    dt : float
        Frame separation, s.
    particles : int
        Tracers in the sheet.
    electrons : float
        Photo-electrons per tracer on the sheet's centre plane.
    """

    rig: str
    parameters: TurbulenceParameters
    dt: float
    particles: int
    electrons: float


_PAPER = flow_preset("lem-10hz")
#: The default scenario's rig, flow (at its largest Δt), tracer count and brightness.
PAPER_CASE = CaseSpec("paper-stereo", _PAPER.parameters, float(_PAPER.dt[-1]), 2000, 2000.0)
#: Twice the default scenario's tracers at three times its largest Δt (1.5 ms, 0.63 τ_η):
#: particles about 1.6 mm apart against a link radius of 1.6–2.2 mm; over 12 seeds the
#: optimal matching still leaves 5.0–6.5 % ghosts and 3.6–6.4 % of the links are wrong
#: before the median test, so that matching, linking and the test choose.
CROWDED_CASE = CaseSpec("paper-stereo", _PAPER.parameters, 1.5e-3, 4000, 2000.0)
_SLOW = TurbulenceParameters(u_rms=0.05, epsilon=1e-3)
#: The slow-4cam scenario's: four cameras, u′ = 0.05 m/s, ε = 10⁻³ m²/s³, Δt = 0.2 τ_η.
SLOW_CASE = CaseSpec("box-4cam", _SLOW, 0.2 * _SLOW.tau_eta, 1500, 2000.0)


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
    lighting : ParticleLighting
        The tracers' diameter, the laser sheet and the light collected.
    settings : PipelineSettings
        The matching and linking settings used (min_cameras and max_speed resolved).
    spec : CaseSpec
        What was recorded.
    """

    rig: Rig
    dt: float
    positions: np.ndarray
    exposures: list
    measurements: list[SnapshotMeasurement]
    sensor: Sensor
    lighting: ParticleLighting
    settings: PipelineSettings
    spec: CaseSpec = PAPER_CASE


def render_case(snapshots: int, *, seed: int, spec: CaseSpec = PAPER_CASE) -> RenderedCase:
    """Render ``snapshots`` double frames and run detection, matching and linking.

    Parameters
    ----------
    snapshots : int
        Frame pairs M.
    seed : int
        Seed of the flow, the particles and the sensor noise.
    spec : CaseSpec
        Rig, flow, Δt, tracers.

    Returns
    -------
    RenderedCase
    """
    rig = load_rig(spec.rig)
    dt = spec.dt
    sample = double_frame(
        KSFlow(PopeSpectrum(spec.parameters)),
        np.array([dt]),
        particles=spec.particles,
        snapshots=snapshots,
        region=rig.sheet,
        rng=seed,
    )
    positions = sample.runs[0].positions
    lighting = ParticleLighting(electrons_at_reference=spec.electrons)
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
    settings, _ = resolve_settings(source, rig.cameras, PipelineSettings())
    measurements = [
        measure_snapshot(source, 0, m, rig.cameras, settings, keep_matched=True)
        for m in range(snapshots)
    ]
    return RenderedCase(
        rig, dt, positions, exposures, measurements, sensor, lighting, settings, spec
    )


def _expose(camera, points, lighting, sensor, detector, rng) -> Exposure:
    """Record ``points`` on ``camera`` and detect them as the pipeline does."""
    frame = record_particles(camera, points, lighting=lighting, sensor=sensor, rng=rng)
    found = detect_particles(
        frame.image, threshold_sigmas=detector.threshold_sigmas, saturation=detector.saturation
    )
    return Exposure(frame, DetectedCentres.of(found))
