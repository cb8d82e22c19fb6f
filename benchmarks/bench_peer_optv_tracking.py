"""A peer's tracker on a rendered recording: OpenPTV's ``optv`` 0.3.2 beside synptv.

Set-up: the ``tr`` scenario's recording (quick: ``tr-ci``) rendered as ``synptv run``
renders it, exported in OpenPTV's layout (``synptv export --format openptv``: the plate
images, img/seq0/<camera>.<number>, sequence.par and track.par) and processed three
ways, each scored against the true trajectories (:mod:`validation.score.trajectories`,
pairs within one object pixel, after one rigid alignment), side by side in one run:

- **OpenPTV**, from the exported files only: its calibration from the plate images
  (:mod:`benchmarks.bench_peer_optv`: its own dot detection, ``full_calibration`` in
  stages), then on every frame its target recognition, correspondences (epipolar band
  twice the calibration's residual) and 3-D positions, written as OpenPTV's
  ``<image>_targets`` and ``res/rt_is.<number>`` files; then its tracker
  (``optv.tracker.Tracker.full_forward``: the four-frame search in image and object
  space, links chosen by the quality of the path) with the exported track.par, and over
  a grid of its acceleration and angle bounds around it, with and without its adding of
  particles from targets no correspondence used (the grid's best by fragmentation is
  reported too, an upper bound a user without the truth would not find); its tracks
  read back from ``res/ptv_is.<number>``.
- **synptv's tracker on OpenPTV's points**: the same rt_is points linked by
  :func:`ptv.pipeline.time_resolved.track_points` (max speed from the exported bounds):
  tracker against tracker on identical input.
- **synptv**, its own chain: the model-free calibration from the same plates, its
  detection and matching (:func:`ptv.pipeline.time_resolved.measure_recording`) and
  :func:`~ptv.pipeline.time_resolved.track_points`.

Run: ``python -m benchmarks.bench_peer_optv_tracking [--quick]`` prints one JSON object and
a markdown table; needs ``optv`` (``pip install ".[peers]"`` in the clone).
"""

import contextlib
import itertools
import json
import os
import shutil
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import tifffile

from benchmarks.bench_peer_optv import (
    BAND_OVER_RESIDUAL,
    _calibrate,
    _params,
    _plate_dots,
    _target_files,
)
from benchmarks.bench_tracking_rendered import _scores
from ptv.calibration.io import load_calibrations
from ptv.detect.frames import ImageDetector
from ptv.io.dataset import open_dataset
from ptv.pipeline.resolve import resolve_matching
from ptv.pipeline.time_resolved import measure_recording, track_points
from ptv.settings import DetectorSettings
from validation.commands.export import export_dataset
from validation.export.openptv import FIRST_NUMBER
from validation.run.experiment import object_pixel
from validation.run.recording_run import RecordingRun
from validation.run.render_recording import sequence_folder
from validation.run.scenario import load_scenario
from validation.score.trajectories import TrackPoints
from validation.truth.recording_truth import read_recording_truth
from validation.workflow.parallel import InProcess

MM = 1e3
#: OpenPTV's settings tried: acceleration bounds (dacc) as multiples of the exported one,
#: angle bounds (dangle, gon), and whether its tracker adds particles from targets no
#: correspondence used (add).
DACC_FACTORS = (0.5, 1.0, 2.0)
ANGLES_GON = (120.0, 200.0)
ADD = (0, 1)


@contextlib.contextmanager
def _inside_quietly(folder: Path):
    """OpenPTV's tracker reads and writes paths relative to the working folder and
    prints a line per frame from C: run it there with standard output closed."""
    before = Path.cwd()
    sys.stdout.flush()
    saved = os.dup(1)
    with open(os.devnull, "w") as null:
        os.dup2(null.fileno(), 1)
    os.chdir(folder)
    try:
        yield
    finally:
        os.chdir(before)
        os.dup2(saved, 1)
        os.close(saved)


def _optv_frame(export: Path, number: int, cameras, cals, params) -> np.ndarray:
    """optv's particles of one recorded frame; writes its targets and rt_is files.

    Returns
    -------
    ndarray, shape (n, 3)
        The rt_is positions, m, in the file's order.
    """
    from optv.correspondences import MatchedCoords, correspondences
    from optv.orientation import point_positions
    from optv.segmentation import target_recognition

    targets, flat = [], []
    for c, (camera, cal) in enumerate(zip(cameras, cals, strict=True)):
        image = tifffile.imread(export / f"img/seq0/{camera}.{number}")
        found = target_recognition(image, params["particles"], c, params["control"])
        found.sort_y()  # numbers the targets in the order written
        targets.append(found)
        flat.append(MatchedCoords(found, params["control"], cal))
    _, cliques, _ = correspondences(targets, flat, cals, params["volume"], params["control"])
    points, members = [], []
    for clique in cliques:
        if clique.shape[1] == 0:
            continue
        coords = np.array([flat[c].get_by_pnrs(clique[c]) for c in range(len(cals))])
        positions, _ = point_positions(
            coords.transpose(1, 0, 2), params["control"], cals, params["volume"]
        )
        points.append(positions)
        members.append(clique.T)
    points = np.concatenate(points) if points else np.zeros((0, 3))
    members = np.concatenate(members) if members else np.zeros((0, len(cals)), dtype=int)
    lines = [f"{len(points)}"]
    for i, (x, p) in enumerate(zip(points, members, strict=True)):
        for c, target in enumerate(p):
            if target >= 0:
                targets[c][int(target)].set_tnr(i)
        ids = [*(int(t) for t in p), *[-1] * (4 - len(p))]
        lines.append(f"{i + 1} {x[0]:.6f} {x[1]:.6f} {x[2]:.6f} " + " ".join(map(str, ids)))
    (export / f"res/rt_is.{number}").write_text("\n".join(lines) + "\n")
    for c, camera in enumerate(cameras):
        targets[c].write(str(export / f"img/seq0/{camera}.").encode(), number)
    return points / MM


