"""A peer, end to end: OpenPTV's ``optv`` 0.3.2 beside synptv's own stack on one dataset.

A small dataset is rendered (the ``paper-stereo`` rig: two Scheimpflug cameras through
8°-oblique windows), exported in OpenPTV's layout (``synptv export --format openptv``)
and processed twice:

- **optv**, from the exported files only: its parameter files (optv.parameters), its
  initial orientations (Calibration.from_file), its own dot detection on the 8-bit
  plate images (target_recognition with detect_plate.par), the dots sorted against the
  target files by projecting them with the initial orientation (match_detection_to_ref),
  then ``full_calibration`` on the dots of every traverse position together, with its
  multimedia model set to the rig's glass (ptv.par, glass vectors). The calibration is
  fitted in stages, each from the last that converged: the exterior orientation, then
  with the principal distance and point, then each distortion and affine term; a stage
  that fails is reported with optv's message. The calibration kept is the converged
  stage of smallest reprojection residual (no truth used). Particles: its own target
  recognition on the 8-bit particle images, its correspondences (epipolar band of
  criteria.par, its half-width set to twice the calibration's RMS reprojection
  residual) and point_positions of every pair, written as a positions CSV in the
  dataset's world frame (metres).
- **synptv**: ``synptv calibrate --methods model-free``, ``synptv ptv`` and ``synptv score
  --positions results.h5``.

Both position sets are scored by ``synptv score`` (yield, ghost fraction, position RMS
per component, in the default analysis volume). The calibration error is the paper's
Table 1 metric for both: every dot seen by both cameras triangulated with the code's
calibration, mean 3-D distance to its nominal position (what the calibration was
fitted to) and to its true centre.

Run: ``python -m benchmarks.bench_peer_optv [--quick]`` prints one JSON object and a
markdown table; needs ``optv`` (``pip install ".[peers]"`` in the clone).
"""

import contextlib
import csv
import io
import json
import sys
import tempfile
from pathlib import Path

import h5py
import numpy as np
import tifffile

from validation.cli import main as synptv
from validation.commands.export import export_dataset
from validation.export.openptv import frame_number

#: Dataset sizes: (particles, frame pairs per Δt, traverse positions).
SIZES = {"quick": (500, 2, 5), "full": (1000, 4, 7)}
#: Pixel radius within which a projected target point claims a detected dot.
SORT_RADIUS_PX = 10
#: Half-width of optv's epipolar band over its calibration's reprojection residual (RMS,
#: px, the worse camera): wide enough for the calibration's errors, narrow because with
#: two cameras every other particle inside the band makes a pair ambiguous (a trial on
#: the quick dataset: yield 0.61 at 2 px, 0.86 at 0.5 px, 0.74 at 0.25 px).
BAND_OVER_RESIDUAL = 2.0
#: Calibration stages: (name, optv flags), each fitted from the last that converged.
STAGES = (
    ("exterior", []),
    ("+ cc, xh, yh", ["cc", "xh", "yh"]),
    ("+ k1", ["cc", "xh", "yh", "k1"]),
    ("+ k2", ["cc", "xh", "yh", "k2"]),
    ("+ k1, k2", ["cc", "xh", "yh", "k1", "k2"]),
    ("+ p1, p2", ["cc", "xh", "yh", "p1", "p2"]),
    ("+ scale, shear", ["cc", "xh", "yh", "scale", "shear"]),
)


def _run_synptv(*argv: str) -> str:
    """Run a synptv command in this process; its stdout, or RuntimeError."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        status = synptv(list(argv))
    if status != 0:
        raise RuntimeError(f"synptv {' '.join(argv)} exited with {status}")
    return out.getvalue()


def _params(export: Path, cameras: int) -> dict:
    """optv's parameter objects, read from the exported parameters/*.par."""
    from optv.parameters import ControlParams, TargetParams, VolumeParams

    control = ControlParams(cameras)
    control.read_control_par(str(export / "parameters/ptv.par"))
    volume = VolumeParams()
    volume.read_volume_par(str(export / "parameters/criteria.par"))
    plate, particles = TargetParams(), TargetParams()
    plate.read(str(export / "parameters/detect_plate.par"))
    particles.read(str(export / "parameters/targ_rec.par"))
    return {"control": control, "volume": volume, "plate": plate, "particles": particles}


