"""Calibrating from dot lists (CSV, OpenPTV .crd/.fix) instead of plate images: the lists
are read as written, the calibration from them recovers the true cameras, and a bad list
is refused in one line naming the file and the line, before anything is written."""

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from ptv.calibration.io import load_calibrations
from ptv.calibration.plate_images import find_traverse_dots, plate_setup
from ptv.triangulate import triangulate
from simulator.rigs import load_rig
from simulator.target import PlateDesign, build_plate, traverse_positions
from validation.cli import main
from validation.dataset.calibrate import calibrate_dataset
from validation.truth.calibration_errors import synthetic_plane_dots

RIG = load_rig("paper-stereo")
DESIGN = PlateDesign()


def write_dot_lists(folder: Path, layout: str, z: np.ndarray, noise_px: float = 0.0) -> list:
    """A dataset folder whose plate positions are dot lists of ``layout`` ("csv" or
    "openptv"): the true cameras' projections of a perfect plate, plus noise (px).

    Returns the written dots, per camera and plane (TraverseDots)."""
    dots = synthetic_plane_dots(RIG.cameras, build_plate(DESIGN, z), noise_px=noise_px, rng=1)
    spec = {
        "cameras": {
            name: {
                "image_size": list(camera.lens.sensor_size),
                "pixel_pitch": camera.lens.pixel_pitch,
                "focal_length": camera.lens.focal_length,
            }
            for name, camera in zip(RIG.camera_names, RIG.cameras, strict=True)
        },
        "target": DESIGN.as_dict(),
        "traverse_z": [float(v) for v in z],
    }
    (folder / "lists").mkdir(parents=True)
    number = {tuple(ij): k for k, ij in enumerate(DESIGN.indices.tolist())}
    for name, planes in zip(RIG.camera_names, dots, strict=True):
        for j, plane in enumerate(planes):
            if layout == "csv":
                rows = [
                    f"{i},{jj},{x!r},{y!r}"
                    for (i, jj), (x, y) in zip(
                        plane.indices.tolist(), plane.pixels.tolist(), strict=True
                    )
                ]
                (folder / "lists" / f"{name}_{j}.csv").write_text("i,j,x,y\n" + "\n".join(rows))
                continue
            stem = folder / "lists" / f"plane{j + 1}_{name}"
            lines = [  # OpenPTV's pixel origin is the top-left pixel's corner
                f"{number[tuple(ij)]:6d} {x + 0.5:.9f} {y + 0.5:.9f}"
                for ij, (x, y) in zip(plane.indices.tolist(), plane.pixels.tolist(), strict=True)
            ]
            stem.with_suffix(".crd").write_text("\n".join(reversed(lines)) + "\n")
            xy_mm = DESIGN.indices * DESIGN.pitch * 1e3
            stem.with_suffix(".fix").write_text(
                "".join(
                    f"{k:.5f} {x:.5f} {y:.5f} {z[j] * 1e3:.5f}\n" for k, (x, y) in enumerate(xy_mm)
                )
            )
    spec["calibration_dots"] = (
        {"format": "csv", "files": "lists/{camera}_{j}.csv"}
        if layout == "csv"
        else {
            "format": "openptv",
            "crd": "lists/plane{j}_{camera}.crd",
            "fix": "lists/plane{j}_{camera}.fix",
            "first_j": 1,
        }
    )
    (folder / "experiment.json").write_text(json.dumps(spec, indent=2))
    return dots


@pytest.mark.parametrize("layout", ["csv", "openptv"])
def test_the_lists_are_read_as_written(tmp_path, layout):
    written = write_dot_lists(tmp_path, layout, traverse_positions(3))
    found = find_traverse_dots(plate_setup(tmp_path))
    assert list(found) == list(RIG.camera_names)
    for name, planes in zip(RIG.camera_names, written, strict=True):
        for read, wrote in zip(found[name], planes, strict=True):
            order = np.lexsort(read.indices.T[::-1])  # the .crd lines come reversed
            back = np.lexsort(wrote.indices.T[::-1])
            np.testing.assert_array_equal(read.indices[order], wrote.indices[back])
            np.testing.assert_allclose(read.pixels[order], wrote.pixels[back], atol=1e-8)
            assert read.z == wrote.z and read.pitch == DESIGN.pitch