def _read_linkage(export: Path, numbers: range) -> TrackPoints:
    """OpenPTV's tracks from its res/ptv_is.<number> files (count, then per particle
    its row in the previous and next frame, −1 or −2 for none, and x y z in mm)."""
    rows = []
    for number in numbers:
        table = np.loadtxt(export / f"res/ptv_is.{number}", skiprows=1, ndmin=2)
        rows.append(table.reshape(-1, 5))
    track_of = [np.full(len(r), -1, dtype=np.int64) for r in rows]
    count = 0
    for f, table in enumerate(rows):
        new = track_of[f] < 0
        track_of[f][new] = count + np.arange(np.count_nonzero(new))
        count += np.count_nonzero(new)
        if f + 1 < len(rows):
            ahead = table[:, 1].astype(np.int64)
            linked = (ahead >= 0) & (ahead < len(rows[f + 1]))
            track_of[f + 1][ahead[linked]] = track_of[f][linked]
    frames = np.concatenate([np.full(len(r), f) for f, r in enumerate(rows)])
    return TrackPoints(
        np.concatenate(track_of), frames, np.concatenate([r[:, 2:] for r in rows]) / MM
    )


def _optv_track(peer: dict, dacc_factor: float, dangle: float, add: int) -> tuple:
    """OpenPTV's tracker over the exported sequence, its acceleration bound scaled from
    the exported one, its angle bound and particle adding set; (tracks, seconds)."""
    from optv.parameters import SequenceParams, TrackingParams
    from optv.tracker import Tracker

    export, cals = peer["export"], peer["cals"]
    for path in (export / "res").iterdir():  # the correspondences as first written
        path.unlink()
    for path in (export / "rt_is").iterdir():
        shutil.copy(path, export / "res" / path.name)
    with _inside_quietly(export):
        sequence = SequenceParams(num_cams=len(cals))
        sequence.read_sequence_par("parameters/sequence.par", len(cals))
        bounds = TrackingParams()
        bounds.read_track_par("parameters/track.par")
        bounds.set_dacc(dacc_factor * bounds.get_dacc())
        bounds.set_dangle(dangle)
        bounds.set_add(add)
        start = time.perf_counter()
        tracker = Tracker(
            peer["params"]["control"], peer["params"]["volume"], bounds, sequence, cals
        )
        tracker.full_forward()
        seconds = time.perf_counter() - start
        numbers = range(sequence.get_first(), sequence.get_last() + 1)
    return _read_linkage(export, numbers), seconds


def _openptv(export: Path, cameras: list, planes: int, frames: int) -> dict:
    """OpenPTV's calibration and points of the exported recording (its rt_is files kept
    in ``rt_is/`` for every tracking run)."""
    import optv.version

    params = _params(export, len(cameras))
    targets_mm = _target_files(export, planes)
    dots = [_plate_dots(export, c, name, planes, params) for c, name in enumerate(cameras)]
    fits = [
        _calibrate(export, name, d, targets_mm, params)
        for name, d in zip(cameras, dots, strict=True)
    ]
    cals = [cal for cal, _ in fits]
    residual = max(r["residual_rms_px"] for _, stages in fits for r in stages if r.get("kept"))
    params["volume"].set_eps0(BAND_OVER_RESIDUAL * residual * params["control"].get_pixel_size()[0])
    (export / "res").mkdir()
    start = time.perf_counter()
    points = [_optv_frame(export, FIRST_NUMBER + f, cameras, cals, params) for f in range(frames)]
    measured = time.perf_counter() - start
    shutil.copytree(export / "res", export / "rt_is")
    bounds = (export / "parameters/track.par").read_text().split()
    return {
        "version": optv.version.__version__,
        "export": export,
        "params": params,
        "cals": cals,
        "residual_rms_px": residual,
        "points": points,
        "points_seconds": measured,
        "exported_dacc_mm": float(bounds[7]),
        "frame_step_mm": float(bounds[1]),
    }


