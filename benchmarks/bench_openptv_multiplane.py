"""Real plates: synptv's calibrations of OpenPTV's multiplane example beside OpenPTV's own.

``examples/openptv-multiplane`` holds four cameras' images of a 27 × 15 dot plate
(5 mm pitch, no marks) at four depths, with the seed dots a user would click, and the
calibration OpenPTV shipped with them (``openptv/cal/cam*.tif.ori``, ``.addpar``, its
``ptv.par`` with the multimedia indices and the sorted dots ``plane*_cam*.tif.crd``,
``.fix``). Both are scored on one metric, the paper's Table 1: every dot of every plane
triangulated from all four cameras, mean 3-D distance to its nominal position.

- synptv: ``synptv calibrate`` (dots found from the images, indexed from the seeds;
  every method), in-sample and leave-one-plane-out;
- OpenPTV: its shipped calibration evaluated by ``optv`` 0.3.2 on its own sorted dot
  pixels (its pixel convention), ``point_positions`` with its multimedia model.

Run: ``python -m benchmarks.bench_openptv_multiplane`` (needs ``pip install
".[peers]"`` in the clone); prints one JSON object and a markdown table.
"""

import contextlib
import io
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

from validation.cli import main as synptv

EXAMPLE = Path(__file__).parents[1] / "examples" / "openptv-multiplane"
CAMERAS = 4
PLANES = 4


def _synptv() -> dict:
    """synptv calibrate --json on the example, every method."""
    with tempfile.TemporaryDirectory() as tmp:
        out = io.StringIO()
        argv = ["calibrate", "--dataset", str(EXAMPLE), "--out", f"{tmp}/cal", "--json", "--quiet"]
        with contextlib.redirect_stdout(out):
            if synptv(argv) != 0:
                raise RuntimeError("synptv calibrate failed")
    return json.loads(out.getvalue())


def _openptv() -> dict:
    """Table 1 of the shipped OpenPTV calibration, by optv, on its sorted dots."""
    from optv.calibration import Calibration
    from optv.orientation import point_positions
    from optv.parameters import ControlParams, VolumeParams
    from optv.transforms import convert_arr_pixel_to_metric, distorted_to_flat

    folder = EXAMPLE / "openptv"
    control = ControlParams(CAMERAS)
    control.read_control_par(str(folder / "parameters/ptv.par"))
    volume = VolumeParams()
    volume.read_volume_par(str(folder / "parameters/criteria.par"))
    cals = []
    for c in range(1, CAMERAS + 1):
        cal = Calibration()
        cal.from_file(
            str(folder / f"cal/cam{c}.tif.ori").encode(),
            str(folder / f"cal/cam{c}.tif.addpar").encode(),
        )
        cals.append(cal)
    errors = []
    for p in range(1, PLANES + 1):
        crds = [np.loadtxt(folder / f"cal/plane{p}_cam{c}.tif.crd") for c in range(1, 5)]
        fix = np.loadtxt(folder / f"cal/plane{p}_cam1.tif.fix")
        flat = np.stack(
            [
                distorted_to_flat(convert_arr_pixel_to_metric(crd[:, 1:3].copy(), control), cal)
                for crd, cal in zip(crds, cals, strict=True)
            ],
            axis=1,
        )
        positions, _ = point_positions(flat, control, cals, volume)
        errors.append(positions - fix[:, 1:4])  # mm
    delta = np.concatenate(errors) * 1e3  # µm
    d_x, d_y, d_z = np.abs(delta).mean(axis=0)
    return {
        "d_X_um": float(d_x),
        "d_Y_um": float(d_y),
        "d_Z_um": float(d_z),
        "d_um": float(np.linalg.norm(delta, axis=1).mean()),
        "dots": len(delta),
    }


def run(quick: bool = False) -> dict:
    """Both calibrations' Table 1 (µm) and synptv's leave-one-plane-out error."""
    mine = _synptv()
    return {
        "synptv": {
            method: {
                **refs["nominal"],
                "leave_one_plane_out_um": mine["leave_one_plane_out"][method]["d_um"],
            }
            for method, refs in mine["table1"].items()
        },
        "openptv_shipped": _openptv(),
    }


def markdown(figures: dict) -> str:
    """The comparison as a markdown table."""
    rows = [
        "| calibration | d_X | d_Y | d_Z | d (µm) | leave-one-plane-out d (µm) |",
        "|---|---|---|---|---|---|",
    ]
    for method, t in figures["synptv"].items():
        rows.append(
            f"| synptv {method} | {t['d_X_um']:.1f} | {t['d_Y_um']:.1f} | {t['d_Z_um']:.1f} | "
            f"{t['d_um']:.1f} | {t['leave_one_plane_out_um']:.1f} |"
        )
    o = figures["openptv_shipped"]
    rows.append(
        f"| OpenPTV (shipped .ori/.addpar) | {o['d_X_um']:.1f} | {o['d_Y_um']:.1f} | "
        f"{o['d_Z_um']:.1f} | {o['d_um']:.1f} | – |"
    )
    return "\n".join(rows)


if __name__ == "__main__":
    figures = run()
    json.dump(figures, sys.stdout, indent=2)
    print()
    print(markdown(figures))
