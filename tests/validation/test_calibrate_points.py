"""synptv calibrate on a 3-D target of listed points (examples/myptv: three cameras, one
image each of MyPTV's stepped target), and its bad input."""

import json
import re
import shutil
from pathlib import Path

import pytest

from ptv.calibration.io import load_calibrations
from validation.cli import main

EXAMPLE = Path(__file__).parents[2] / "examples" / "myptv"


def test_myptv_cameras_from_their_target_images(tmp_path, capsys):
    argv = ["calibrate", "--dataset", str(EXAMPLE), "--out", str(tmp_path / "cal"), "--json"]
    assert main([*argv, "--quiet"]) == 0
    printed = capsys.readouterr()
    report = json.loads(printed.out)
    for name, cam in report["cameras"].items():
        # MyPTV's own calibration associated 421, 432 and 411 of the 437 points.
        assert cam["points"] >= 410, name
        assert cam["rms_px"] < 0.45, name
    # A principal point off the 1280 × 1024 sensor is said, not taken silently.
    off = sorted(
        name
        for name, cam in report["cameras"].items()
        if not (
            0 <= cam["principal_point_px"][0] < 1280 and 0 <= cam["principal_point_px"][1] < 1024
        )
    )
    assert sorted(w.split(":")[0] for w in report["warnings"]) == off
    assert printed.err.count("lies off the 1280 × 1024 px sensor") == len(off)
    assert report["target_points"]["points"] >= 420
    assert report["target_points"]["d_um"] < 80.0
    cameras = load_calibrations(report["files"]["pinhole"])
    assert list(cameras) == ["cam1", "cam2", "cam3"]


def copy_example(tmp_path: Path) -> Path:
    """The example's text files and calibration images in a folder of its own."""
    folder = tmp_path / "data"
    shutil.copytree(EXAMPLE / "Calibration", folder / "Calibration")
    for name in ("experiment.json", "seeds.csv"):
        shutil.copy(EXAMPLE / name, folder / name)
    return folder


def edit_json(folder: Path, edit) -> None:
    spec = json.loads((folder / "experiment.json").read_text())
    edit(spec)
    (folder / "experiment.json").write_text(json.dumps(spec))


def refuse(folder: Path, capsys, *extra) -> str:
    """Run synptv calibrate, expect exit status 2, one line on stderr and no output."""
    out = folder / "out"
    assert main(["calibrate", "--dataset", str(folder), "--out", str(out), "--quiet", *extra]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err
    assert not out.exists()
    return err


def test_plate_fields_in_a_point_target_description_are_named(tmp_path, capsys):
    folder = copy_example(tmp_path)

    def edit(spec):
        spec["traverse_z"] = [0.0, 0.001]
        spec["calibration_images"] = "Calibration/{camera}_{j}.tif"
        spec["target"]["units"] = "cm"
        del spec["calibration_seeds"]

    edit_json(folder, edit)
    err = refuse(folder, capsys)
    assert err.startswith(f"synptv calibrate: error: {folder / 'experiment.json'}: 4 problems: ")
    for fragment in (
        "calibration_images: 'Calibration/{camera}_{j}.tif': a point target has one image per "
        "camera",
        "calibration_seeds: required to calibrate",
        "target.units: 'cm' is not one of ['m', 'mm']",
        "traverse_z: a point target is imaged once per camera",
    ):
        assert fragment in err


@pytest.mark.parametrize(
    ("row", "message"),
    [
        (
            "cam1,1.0,0.0,0.0,300,900",
            r"row 20: no point of .*target_file at X, Y, Z = 1.0, 0.0, 0.0 mm",
        ),
        ("cam4,0.0,0.0,0.0,300,900", r"row 20: unknown camera 'cam4' \(experiment.json has cam1"),
        ("cam1,0.0,0.0,0.0,x,900", "row 20: X, Y, Z, x, y must be numbers"),
        (
            "cam1,0.0,0.0,0.0,250,900",
            "row 20: point 0.0, 0.0, 0.0 is seeded twice for camera 'cam1'",
        ),
    ],
)
def test_a_bad_seed_row_is_named(tmp_path, capsys, row, message):
    folder = copy_example(tmp_path)
    with (folder / "seeds.csv").open("a") as f:
        f.write(row + "\n")
    err = refuse(folder, capsys)
    assert err.startswith(f"synptv calibrate: error: {folder / 'seeds.csv'}: ")
    assert re.search(message, err), err


def test_too_few_seeds_a_bad_target_line_and_a_missing_image(tmp_path, capsys):
    folder = copy_example(tmp_path)
    lines = (folder / "seeds.csv").read_text().splitlines()
    (folder / "seeds.csv").write_text("\n".join(lines[:1] + lines[4:]) + "\n")
    assert "camera 'cam1' has 3 seed point(s); each camera needs at least 4" in refuse(
        folder, capsys
    )
    shutil.copy(EXAMPLE / "seeds.csv", folder / "seeds.csv")
    with (folder / "Calibration" / "target_file").open("a") as f:
        f.write("1.0 2.0\n")
    err = refuse(folder, capsys)
    assert f"{folder / 'Calibration' / 'target_file'}: line 438: expected 3, got '1.0 2.0'" in err
    shutil.copy(EXAMPLE / "Calibration" / "target_file", folder / "Calibration" / "target_file")
    (folder / "Calibration" / "cam2.tif").unlink()
    err = refuse(folder, capsys)
    assert (
        f"{folder / 'Calibration' / 'cam2.tif'}: calibration image of camera 'cam2' missing" in err
    )


def test_a_point_target_calibrates_with_the_pinhole_only(tmp_path, capsys):
    folder = copy_example(tmp_path)
    err = refuse(folder, capsys, "--methods", "model-free")
    assert "--methods model-free: " in err and "calibrates with pinhole only" in err


def test_seeds_that_fit_no_camera_name_the_image(tmp_path, capsys):
    folder = copy_example(tmp_path)
    text = (folder / "seeds.csv").read_text()
    # cam2's corner (68, 0, 0) clicked at cam2's (0, 0, 0): no camera fits both.
    (folder / "seeds.csv").write_text(
        text.replace("cam2,68.0,0.0,0.0,1022.0,904.0", "cam2,68.0,0.0,0.0,237.0,912.0")
    )
    err = refuse(folder, capsys)
    assert f"{folder / 'Calibration' / 'cam2.tif'}: the seed points do not fit one camera" in err


def test_a_window_on_the_cameras_wrong_side_names_the_image(tmp_path, capsys):
    folder = copy_example(tmp_path)

    def edit(spec):
        # The wet face 0.5 m below the target, facing away from the cameras above it.
        spec["cameras"]["cam2"]["window"] = {
            "normal": [0, 0, -1],
            "distance": 0.5,
            "thickness": 0.01,
            "glass_index": 1.5,
            "medium_index": 1.33,
        }

    edit_json(folder, edit)
    err = refuse(folder, capsys)
    assert f"{folder / 'Calibration' / 'cam2.tif'}: the camera (centre " in err
    assert "is not outside its window" in err
