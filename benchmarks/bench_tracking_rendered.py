"""Tracking a rendered recording: synptv's tracker beside trackpy's linker on the same points.

Set-up: the ``tr`` scenario's recording (quick: ``tr-ci``) rendered as ``synptv run``
renders it (:func:`validation.run.render_recording.build_recording_dataset`), its particles
detected on every image and matched through the rig's true cameras
(:func:`ptv.pipeline.time_resolved.measure_recording`): the points a lab's code would link,
ghost matches and points displaced by overlapping images included. synptv:
:func:`ptv.pipeline.time_resolved.track_points` (two passes, gap closing and joins). trackpy:
``link_df`` in 3-D with its nearest-velocity predictor, the same first-link radius and as
many frames of memory as synptv's gap. Max speed 5u′ for both. Both are scored against
the true trajectories (:mod:`validation.score.trajectories`, pairs within one object
pixel), as given and with the tracks of fewer than five points left out (the tracks
``synptv run`` fits), side by side in one run, with the time each takes to link.
"""

import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from benchmarks.bench_tracking import _trackpy
from ptv.detect.frames import ImageDetector
from ptv.io.dataset import open_dataset
from ptv.pipeline.link_radii import link_radius
from ptv.pipeline.resolve import resolve_matching
from ptv.pipeline.time_resolved import measure_recording, track_points
from ptv.settings import DetectorSettings
from ptv.tracking.fitting import MIN_FIT_POINTS
from validation.run.experiment import object_pixel
from validation.run.recording_run import RecordingRun
from validation.run.recording_scores import long_tracks
from validation.run.render_recording import sequence_folder
from validation.run.scenario import load_scenario
from validation.score.recorded_tracks import align_tracks, true_trajectories
from validation.score.trajectories import TrackPoints, trajectory_scores
from validation.truth.recording_truth import read_recording_truth
from validation.workflow.parallel import InProcess


def _scores(tracks: TrackPoints, truth, radius: float, seconds: float) -> dict:
    moved, _, _ = align_tracks(tracks, truth)
    observed = true_trajectories(truth, 2)
    out = {"link_seconds": seconds}
    for key, view in (("all", moved), ("fitted", long_tracks(moved, MIN_FIT_POINTS))):
        s = trajectory_scores(observed, view, radius)
        out[key] = {
            **{k: s[k] for k in ("tracked", "ghost_tracks", "fragmentation", "tracks")},
            "mislinks": s["mislinks"],
            "mislinked_links": round(s["mislinks"] * s["links"]),
            "avoidable_mislinked_links": round(s["avoidable_mislinks"] * s["links"]),
            "ghost_links": s["ghost_links"],
            "mean_track_length": s["lengths"]["tracks"]["mean"],
        }
    return out


def run(quick: bool) -> dict:
    """Render the recording, detect and match it, link with both codes, score both."""
    scenario = load_scenario("tr-ci" if quick else "tr")
    with tempfile.TemporaryDirectory() as folder:
        recorded = RecordingRun(scenario, Path(folder), InProcess(), None)
        start = time.perf_counter()
        dataset = recorded.dataset()
        rendered = time.perf_counter() - start
        rig, preset = recorded.run.rig, recorded.run.preset
        sequence = sequence_folder(dataset.folder, 0)
        detector = ImageDetector(
            open_dataset(sequence), DetectorSettings(saturation=float(scenario.sensor.max_dn))
        )
        cameras = list(rig.cameras)
        settings = replace(recorded.run.settings, max_speed=5 * preset.parameters.u_rms)
        settings, _ = resolve_matching(detector, cameras, settings)
        numbers = detector.dataset.sequence.frame_numbers()
        start = time.perf_counter()
        points = measure_recording(detector, cameras, settings, numbers).points
        measured = time.perf_counter() - start
        truth = read_recording_truth(sequence)
    frame_rate = recorded.plan.frame_rate
    radius = object_pixel(rig)
    out = {
        "scenario": scenario.name,
        "frames": recorded.plan.frames,
        "points_per_frame": float(np.mean([len(p) for p in points])),
        "render_seconds": rendered,
        "detect_match_seconds": measured,
        "gap_frames": settings.track_gap,
    }
    start = time.perf_counter()
    linked = track_points(points, frame_rate, settings)
    seconds = time.perf_counter() - start
    ours = TrackPoints(linked.tracks.track, linked.tracks.frame, linked.tracks.positions)
    out["synptv"] = _scores(ours, truth, radius, seconds)
    out["synptv"]["prediction_noise_um"] = linked.miss_noise * 1e6
    first = link_radius(1.0 / frame_rate, settings)
    start = time.perf_counter()
    theirs = _trackpy(points, first, settings.track_gap)
    out["trackpy"] = _scores(theirs, truth, radius, time.perf_counter() - start)
    out["link_radius_um"] = first * 1e6
    return out