def _initial(export: Path, camera: str):
    """The exported initial orientation of ``camera`` as an optv Calibration."""
    from optv.calibration import Calibration

    cal = Calibration()
    cal.from_file(
        str(export / f"cal/{camera}.tif.ori").encode(),
        str(export / f"cal/{camera}.tif.addpar").encode(),
    )
    return cal


def _copy(cal, export: Path, camera: str):
    """A Calibration holding the values of ``cal`` (optv fits in place)."""
    out = _initial(export, camera)
    out.set_pos(cal.get_pos())
    out.set_angles(cal.get_angles())
    out.set_primary_point(cal.get_primary_point())
    out.set_radial_distortion(cal.get_radial_distortion())
    out.set_decentering(cal.get_decentering())
    out.set_affine_trans(cal.get_affine())
    out.set_glass_vec(cal.get_glass_vec())
    return out


def _plate_dots(export: Path, c: int, camera: str, planes: int, params: dict) -> dict:
    """optv's dots on every plate image of camera c, sorted against the target files
    with the initial orientation: {(plane, dot): pixel (2,)}."""
    from optv.orientation import match_detection_to_ref
    from optv.segmentation import target_recognition

    guess = _initial(export, camera)
    found = {}
    for j in range(planes):
        image = tifffile.imread(export / f"cal/{camera}/plane_{j:02d}.tif")
        detected = target_recognition(image, params["plate"], c, params["control"])
        reference = np.loadtxt(export / f"cal/target_plane_{j:02d}.txt")[:, 1:]
        ordered = match_detection_to_ref(
            guess, reference, detected, params["control"], eps=SORT_RADIUS_PX
        )
        for i, target in enumerate(ordered):
            if target.pnr() >= 0:
                found[(j, i)] = np.array(target.pos())
    return found


def _calibrate(export: Path, camera: str, dots: dict, targets_mm, params: dict) -> tuple:
    """optv's staged full_calibration of one camera on its sorted dots; the kept
    Calibration and one record per stage."""
    from optv.orientation import full_calibration
    from optv.tracking_framebuf import TargetArray

    keys = sorted(dots)
    reference = np.array([targets_mm[key] for key in keys])
    targets = TargetArray(len(keys))
    for i, key in enumerate(keys):
        targets[i].set_pos(dots[key])
        targets[i].set_pnr(i)
    pitch = params["control"].get_pixel_size()[0]
    last, best, stages = _initial(export, camera), None, []
    for name, flags in STAGES:
        trial = _copy(last, export, camera)
        try:
            residuals, _used, _err = full_calibration(
                trial, reference, targets, params["control"], flags
            )
        except ValueError as err:
            stages.append({"stage": name, "converged": False, "message": str(err)})
            continue
        rms = float(np.sqrt(np.mean(np.sum(residuals**2, axis=1)))) / pitch
        stages.append({"stage": name, "converged": True, "residual_rms_px": rms})
        last = trial
        if best is None or rms < best[0]:
            best = (rms, name, trial)
    for record in stages:
        record["kept"] = record["stage"] == best[1]
    return best[2], stages


def _target_files(export: Path, planes: int) -> np.ndarray:
    """Nominal dot positions of the exported target files, (N_Z, D, 3), mm."""
    return np.stack(
        [np.loadtxt(export / f"cal/target_plane_{j:02d}.txt")[:, 1:] for j in range(planes)]
    )


def _triangulate(pixels: list, cals: list, params: dict) -> np.ndarray:
    """optv's 3-D positions (n, 3), mm, of points given by their pixels in each camera."""
    from optv.orientation import point_positions
    from optv.transforms import convert_arr_pixel_to_metric, distorted_to_flat

    flat = np.stack(
        [
            distorted_to_flat(convert_arr_pixel_to_metric(np.asarray(p), params["control"]), cal)
            for p, cal in zip(pixels, cals, strict=True)
        ],
        axis=1,
    )
    positions, _rcm = point_positions(flat, params["control"], cals, params["volume"])
    return positions


