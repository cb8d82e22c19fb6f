"""``synptv ptv``: results, summary and figures from a dataset folder; bad input."""

import json

import h5py
import matplotlib.image
import pytest

from ptv.calibration.io import load_calibrations, save_calibrations
from simulator.presets import flow_preset
from simulator.rigs import load_rig
from validation.cli import main
from validation.dataset.calibrate import calibrate_dataset
from validation.dataset.render import RenderSettings, write_dataset
from validation.report.ptv_figures import FIGURE_FILES

SETTINGS = RenderSettings(frames=2, planes=3, particles=600, n_modes=80, seed=5)


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    folder = tmp_path_factory.mktemp("cli-ptv") / "ds"
    write_dataset(folder, load_rig("paper-stereo"), flow_preset("lem-10hz"), SETTINGS)
    cal = calibrate_dataset(folder, methods=("model-free",))
    return folder, cal.files["model-free"]


def test_ptv_command_writes_results_summary_and_figures(dataset, tmp_path, capsys):
    folder, calibration = dataset
    out = tmp_path / "out"
    argv = ["ptv", "--dataset", str(folder), "--calibration", str(calibration)]
    code = main([*argv, "--out", str(out), "--max-speed", "1.2", "--quiet"])
    printed = capsys.readouterr()
    assert code == 0, printed.err
    assert "epsilon plateau" in printed.out and "u' (Eulerian variance fit)" in printed.out
    assert printed.err == ""  # --quiet: no progress bar
    names = {p.name for p in out.iterdir()}
    assert names == {"results.h5", "summary.json", *FIGURE_FILES.values()}
    for name in FIGURE_FILES.values():
        image = matplotlib.image.imread(out / name)
        assert image.ndim == 3 and image.shape[0] > 300 and image.shape[1] > 400
    summary = json.loads((out / "summary.json").read_text())
    assert summary["settings"]["max_speed"] == 1.2
    assert summary["dataset"] == str(folder) and summary["calibration"] == str(calibration)
    assert [c["snapshots_kept"] for c in summary["counts"]] == [2] * 5
    assert summary["epsilon"]["plateau"]["epsilon"] > 0
    assert summary["counts"][4]["link_radius"] == pytest.approx(1.2 * 5.093e-4 + 1.5e-4, rel=1e-3)
    with h5py.File(out / "results.h5") as f:
        assert f["statistics/s2"].shape == (24,)
        assert f["particles/dt0/offsets"].shape == (3,)


def test_ptv_command_processes_the_first_snapshots_only(dataset, tmp_path, capsys):
    folder, calibration = dataset
    out = tmp_path / "one"
    argv = ["ptv", "--dataset", str(folder), "--calibration", str(calibration)]
    assert main([*argv, "--out", str(out), "--snapshots", "1", "--quiet"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert [c["snapshots_processed"] for c in summary["counts"]] == [1] * 5
    assert summary["errors"] == "pairs"  # one snapshot per Δt: no bootstrap
    capsys.readouterr()


def test_a_settings_file_sets_every_stage_and_the_command_line_overrides_it(
    dataset, tmp_path, capsys
):
    folder, calibration = dataset
    settings = tmp_path / "settings.toml"
    settings.write_text(
        "[detection]\nthreshold_sigmas = 7.0\n[matching]\ntolerance = 2.0e-4\n"
        "[linking]\nmax_speed = 1.2\n[statistics]\nn_bins = 12\n[run]\nsnapshots = 1\n"
    )
    argv = ["ptv", "--dataset", str(folder), "--calibration", str(calibration), "--quiet"]
    out = tmp_path / "set"
    assert main([*argv, "--settings", str(settings), "--max-speed", "1.3", "--out", str(out)]) == 0
    used = json.loads((out / "summary.json").read_text())["settings"]
    assert used["threshold_sigmas"] == 7.0 and used["tolerance"] == 2.0e-4
    assert used["n_bins"] == 12 and used["snapshots"] == 1
    assert used["max_speed"] == 1.3  # the command line over the file
    capsys.readouterr()
    assert main(["ptv", "--settings", str(settings), "--print-settings"]) == 0
    printed = capsys.readouterr().out
    assert "threshold_sigmas = 7.0" in printed and "n_bins = 12" in printed


def test_ptv_command_reports_bad_input_in_one_line(dataset, tmp_path, capsys):
    folder, calibration = dataset
    out = str(tmp_path / "bad")
    code = main(
        ["ptv", "--dataset", str(tmp_path / "nowhere"), "--calibration", "x.h5", "--out", out]
    )
    err = capsys.readouterr().err
    assert (
        code == 2
        and err.startswith("synptv ptv: error: dataset folder")
        and "does not exist" in err
    )
    calibrations = load_calibrations(calibration)
    other = save_calibrations(
        tmp_path / "other.h5", {"cam1": calibrations["cam1"], "left": calibrations["cam2"]}
    )
    argv = ["ptv", "--dataset", str(folder), "--calibration", str(other), "--out", out, "--quiet"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "cameras don't match the calibration" in err and len(err.strip().splitlines()) == 1
    argv = ["ptv", "--dataset", str(folder), "--calibration", str(calibration), "--out", out]
    assert main([*argv, "--max-speed", "-1", "--quiet"]) == 2
    assert "max_speed must be a finite number > 0" in capsys.readouterr().err
    assert main([*argv, "--min-cameras", "3", "--quiet"]) == 2
    assert "min_cameras is 3 but the dataset has 2 cameras" in capsys.readouterr().err
    assert main([*argv, "--min-cameras", "1", "--quiet"]) == 2
    assert "min_cameras must be an integer >= 2" in capsys.readouterr().err
    assert not (tmp_path / "bad").exists()


def test_a_failure_after_the_pipeline_leaves_the_earlier_output_untouched(
    dataset, tmp_path, capsys, monkeypatch
):
    import validation.report.ptv_figures

    folder, calibration = dataset
    out = tmp_path / "out"
    argv = ["ptv", "--dataset", str(folder), "--calibration", str(calibration)]
    argv += ["--out", str(out), "--snapshots", "1", "--quiet"]
    assert main(argv) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}

    def fails(result, folder):
        raise ValueError("a figure cannot be drawn")

    monkeypatch.setattr(validation.report.ptv_figures, "save_ptv_figures", fails)
    assert main([*argv, "--max-speed", "1.2"]) == 2  # results that differ, if written
    assert "a figure cannot be drawn" in capsys.readouterr().err
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before  # no lock, no staging


def test_a_folder_held_by_another_command_is_refused_before_the_pipeline(dataset, tmp_path, capsys):
    from validation.workflow.files import hold_output_folder

    folder, calibration = dataset
    out = tmp_path / "out"
    argv = ["ptv", "--dataset", str(folder), "--calibration", str(calibration)]
    with hold_output_folder(out, "synptv ptv"):
        assert main([*argv, "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "is in use by synptv ptv" in err and err.count("\n") == 1


def test_positions_only_writes_the_points_and_links_without_statistics(dataset, tmp_path, capsys):
    folder, calibration = dataset
    out = tmp_path / "positions"
    argv = ["ptv", "--dataset", str(folder), "--calibration", str(calibration), "--quiet"]
    assert main([*argv, "--positions-only", "--out", str(out)]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["results.h5", "summary.json"]
    with h5py.File(out / "results.h5") as f:
        assert "statistics" not in f
        assert len(f["positions/x"]) > 0 and len(f["particles/dt0/positions"]) > 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["statistics_dt"] is None and "epsilon" not in summary
    assert "positions and links written to" in capsys.readouterr().out