def test_calibrating_from_dot_lists_recovers_the_true_cameras(tmp_path):
    write_dot_lists(tmp_path / "ds", "csv", traverse_positions(5))
    result = calibrate_dataset(
        tmp_path / "ds", methods=("model-free", "soloff"), out=tmp_path / "cal"
    )
    rng = np.random.default_rng(2)
    points = np.column_stack(
        [
            rng.uniform(-0.03, 0.03, 300),
            rng.uniform(-0.03, 0.03, 300),
            rng.uniform(-2e-3, 2e-3, 300),
        ]
    )
    pixels = [camera.project(points) for camera in RIG.cameras]
    for method in ("model-free", "soloff"):
        models = load_calibrations(tmp_path / "cal" / f"{method}.h5")
        assert list(models) == list(RIG.camera_names)
        error = np.linalg.norm(triangulate(list(models.values()), pixels).points - points, axis=1)
        # Exact dots and flat refraction: only the fitted polynomials limit either
        # model (~0.1 µm, far below a 100 µm object-side pixel).
        assert np.nanmax(error) < 1e-6, method
        assert result.table1[method]["nominal"]["d_um"] < 0.5
    assert len(result.leave_one_plane_out["model-free"]["planes_d_um"]) == 5


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    """Two plate positions as CSV lists and as OpenPTV lists."""
    root = tmp_path_factory.mktemp("lists")
    for layout in ("csv", "openptv"):
        write_dot_lists(root / layout, layout, traverse_positions(2))
    return root


def _set_line(path: Path, number: int, text: str | None) -> None:
    """Line ``number`` (1-based) of ``path`` replaced by ``text`` (None: removed)."""
    lines = path.read_text().splitlines()
    lines[number - 1 : number] = [] if text is None else [text]
    path.write_text("\n".join(lines) + "\n")


def _set_field(path: Path, number: int, field: int, value: str, sep: str = ",") -> None:
    """Field ``field`` of line ``number`` of ``path`` set to ``value``."""
    parts = path.read_text().splitlines()[number - 1].split(sep if sep == "," else None)
    parts[field] = value
    _set_line(path, number, sep.join(parts))


def _spec(folder: Path, change) -> None:
    spec = json.loads((folder / "experiment.json").read_text())
    change(spec)
    (folder / "experiment.json").write_text(json.dumps(spec))