def _calibration_error(dataset: Path, dots: list, targets_mm, cals: list, params) -> dict:
    """Table 1 metric of optv's calibration: mean 3-D distance of the dots seen by every
    camera, triangulated, to their nominal and true centres, µm."""
    common = sorted(set.intersection(*(set(d) for d in dots)))
    points = _triangulate([[d[key] for key in common] for d in dots], cals, params) / 1e3
    nominal = np.array([targets_mm[key] for key in common]) / 1e3
    with h5py.File(dataset / "truth.h5", "r") as truth:
        true = truth["plate/dots_world"][:]
    centres = np.array([true[j, i] for j, i in common])
    return {
        "dots": len(common),
        "d_um_nominal": float(np.mean(np.linalg.norm(points - nominal, axis=1)) * 1e6),
        "d_um_true": float(np.mean(np.linalg.norm(points - centres, axis=1)) * 1e6),
    }


def _frame_positions(export: Path, k: int, number: int, cameras, cals, params) -> np.ndarray:
    """optv's particles of one exposure: target recognition, correspondences, 3-D
    positions (n, 3), m."""
    from optv.correspondences import MatchedCoords, correspondences
    from optv.orientation import point_positions
    from optv.segmentation import target_recognition

    targets, flat = [], []
    for c, (camera, cal) in enumerate(zip(cameras, cals, strict=True)):
        image = tifffile.imread(export / f"img/dt{k}/{camera}.{number}")
        found = target_recognition(image, params["particles"], c, params["control"])
        found.sort_y()
        targets.append(found)
        flat.append(MatchedCoords(found, params["control"], cal))
    _pos, cliques, _n = correspondences(targets, flat, cals, params["volume"], params["control"])
    out = []
    for clique in cliques:
        if clique.shape[1] == 0:
            continue
        coords = np.array([flat[c].get_by_pnrs(clique[c]) for c in range(len(cals))])
        positions, _rcm = point_positions(
            coords.transpose(1, 0, 2), params["control"], cals, params["volume"]
        )
        out.append(positions)
    return np.concatenate(out) / 1e3 if out else np.zeros((0, 3))


def _optv_positions(export: Path, frames: list, cameras, cals, params, path: Path) -> int:
    """Write optv's positions of every exposure as a synptv score CSV; rows written."""
    rows = 0
    with path.open("w", newline="") as stream:
        writer = csv.writer(stream)
        writer.writerow(["dt", "snapshot", "frame", "x", "y", "z"])
        for k, m, frame in frames:
            number = frame_number(m, frame)
            for x, y, z in _frame_positions(export, k, number, cameras, cals, params):
                writer.writerow([k, m, frame, f"{x:.9f}", f"{y:.9f}", f"{z:.9f}"])
                rows += 1
    return rows


def _score(dataset: Path, positions: Path, out: Path) -> dict:
    """synptv score's JSON object for a positions file."""
    text = _run_synptv(
        "score",
        "--dataset",
        str(dataset),
        "--positions",
        str(positions),
        "--json",
        "--out",
        str(out),
    )
    return json.loads(text[text.index("{") :])


def _summary(score: dict) -> dict:
    """The table's figures of a score."""
    return {
        "yield": score["yield"],
        "ghost_fraction": score["ghost_fraction"],
        "position_rms_um": score["position_rms_um"],
        "n_reference": score["n_reference"],
        "n_found": score["n_found"],
    }


