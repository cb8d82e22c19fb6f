"""Real particles: synptv's 3-D particles beside those MyPTV and OpenPTV shipped.

Two examples hold real particle images with one image per camera of a stepped 3-D
target (docs/experiment.md §3b):

- ``examples/myptv``: MyPTV's example, three cameras; MyPTV's matched particles
  (``myptv/particles``) of frames 01–03;
- ``examples/test-cavity``: OpenPTV's test_cavity, four cameras through the glass
  walls of a water tank; OpenPTV's correspondences ``openptv/res/rt_is.10001`` and
  ``.10002``.

For each, from the command line as a user runs it: ``synptv calibrate`` (one pinhole
per camera from the target image and the seed points), then ``synptv ptv
--positions-only`` with the example's ``ptv.toml``; per frame, the fraction of the
shipped particles with a synptv particle within 0.1 mm (and within 1 mm: found at
all) and the median distance to synptv's nearest. Both calibrations are in the
target's frame, so no transform is applied. The shipped particles are the other
code's output, not the truth.

Diagnostics that separate the calibration from detection and matching:

- MyPTV: its own blob triplets (``myptv/blobs_cam*``, the blobs of every shipped
  particle) triangulated by synptv's calibration: the distance to MyPTV's point and
  how closely the three rays meet;
- MyPTV: the target points each camera used, against MyPTV's own count
  (``myptv/cam*_cal_points``);
- test-cavity: each camera's centre against OpenPTV's ``openptv/cal/cam*.tif.ori``;
  with ``optv`` installed (``pip install ".[peers]"`` in the clone), OpenPTV's particles of frame
  10001 taken apart: the particle images they cite, how tightly its rays meet, and its
  correspondences triangulated by synptv's calibration (:func:`openptv_check`).

Run: ``python -m benchmarks.bench_real_particles [myptv] [test-cavity]``; prints one
JSON object. About a minute per example on two cores.
"""

import contextlib
import io
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

from ptv.calibration.io import load_calibrations
from ptv.io.dataset import open_dataset
from ptv.triangulate import triangulate
from validation.cli import main as synptv
from validation.reference_particles import (
    MM,
    agreement,
    read_myptv_particles,
    read_rt_is,
    synptv_frames,
)

EXAMPLES = Path(__file__).parents[1] / "examples"


