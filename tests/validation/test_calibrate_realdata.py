"""synptv calibrate on real plate images (examples/openptv-multiplane, four planes)."""

import json
from pathlib import Path

from validation.cli import main

EXAMPLE = Path(__file__).parents[2] / "examples" / "openptv-multiplane"


def test_four_planes_give_a_leave_one_plane_out_error_above_the_in_sample_one(tmp_path, capsys):
    argv = ["calibrate", "--dataset", str(EXAMPLE), "--methods", "model-free", "--json"]
    assert main([*argv, "--out", str(tmp_path / "cal"), "--quiet"]) == 0
    report = json.loads(capsys.readouterr().out)
    in_sample = report["table1"]["model-free"]["nominal"]
    held_out = report["leave_one_plane_out"]["model-free"]
    assert in_sample["coverage"] == 1.0 and report["warnings"] == []
    assert len(held_out["planes_d_um"]) == 4
    # A plane left out is extrapolated (the outer two) or interpolated from the others:
    # never closer than the fit that saw it.
    assert held_out["d_um"] > in_sample["d_um"]


def test_plate_self_calibration_adds_the_corrected_grid(tmp_path, capsys):
    out = tmp_path / "cal"
    argv = ["calibrate", "--dataset", str(EXAMPLE), "--methods", "model-free", "--json"]
    assert main([*argv, "--plate-offsets", "rows-columns", "--out", str(out), "--quiet"]) == 0
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