def run(quick: bool) -> dict:
    """Render, export, run both codes, score; the figures as one dict."""
    import optv.version

    particles, pairs, planes = SIZES["quick" if quick else "full"]
    with tempfile.TemporaryDirectory(prefix="bench-peer-optv-") as tmp:
        work = Path(tmp)
        dataset, export = work / "dataset", work / "openptv"
        _run_synptv(
            "render",
            "--rig",
            "paper-stereo",
            "--out",
            str(dataset),
            "--particles",
            str(particles),
            "--frames",
            str(pairs),
            "--planes",
            str(planes),
            "--workers",
            "1",
            "--quiet",
        )
        export_dataset(dataset, "openptv", export)
        description = json.loads((dataset / "experiment.json").read_text())
        cameras = list(description["cameras"])
        params = _params(export, len(cameras))

        targets_mm = _target_files(export, planes)
        dots = [_plate_dots(export, c, name, planes, params) for c, name in enumerate(cameras)]
        fits = [
            _calibrate(export, name, d, targets_mm, params)
            for name, d in zip(cameras, dots, strict=True)
        ]
        cals = [cal for cal, _stages in fits]
        band_px = BAND_OVER_RESIDUAL * max(
            r["residual_rms_px"] for _cal, stages in fits for r in stages if r.get("kept")
        )
        params["volume"].set_eps0(band_px * params["control"].get_pixel_size()[0])
        frames = [
            (k, m, frame)
            for k in range(len(description["dt"]))
            for m in range(pairs)
            for frame in "ab"
        ]
        csv_path = work / "optv_positions.csv"
        rows = _optv_positions(export, frames, cameras, cals, params, csv_path)
        optv_score = _score(dataset, csv_path, work / "score-optv")

        table1 = json.loads(
            _run_synptv(
                "calibrate",
                "--dataset",
                str(dataset),
                "--methods",
                "model-free",
                "--json",
                "--quiet",
                "--out",
                str(work / "calibrations"),
            )
        )
        _run_synptv(
            "ptv",
            "--dataset",
            str(dataset),
            "--calibration",
            table1["files"]["model-free"],
            "--out",
            str(work / "ptv"),
            "--quiet",
        )
        synptv_score = _score(dataset, work / "ptv/results.h5", work / "score-synptv")
        model_free = table1["table1"]["model-free"]
        return {
            "dataset": {
                "rig": "paper-stereo",
                "particles": particles,
                "frame_pairs_per_dt": pairs,
                "dt": len(description["dt"]),
                "planes": planes,
            },
            "optv": {
                "version": optv.version.__version__,
                "calibration": {
                    "stages": {
                        name: stages for name, (_cal, stages) in zip(cameras, fits, strict=True)
                    },
                    "dots_found": [len(d) for d in dots],
                    **_calibration_error(dataset, dots, targets_mm, cals, params),
                },
                "epipolar_band_px": band_px,
                "positions_written": rows,
                **_summary(optv_score),
            },
            "synptv": {
                "calibration": {
                    "method": "model-free",
                    "d_um_nominal": model_free["nominal"]["d_um"],
                    "d_um_true": model_free.get("true", {}).get("d_um"),
                },
                **_summary(synptv_score),
            },
        }


def markdown(figures: dict) -> str:
    """The side-by-side table of :func:`run`'s figures."""
    lines = [
        "| code | calibration d, nominal / true dots (µm) | yield | ghost fraction "
        "| position RMS x / y / z (µm) |",
        "|---|---|---|---|---|",
    ]
    for code, label in (
        ("optv", f"OpenPTV optv {figures['optv']['version']}"),
        ("synptv", "synptv"),
    ):
        f = figures[code]
        cal = f["calibration"]
        rms = " / ".join("–" if v is None else f"{v:.1f}" for v in f["position_rms_um"].values())
        true = "–" if cal["d_um_true"] is None else f"{cal['d_um_true']:.1f}"
        lines.append(
            f"| {label} | {cal['d_um_nominal']:.1f} / {true} | {f['yield']:.3f} "
            f"| {f['ghost_fraction']:.3f} | {rms} |"
        )
    return "\n".join(lines)


if __name__ == "__main__":
    result = run(quick="--quick" in sys.argv[1:])
    json.dump(result, sys.stdout, indent=2)
    print()
    print(markdown(result))