CAM = RIG.camera_names[0]
CSV_1 = f"lists/{CAM}_1.csv"
CRD_2, FIX_2 = f"lists/plane2_{CAM}.crd", f"lists/plane2_{CAM}.fix"
BAD = {
    # case: (layout, spoil, file named, message)
    "missing list": ("csv", lambda d: (d / CSV_1).unlink(), CSV_1, "dot list missing (1 of 2)"),
    "malformed row": (
        "csv",
        lambda d: _set_field(d / CSV_1, 3, 2, "abc"),
        CSV_1,
        "line 3: x must be a finite number, got 'abc'",
    ),
    "short row": ("csv", lambda d: _set_line(d / CSV_1, 4, "1,2"), CSV_1, "line 4: fewer fields"),
    "index not an integer": (
        "csv",
        lambda d: _set_field(d / CSV_1, 5, 0, "1.5"),
        CSV_1,
        "line 5: i must be an integer, got '1.5'",
    ),
    "missing column": (
        "csv",
        lambda d: _set_line(d / CSV_1, 1, "i,j,x,z"),
        CSV_1,
        "missing column(s) y (the header is i,j,x,y)",
    ),
    "repeated node": (
        "csv",
        lambda d: (d / CSV_1).write_text(
            (d / CSV_1).read_text() + "\n" + (d / CSV_1).read_text().splitlines()[1]
        ),
        CSV_1,
        "listed twice (first on line 2)",
    ),
    "pixel off the image": (
        "csv",
        lambda d: _set_field(d / CSV_1, 2, 2, "5000.0"),
        CSV_1,
        "line 2: pixel (5000,",
    ),
    "node off the plate": (
        "csv",
        lambda d: _set_field(d / CSV_1, 2, 0, "50"),
        CSV_1,
        "line 2: grid node (50,",
    ),
    "too few dots": (
        "csv",
        lambda d: (d / CSV_1).write_text("\n".join((d / CSV_1).read_text().splitlines()[:6])),
        CSV_1,
        "5 dot(s), a plate position needs at least 12",
    ),
    "stuck traverse": (
        "csv",
        lambda d: shutil.copy(d / f"lists/{CAM}_0.csv", d / CSV_1),
        CSV_1,
        "dots sit where they were",
    ),
    "unknown point number": (
        "openptv",
        lambda d: _set_field(d / CRD_2, 1, 0, "9999", sep=" "),
        CRD_2,
        "line 1: point number 9999 is not in",
    ),
    "malformed crd line": (
        "openptv",
        lambda d: _set_line(d / CRD_2, 2, "12 400.5"),
        CRD_2,
        "line 2: expected 3 numbers (number x y), got '12 400.5'",
    ),
    "repeated point number": (
        "openptv",
        lambda d: _set_field(d / CRD_2, 3, 0, (d / CRD_2).read_text().split()[0], sep=" "),
        CRD_2,
        "line 3: point number",
    ),
    "Z of another position": (
        "openptv",
        lambda d: shutil.copy(d / f"lists/plane1_{CAM}.fix", d / FIX_2),
        FIX_2,
        "but traverse_z gives 0.5 mm for this plate position",
    ),
    "point off the grid": (
        "openptv",
        lambda d: _set_field(d / FIX_2, 1, 1, "-48.7", sep=" "),
        FIX_2,
        "line 1: point (-48.7, -50) mm is not on the target's 5 mm grid",
    ),
    "missing fix": ("openptv", lambda d: (d / FIX_2).unlink(), FIX_2, "dot list missing"),
    "images and dots": (
        "csv",
        lambda d: _spec(d, lambda s: s.update(calibration_images="p/{camera}_{j}.tif")),
        "experiment.json",
        "(top level): calibration_dots gives the dots: leave out calibration_images",
    ),
    "files of another format": (
        "csv",
        lambda d: _spec(d, lambda s: s["calibration_dots"].update(crd="{camera}{j}.crd")),
        "experiment.json",
        "calibration_dots: format 'csv' takes files, not crd",
    ),
    "no fix pattern": (
        "openptv",
        lambda d: _spec(d, lambda s: s["calibration_dots"].pop("fix")),
        "experiment.json",
        "calibration_dots: 'fix' is a required property",
    ),
    "no dots at all": (
        "csv",
        lambda d: _spec(d, lambda s: s.pop("calibration_dots")),
        "experiment.json",
        "calibration_images: required to calibrate (or calibration_dots)",
    ),
}


@pytest.mark.parametrize("case", list(BAD))
def test_a_bad_dot_list_is_named_in_one_line_and_nothing_is_written(small, tmp_path, capsys, case):
    layout, spoil, file, message = BAD[case]
    folder = tmp_path / "ds"
    shutil.copytree(small / layout, folder)
    spoil(folder)
    out = tmp_path / "cal"
    argv = ["calibrate", "--dataset", str(folder), "--methods", "model-free", "--out", str(out)]
    assert main([*argv, "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(folder / file) in err and message in err, err
    assert not out.exists()


def test_points_openptv_did_not_find_are_skipped(tmp_path):
    """OpenPTV writes −999 for a plate point it could not sort on an image: those lines
    are left out, not refused, and the other dots read as written."""
    written = write_dot_lists(tmp_path, "openptv", traverse_positions(3))
    crd = tmp_path / "lists" / f"plane1_{RIG.camera_names[0]}.crd"
    lines = crd.read_text().splitlines()
    lines[0] = f"{lines[0].split()[0]} -999.000000000 -999.000000000"
    lines[1] = "  -999 -999.000000000 -999.000000000"
    crd.write_text("\n".join(lines) + "\n")
    first = find_traverse_dots(plate_setup(tmp_path))[RIG.camera_names[0]][0]
    assert len(first.indices) == len(written[0][0].indices) - 2
