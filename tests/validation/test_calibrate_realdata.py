"""synptv calibrate on real plate images (examples/openptv-multiplane, four planes), and
on OpenPTV's own sorted dot lists of the same plates instead of the images."""

import json
from pathlib import Path

import pytest

from validation.cli import main
from validation.dataset.calibrate import calibrate_dataset

EXAMPLE = Path(__file__).parents[2] / "examples" / "openptv-multiplane"


@pytest.fixture(scope="module")
def from_images(tmp_path_factory):
    """The model-free calibration of the plate images."""
    out = tmp_path_factory.mktemp("cal")
    return calibrate_dataset(EXAMPLE, methods=("model-free",), out=out)


def test_four_planes_give_a_leave_one_plane_out_error_above_the_in_sample_one(from_images):
    in_sample = from_images.table1["model-free"]["nominal"]
    held_out = from_images.leave_one_plane_out["model-free"]
    assert in_sample["coverage"] == 1.0
    assert len(held_out["planes_d_um"]) == 4
    # A plane left out is extrapolated (the outer two) or interpolated from the others:
    # never closer than the fit that saw it.
    assert held_out["d_um"] > in_sample["d_um"]


def test_plane_fits_that_miss_a_dot_by_more_than_2_px_are_warned_of(from_images):
    # Binary dots: ~0.3 px of quantisation per axis leaves a cubic plane fit within about
    # 1.5 px over 405 dots; cam3 and cam4 miss one dot by 5.8 and 6.6 px.
    residual = from_images.max_plane_residual_px
    above = sorted(name for name, px in residual.items() if px > 2.0)
    assert {"cam3", "cam4"} <= set(above)
    assert sorted(w.split(":")[0] for w in from_images.warnings) == above
    assert all("the cubic plane fit of cam" in w for w in from_images.warnings)
    for name, rows in from_images.per_image.items():
        assert [row["image"] for row in rows] == [f"{name}_plane{j}.tiff" for j in range(4)]
        assert all(row["dots"] == 405 for row in rows)


def test_plate_self_calibration_adds_the_corrected_grid(tmp_path, capsys):
    out = tmp_path / "cal"  # from OpenPTV's dot lists: the same dots, no image to read
    argv = ["calibrate", "--dataset", str(EXAMPLE / "openptv"), "--methods", "model-free"]
    assert main([*argv, "--plate-offsets", "rows-columns", "--out", str(out), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    table1 = report["table1"]["model-free"]
    assert set(table1) == {"nominal", "corrected"}
    offsets = report["plate_offsets"]
    assert offsets == json.loads((out / "plate_offsets.json").read_text())
    assert len(offsets["columns"]["i"]) == 27 and len(offsets["rows"]["j"]) == 15
    # The corrected grid is what the maps were fitted on: they reach it at least as well.
    residual = offsets["map_residual_rms_um"]
    assert residual["corrected"] <= residual["nominal"]
    assert (out / "plate_offsets.png").stat().st_size > 0


def test_openptvs_dot_lists_calibrate_as_the_images_do(from_images, tmp_path, capsys):
    # examples/openptv-multiplane/openptv/experiment.json names OpenPTV's .crd/.fix files
    # of the four planes: the same dots at the same pixels (less OpenPTV's half pixel),
    # so the same calibration and the same errors, without reading an image.
    argv = ["calibrate", "--dataset", str(EXAMPLE / "openptv"), "--methods", "model-free"]
    assert main([*argv, "--out", str(tmp_path / "cal"), "--json", "--quiet"]) == 0
    report = json.loads(capsys.readouterr().out)
    listed = report["table1"]["model-free"]["nominal"]
    assert listed == pytest.approx(from_images.table1["model-free"]["nominal"], rel=1e-9)
    # Binary, undistorted images: ~0.3 px of quantisation per axis, some 0.2 mm in 3-D.
    assert 100 < listed["d_um"] < 300 and listed["coverage"] == 1.0
    assert report["leave_one_plane_out"]["model-free"]["d_um"] == pytest.approx(
        from_images.leave_one_plane_out["model-free"]["d_um"], rel=1e-9
    )