def _synptv_points(recorded: RecordingRun, dataset, scenario) -> tuple:
    """synptv's matched points of every frame through its model-free calibration."""
    calibrations = recorded.run.calibrations(dataset)
    cameras = load_calibrations(calibrations.folder / "model-free.h5")
    detector = ImageDetector(
        open_dataset(sequence_folder(dataset.folder, 0)),
        DetectorSettings(saturation=float(scenario.sensor.max_dn)),
    )
    ordered = [cameras[name] for name in detector.cameras]
    settings, _ = resolve_matching(detector, ordered, recorded.run.settings)
    start = time.perf_counter()
    numbers = detector.dataset.sequence.frame_numbers()
    points = measure_recording(detector, ordered, settings, numbers).points
    return points, settings, time.perf_counter() - start


def run(quick: bool) -> dict:
    """Render and export the recording, run OpenPTV and synptv, score every code."""
    scenario = load_scenario("tr-ci" if quick else "tr")
    with tempfile.TemporaryDirectory(prefix="bench-optv-tracking-") as tmp:
        work = Path(tmp)
        recorded = RecordingRun(scenario, work / "run", InProcess(), None)
        dataset = recorded.dataset()
        export = work / "openptv"
        export_dataset(dataset.folder, "openptv", export)
        truth = read_recording_truth(sequence_folder(dataset.folder, 0))
        frames = recorded.plan.frames
        cameras = list(recorded.run.rig.camera_names)
        radius = object_pixel(recorded.run.rig)
        frame_rate = recorded.plan.frame_rate

        peer = _openptv(export, cameras, scenario.calibration.planes, frames)
        grid = {}
        for factor, angle, add in itertools.product(DACC_FACTORS, ANGLES_GON, ADD):
            tracks, seconds = _optv_track(peer, factor, angle, add)
            grid[f"dacc x{factor:g}, dangle {angle:g}, add {add}"] = _scores(
                tracks, truth, radius, seconds
            )
        exported = grid["dacc x1, dangle 120, add 0"]
        best = min(grid, key=lambda k: grid[k]["fitted"]["fragmentation"])

        ours, settings, measured = _synptv_points(recorded, dataset, scenario)
        settings = replace(settings, max_speed=peer["frame_step_mm"] / MM * frame_rate)
        start = time.perf_counter()
        linked = track_points(ours, frame_rate, settings).tracks
        seconds = time.perf_counter() - start
        synptv = _scores(
            TrackPoints(linked.track, linked.frame, linked.positions), truth, radius, seconds
        )
        start = time.perf_counter()
        on_peer = track_points(peer["points"], frame_rate, settings).tracks
        seconds = time.perf_counter() - start
        synptv_on_peer = _scores(
            TrackPoints(on_peer.track, on_peer.frame, on_peer.positions), truth, radius, seconds
        )
    return {
        "scenario": scenario.name,
        "frames": frames,
        "optv": {
            "version": peer["version"],
            "calibration_residual_rms_px": peer["residual_rms_px"],
            "points_per_frame": float(np.mean([len(p) for p in peer["points"]])),
            "points_seconds": peer["points_seconds"],
            "exported_dacc_mm": peer["exported_dacc_mm"],
            "exported": exported,
            "best_of_grid": {"bounds": best, **grid[best]},
            "grid": {k: v["fitted"] for k, v in grid.items()},
        },
        "synptv_tracker_on_optv_points": synptv_on_peer,
        "synptv": {
            "points_per_frame": float(np.mean([len(p) for p in ours])),
            "points_seconds": measured,
            **synptv,
        },
    }


def markdown(figures: dict) -> str:
    """The side-by-side table of :func:`run`'s figures (tracks of five points or more)."""
    lines = [
        "| code | points per frame | tracked | segments per trajectory | mislinks (avoidable) "
        "| ghost tracks | mean track length | link time (s) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    optv = figures["optv"]
    best = optv["best_of_grid"]
    rows = (
        (
            f"OpenPTV {optv['version']}, exported track.par",
            optv["points_per_frame"],
            optv["exported"],
        ),
        (f"OpenPTV, best of grid ({best['bounds']})", optv["points_per_frame"], best),
        (
            "synptv's tracker, OpenPTV's points",
            optv["points_per_frame"],
            figures["synptv_tracker_on_optv_points"],
        ),
        ("synptv", figures["synptv"]["points_per_frame"], figures["synptv"]),
    )
    for label, points, f in rows:
        s = f["fitted"]
        lines.append(
            f"| {label} | {points:.0f} | {s['tracked']:.3f} | {s['fragmentation']:.3f} "
            f"| {s['mislinked_links']} ({s['avoidable_mislinked_links']}) "
            f"| {100 * s['ghost_tracks']:.2f} % | {s['mean_track_length']:.1f} "
            f"| {f['link_seconds']:.2f} |"
        )
    return "\n".join(lines)


if __name__ == "__main__":
    result = run(quick="--quick" in sys.argv[1:])
    json.dump(result, sys.stdout, indent=2)
    print()
    print(markdown(result))