def _json_of(argv: list[str]) -> dict:
    """stdout of a ``synptv ... --json`` command, parsed."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        if synptv(argv) != 0:
            raise RuntimeError(f"synptv {' '.join(argv)} failed")
    return json.loads(out.getvalue())


def run_synptv(folder: Path, work: Path) -> tuple[dict, dict[int, np.ndarray]]:
    """``synptv calibrate`` and ``synptv ptv --positions-only`` on an example.

    Returns
    -------
    calibration : dict
        The JSON of ``synptv calibrate``.
    frames : dict of int to ndarray, shape (N, 3)
        Recorded frame number → synptv's particles, m.
    """
    calibration = _json_of(
        ["calibrate", "--dataset", str(folder), "--out", str(work / "cal"), "--json", "--quiet"]
    )
    argv = [
        "ptv",
        "--dataset",
        str(folder),
        "--calibration",
        calibration["files"]["pinhole"],
        "--settings",
        str(folder / "ptv.toml"),
        "--out",
        str(work / "ptv"),
        "--positions-only",
        "--quiet",
    ]
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        if synptv(argv) != 0:
            raise RuntimeError(f"synptv ptv failed on {folder}")
    return calibration, synptv_frames(work / "ptv" / "results.h5", open_dataset(folder))


def _compare(found: dict, reference: dict) -> dict:
    """Per frame: the agreement within 0.1 mm, and the fraction found within 1 mm."""
    close = agreement(found, reference)
    loose = agreement(found, reference, radius=1.0 * MM)
    return {str(n): {**close[n], "within_1mm": loose[n]["within"]} for n in sorted(close)}


def myptv_blob_check(folder: Path, calibration: str) -> dict:
    """MyPTV's blob triplets triangulated by synptv's calibration (its frames 0–2).

    Returns
    -------
    dict
        ``particles``; ``median_mm`` and ``within`` (fraction within 0.1 mm): distance
        to MyPTV's point; ``median_ray_mm``: the RMS distance of the three rays to
        their point, median over the particles.
    """
    shipped = np.loadtxt(folder / "myptv" / "particles")
    shipped = shipped[shipped[:, -1] <= 2]
    cameras = list(load_calibrations(calibration).values())
    pixels = []
    for c in range(len(cameras)):
        blobs = np.loadtxt(folder / "myptv" / f"blobs_cam{c + 1}")
        rows = []
        for particle in shipped:
            of_frame = blobs[blobs[:, 5] == particle[-1]]
            row = of_frame[int(particle[3 + c])]
            rows.append((row[1], row[0]))  # MyPTV's blob files hold the row first
        pixels.append(np.array(rows))
    result = triangulate(cameras, pixels)
    distance = np.linalg.norm(result.points - shipped[:, :3] * MM, axis=1)
    return {
        "particles": len(shipped),
        "median_mm": float(np.median(distance) / MM),
        "within": float(np.mean(distance <= 0.1 * MM)),
        "median_ray_mm": float(np.median(result.rms_distance) / MM),
    }


def _myptv(work: Path) -> dict:
    folder = EXAMPLES / "myptv"
    calibration, found = run_synptv(folder, work)
    reference = read_myptv_particles(folder / "myptv" / "particles", first_frame=1)
    for name, cam in calibration["cameras"].items():
        with (folder / "myptv" / f"{name}_cal_points").open() as f:
            cam["myptv_points"] = sum(1 for line in f if line.strip())
    return {
        "calibration": calibration,
        "frames": _compare(found, reference),
        "myptv_blobs_through_synptv": myptv_blob_check(folder, calibration["files"]["pinhole"]),
    }


def _ori_centre(path: Path) -> np.ndarray:
    """The projection centre of an OpenPTV ``.ori`` file (its first line), m."""
    return np.array(path.read_text().split()[:3], dtype=float) * MM


#: OpenPTV's image pre-processing before its target recognition: the half-width of the
#: box filter whose output is subtracted (the high-pass its GUI applies), px.
_OPENPTV_HIGHPASS = 25


def openptv_check(folder: Path, calibration: str, frame: int = 10001) -> dict | None:
    """OpenPTV's particles of ``frame`` taken apart with ``optv`` (``pip install
    ".[peers]"`` in the clone).

    ``rt_is`` names, per camera, the index of the particle image each particle used in
    OpenPTV's target list, which is not shipped. It is rebuilt as OpenPTV builds it:
    the high-passed image, its target recognition with the shipped ``targ_rec.par``,
    sorted by image row. Then:

    - ``rebuilt_mm``: the targets of the four-camera particles triangulated by
      OpenPTV's calibration (``.ori``, ``.addpar``, its multimedia model), median
      distance to OpenPTV's points: the rebuild is right when this is the file's
      rounding;
    - per camera ``reprojection_px``: OpenPTV's particles projected by its own
      calibration, median distance to the targets they cite (how tightly its own rays
      meet), and ``detected_1px``: the fraction of those targets with a synptv detection
      (the example's ``ptv.toml``) within 1 px;
    - ``synptv_triangulation``: OpenPTV's correspondences triangulated by synptv's
      calibration, by the number of cameras: count, median distance to OpenPTV's point
      (mm) and the fraction within 0.1 mm. This compares the two calibrations alone.

    Returns None without ``optv``.
    """
    try:
        from optv.calibration import Calibration
        from optv.image_processing import preprocess_image
        from optv.imgcoord import image_coordinates
        from optv.orientation import point_positions
        from optv.parameters import ControlParams, TargetParams
        from optv.segmentation import target_recognition
        from optv.transforms import convert_arr_metric_to_pixel, convert_arr_pixel_to_metric
    except ImportError:
        return None
    from scipy.spatial import cKDTree

    from ptv.detect.frames import ImageDetector
    from ptv.io.images import read_image
    from ptv.pipeline.settings_file import load_settings

    dataset = open_dataset(folder)
    detector = ImageDetector(dataset, load_settings(folder / "ptv.toml").detection)
    k, frame_of = next(
        (k, f)
        for k in range(dataset.n_dt)
        for f in "ab"
        if dataset.sequence.frame_number(k, 0, f) == frame
    )
    detections = [d.xy for d in detector.detect(k, 0, frame_of)]
    table = np.loadtxt(folder / "openptv" / "res" / f"rt_is.{frame}", skiprows=1, ndmin=2)
    parameters = folder / "openptv" / "parameters"
    control = ControlParams(len(detections))
    control.read_control_par(str(parameters / "ptv.par"))
    recognition = TargetParams()
    recognition.read(str(parameters / "targ_rec.par"))
    cited = np.full((len(detections), len(table), 2), np.nan)
    cameras, per_camera = [], {}
    for c, name in enumerate(dataset.cameras):
        cal = Calibration()
        cal.from_file(
            str(folder / "openptv" / "cal" / f"{name}.tif.ori").encode(),
            str(folder / "openptv" / "cal" / f"{name}.tif.addpar").encode(),
        )
        cameras.append(cal)
        path = folder / dataset.sequence.images.format(camera=name, n=frame)
        image = read_image(path).astype(np.uint8)
        targets = target_recognition(
            preprocess_image(image, 0, control, _OPENPTV_HIGHPASS), recognition, c, control
        )
        targets.sort_y()
        xy = np.array([t.pos() for t in targets])
        index = table[:, 4 + c].astype(int)
        seen = index >= 0
        cited[c, seen] = xy[index[seen]]
        metric = image_coordinates(
            np.ascontiguousarray(table[seen, 1:4]), cal, control.get_multimedia_params()
        )
        projected = convert_arr_metric_to_pixel(metric, control)
        # OpenPTV's pixel (0, 0) is a corner, synptv's a centre.
        nearest = cKDTree(detections[c]).query(cited[c, seen] - 0.5)[0]
        per_camera[name] = {
            "targets": len(xy),
            "cited": int(seen.sum()),
            "reprojection_px": float(np.median(np.linalg.norm(projected - cited[c, seen], axis=1))),
            "detected_1px": float(np.mean(nearest <= 1.0)),
        }
    count = np.isfinite(cited[:, :, 0]).sum(axis=0)
    four = count == len(cameras)
    metric = np.stack(
        [convert_arr_pixel_to_metric(np.ascontiguousarray(p[four]), control) for p in cited],
        axis=1,
    )
    rebuilt = point_positions(np.ascontiguousarray(metric), control, cameras, None)[0]
    ours = triangulate(list(load_calibrations(calibration).values()), list(cited - 0.5)).points
    distance = np.linalg.norm(ours - table[:, 1:4] * MM, axis=1)
    return {
        "rebuilt_mm": float(np.median(np.linalg.norm(rebuilt - table[four, 1:4], axis=1))),
        "cameras": per_camera,
        "synptv_triangulation": {
            str(n): {
                "particles": int(np.sum(count == n)),
                "median_mm": float(np.median(distance[count == n]) / MM),
                "within": float(np.mean(distance[count == n] <= 0.1 * MM)),
            }
            for n in range(2, len(cameras) + 1)
        },
    }


def _test_cavity(work: Path) -> dict:
    folder = EXAMPLES / "test-cavity"
    calibration, found = run_synptv(folder, work)
    reference = {n: read_rt_is(folder / "openptv" / "res" / f"rt_is.{n}") for n in (10001, 10002)}
    for name, cam in calibration["cameras"].items():
        ori = _ori_centre(folder / "openptv" / "cal" / f"{name}.tif.ori")
        cam["openptv_centre_m"] = ori.tolist()
        cam["centre_offset_mm"] = float(np.linalg.norm(np.array(cam["centre_m"]) - ori) / MM)
    return {
        "calibration": calibration,
        "frames": _compare(found, reference),
        "openptv_through_synptv": openptv_check(folder, calibration["files"]["pinhole"]),
    }


BENCHMARKS = {"myptv": _myptv, "test-cavity": _test_cavity}


def main(names: list[str]) -> dict:
    """Run the examples ``names`` (all by default) and return their figures."""
    unknown = [n for n in names if n not in BENCHMARKS]
    if unknown:
        raise SystemExit(f"unknown example(s) {', '.join(unknown)}; known: {', '.join(BENCHMARKS)}")
    results = {}
    for name in names or list(BENCHMARKS):
        with tempfile.TemporaryDirectory() as tmp:
            results[name] = BENCHMARKS[name](Path(tmp))
    return results


if __name__ == "__main__":
    print(json.dumps(main(sys.argv[1:]), indent=2))
