"""Time-resolved tracking: synptv's tracker beside trackpy's linker on the same points.

Set-up: a recording of the 10 Hz flow (kinematic simulation, 200 modes) through the
``paper-stereo`` rig's light sheet (:func:`simulator.recording.follow_recording`): 2000
tracers in the sheet, 200 frames at τ = τ_η/10 (quick: 500 tracers, 50 frames). The
points each code links are the particles in the sheet at every frame with 15 µm of
Gaussian noise per component, 2 % of them dropped at random (a detection missed, so that
a track must bridge a gap to stay whole). synptv: :func:`ptv.tracking.linking.
track_frames` with the radii and the gap closing ``synptv ptv --tracks`` uses
(:func:`ptv.pipeline.time_resolved.track_radii`, max speed 5u′, the noise given; up to
``track_gap`` missed frames). trackpy: ``link_df`` in 3-D with its nearest-velocity
predictor, the same first radius, and as many frames of memory. Both are scored against
the true trajectories
(:mod:`validation.score.trajectories`, pairs within 5√3 σ), side by side in one run,
with the time each takes to link.
"""

import time

import numpy as np

from ptv.pipeline.time_resolved import track_radii
from ptv.settings import PipelineSettings
from ptv.tracking.linking import track_frames
from ptv.tracking.stitching import stitch_tracks
from simulator.particles import KSFlow
from simulator.presets import flow_preset
from simulator.recording import follow_recording
from simulator.rigs import load_rig
from simulator.spectra import PopeSpectrum
from validation.score.trajectories import TrackPoints, TrueTrajectories, trajectory_scores

#: Position noise per component, m, and the fraction of points dropped.
NOISE = 15e-6
DROPPED = 0.02
#: Frame interval over τ_η.
TAU_OVER_TAU_ETA = 0.1


def _points(recording, rng):
    """The noisy points of every frame kept, and the truth row of each."""
    keep = rng.random(len(recording.frame)) >= DROPPED
    noisy = recording.position + rng.normal(0.0, NOISE, recording.position.shape)
    rows = [np.flatnonzero(keep & (recording.frame == f)) for f in range(len(recording.times))]
    return [noisy[r] for r in rows], rows


def _synptv(frames, frame_rate, settings):
    radius, predicted, noise = track_radii(frame_rate, settings)
    gap = settings.track_gap
    tracks, _ = stitch_tracks(
        track_frames(
            frames, radius=radius, predicted_radius=predicted, predicted_noise=noise, gap=gap
        ),
        predicted_radius=predicted,
        predicted_noise=noise,
        gap=gap,
    )
    return TrackPoints(tracks.track, tracks.frame, tracks.positions), radius


def _trackpy(frames, radius, memory):
    import pandas as pd
    import trackpy

    trackpy.quiet()
    table = pd.DataFrame(
        {
            "frame": np.concatenate([np.full(len(x), f) for f, x in enumerate(frames)]),
            **{
                axis: np.concatenate([x[:, i] for x in frames]) * 1e3  # mm
                for i, axis in enumerate("xyz")
            },
        }
    )
    linked = trackpy.predict.NearestVelocityPredict().link_df(
        table, search_range=radius * 1e3, memory=memory, pos_columns=list("xyz")
    )
    return TrackPoints(
        linked["particle"].to_numpy(),
        linked["frame"].to_numpy(),
        linked[list("xyz")].to_numpy() / 1e3,
    )


def _summary(scores: dict, seconds: float) -> dict:
    keys = ("tracked", "ghost_tracks", "fragmentation", "mislinks", "ghost_links", "tracks")
    return {
        **{k: scores[k] for k in keys},
        "mean_track_length": scores["lengths"]["tracks"]["mean"],
        "mean_trajectory_length": scores["lengths"]["trajectories"]["mean"],
        "position_rms_um": scores["errors"]["position_um"],
        "link_seconds": seconds,
    }


def run(quick: bool) -> dict:
    """Simulate the recording, link its points with both codes, score both."""
    preset = flow_preset("lem-10hz")
    p = preset.parameters
    particles, n_frames = (500, 50) if quick else (2000, 200)
    frame_rate = 1.0 / (TAU_OVER_TAU_ETA * p.tau_eta)
    region = load_rig("paper-stereo").sheet
    start = time.perf_counter()
    recording = follow_recording(
        KSFlow(PopeSpectrum(p)),
        frame_rate,
        n_frames,
        particles=particles,
        region=region,
        rng=0,
    )
    simulated = time.perf_counter() - start
    truth = TrueTrajectories(
        recording.particle,
        recording.frame,
        recording.position,
        recording.velocity,
        recording.acceleration,
        np.ones(len(recording.frame), dtype=bool),
    )
    frames, _ = _points(recording, np.random.default_rng(1))
    pair_radius = 5 * np.sqrt(3) * NOISE
    out = {
        "particles_in_sheet": particles,
        "frames": n_frames,
        "tau_over_tau_eta": TAU_OVER_TAU_ETA,
        "noise_um": NOISE * 1e6,
        "dropped": DROPPED,
        "seeds": recording.seeds,
        "simulate_seconds": simulated,
    }
    settings = PipelineSettings(max_speed=5 * p.u_rms, position_noise=NOISE)
    out["gap_frames"] = settings.track_gap
    start = time.perf_counter()
    ours, radius = _synptv(frames, frame_rate, settings)
    out["synptv"] = _summary(
        trajectory_scores(truth, ours, pair_radius), time.perf_counter() - start
    )
    out["link_radius_um"] = radius * 1e6
    start = time.perf_counter()
    theirs = _trackpy(frames, radius, settings.track_gap)
    out["trackpy"] = _summary(
        trajectory_scores(truth, theirs, pair_radius), time.perf_counter() - start
    )
    return out
