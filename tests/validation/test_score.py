"""``synptv score``: known perturbations of the truth give back their yield, ghosts and
noise; synptv's own matched points give the numbers ``synptv run`` reports; bad input is
a one-line error that writes nothing."""

import csv
import json
import re
import shutil
import subprocess
import sys
from importlib import resources
from pathlib import Path

import h5py
import matplotlib.image
import numpy as np
import pytest

from validation.cli import main

TINY = """\
name = "tiny-score"
description = "a tiny run whose rung scores are compared with synptv score"
seed = 4

[rig]
name = "rig.toml"

[calibration]
planes = 3
methods = ["model-free"]

[particles]
count = 2000
frames = 2

[ptv]
methods = ["model-free"]
bins = 8
n_boot = 20

[output]
images = true
"""

#: synptv run's analysis volume (the scenario default), the test's own copy, m.
BOX = np.array([0.07, 0.07, 0.008])
DROPPED, NOISE, GHOSTS, SWAPPED = 0.10, 10e-6, 0.05, 0.05


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """A tiny ``synptv run`` (2000 tracers, 2 snapshots per Δt, model-free only) that
    keeps its images, for ``synptv ptv``."""
    root = tmp_path_factory.mktemp("score")
    (root / "tiny.toml").write_text(TINY)
    shutil.copyfile(
        resources.files("simulator") / "rig_presets" / "paper-stereo.toml", root / "rig.toml"
    )
    argv = ["run", "--scenario", str(root / "tiny.toml"), "--quiet", "--workers", "1"]
    assert main([*argv, "--out", str(root / "run")]) in (0, 1)
    return root / "run"


def perturbed_truth(truth_path, seed=0):
    """Rows (dt, snapshot, frame, x, y, z, track) of the truth with DROPPED of the
    particles of every frame left out, NOISE Gaussian noise per component and uniform
    ghosts in the analysis volume making GHOSTS of the positions there; in frame b the
    track ids of SWAPPED of the particles are rotated among them (wrong links)."""
    rng = np.random.default_rng(seed)
    rows, ghost_id = [], 10**6
    with h5py.File(truth_path, "r") as f:
        for k in range(len(f["particles"])):
            group = f[f"particles/dt{k}"]
            for m in range(group["positions_a"].shape[0]):
                for frame in "ab":
                    x = group[f"positions_{frame}"][m]
                    keep = rng.permutation(len(x))[: round((1 - DROPPED) * len(x))]
                    track = keep.copy()
                    if frame == "b":
                        swap = rng.choice(len(keep), round(SWAPPED * len(keep)), replace=False)
                        track[swap] = np.roll(track[swap], 1)
                    points = x[keep] + rng.normal(0.0, NOISE, (len(keep), 3))
                    inside = np.all(np.abs(points) <= BOX / 2, axis=1).sum()
                    n_ghosts = round(GHOSTS / (1 - GHOSTS) * inside)
                    ghosts = rng.uniform(-BOX / 2, BOX / 2, (n_ghosts, 3))
                    ids = ghost_id + np.arange(n_ghosts)
                    ghost_id += n_ghosts
                    for p, t in zip(np.concatenate([points, ghosts]), [*track, *ids], strict=True):
                        rows.append((k, m, frame, *p, int(t)))
    order = rng.permutation(len(rows))  # a code writes its rows in its own order
    return [rows[i] for i in order]


def write_csv(path, rows, header=("dt", "snapshot", "frame", "x", "y", "z", "track")):
    with open(path, "w", newline="") as stream:
        writer = csv.writer(stream)
        writer.writerow(header)
        for row in rows:
            writer.writerow([repr(float(v)) if isinstance(v, float) else v for v in row])
    return path


def score(capsys, *argv):
    code = main(["score", *argv, "--json"])
    printed = capsys.readouterr()
    assert code == 0, printed.err
    return json.loads(printed.out)


def test_a_perturbed_truth_scores_as_perturbed(run, tmp_path, capsys):
    rows = perturbed_truth(run / "dataset" / "truth.h5")
    positions = write_csv(tmp_path / "positions.csv", rows)
    out = tmp_path / "report"
    argv = ["--dataset", str(run / "dataset"), "--positions", str(positions), "--tracks"]
    result = score(capsys, *argv, "--out", str(out))
    assert result["yield"] == pytest.approx(1 - DROPPED, abs=0.01)
    assert result["ghost_fraction"] == pytest.approx(GHOSTS, abs=0.01)
    for axis in "xyz":
        assert result["position_rms_um"][axis] == pytest.approx(NOISE * 1e6, abs=1.0)
        assert abs(result["position_mean_um"][axis]) < 1.0
    assert result["n_reference"] > 10_000 and result["n_found"] > 10_000
    assert [e["dt_index"] for e in result["per_dt"]] == [0, 1, 2, 3, 4]
    for entry in result["per_dt"]:
        assert entry["yield"] == pytest.approx(1 - DROPPED, abs=0.02)
        assert entry["ghost_fraction"] == pytest.approx(GHOSTS, abs=0.02)
    tracks = result["tracks"]
    assert tracks["wrong_fraction"] == pytest.approx(SWAPPED, abs=0.01)
    assert tracks["broken_fraction"] == pytest.approx(SWAPPED, abs=0.01)
    assert tracks["correct"] + tracks["wrong"] == tracks["links"]
    statistics = result["statistics"]
    assert statistics["computed"] and statistics["linked_by"] == "tracks"
    assert statistics["c1"]["bins"] > 0 and statistics["epsilon"]["value"] > 0
    assert result["alignment"]["rotation_deg"] < 1e-3
    # as the LPT Challenge scores it, over the whole volume and every exposure
    challenge = result["reconstruction"]
    ghost_rows = sum(row[6] >= 10**6 for row in rows)
    assert challenge["found"] == pytest.approx(1 - DROPPED, abs=0.01)
    assert challenge["ghosts"] == pytest.approx(ghost_rows / len(rows), abs=0.005)
    assert challenge["rms_um"] == pytest.approx(np.sqrt(3) * NOISE * 1e6, rel=0.1)
    assert challenge["points"] == len(rows)
    assert sum(row["particles"] for row in challenge["by_depth"]) == challenge["particles"]
    for row in challenge["by_neighbour"]:  # dropped alike wherever a particle's images lie
        if row["particles"] > 1000:
            assert row["found"] == pytest.approx(1 - DROPPED, abs=0.03)
    assert sorted(p.name for p in out.iterdir()) == ["report.html", "score.json", "score.png"]
    assert json.loads((out / "score.json").read_text()) == result
    assert matplotlib.image.imread(out / "score.png").shape[1] > 800
    assert "Links of the tracks" in (out / "report.html").read_text()


def test_the_same_columns_in_hdf5_score_the_same(run, tmp_path, capsys):
    rows = perturbed_truth(run / "dataset" / "truth.h5", seed=1)[:5000]
    positions = write_csv(tmp_path / "positions.csv", rows)
    with h5py.File(tmp_path / "positions.h5", "w") as f:
        columns = list(zip(*rows, strict=True))
        for name, values in zip(("dt", "snapshot", "frame", "x", "y", "z"), columns, strict=False):
            f[name] = np.array(values, dtype="S1" if name == "frame" else None)
    dataset = ["--dataset", str(run / "dataset")]
    from_csv = score(capsys, *dataset, "--positions", str(positions), "--out", str(tmp_path / "c"))
    h5 = str(tmp_path / "positions.h5")
    from_h5 = score(capsys, *dataset, "--positions", h5, "--out", str(tmp_path / "h"))
    for key in ("yield", "ghost_fraction", "position_rms_um", "n_reference", "n_found", "per_dt"):
        assert from_csv[key] == from_h5[key]


def test_the_old_analysis_volume_option_is_read_as_analysis_size(run, tmp_path, capsys):
    rows = perturbed_truth(run / "dataset" / "truth.h5", seed=2)[:3000]
    positions = str(write_csv(tmp_path / "positions.csv", rows))
    argv = ["--dataset", str(run / "dataset"), "--positions", positions]
    new = score(capsys, *argv, "--analysis-size", "0.05,0.05,0.006", "--out", str(tmp_path / "n"))
    old_name = ("--analysis-volume", "0.05,0.05,0.006", "--out", str(tmp_path / "o"))
    code = main(["score", *argv, *old_name, "--json"])
    printed = capsys.readouterr()
    assert code == 0
    assert printed.err.strip() == (
        "synptv score: --analysis-volume is an old name, read as --analysis-size: write that"
    )
    old = json.loads(printed.out)
    size = [0.05, 0.05, 0.006]
    assert new["settings"]["analysis_size_m"] == old["settings"]["analysis_size_m"] == size
    assert (new["yield"], new["n_reference"]) == (old["yield"], old["n_reference"])
    both = ("--analysis-size", "0.05,0.05,0.006", "--analysis-volume", "0.05,0.05,0.006")
    err = bad(capsys, tmp_path, run, positions, *both)
    assert "--analysis-volume is the old name of --analysis-size" in err


def test_the_example_scores_its_stand_in_as_it_was_made(run, tmp_path):
    """examples/score_your_code.py on this dataset: its stand-in's 5 % missed, 10 µm of
    noise and 2 % swapped tracks come back, within about 4 standard errors (some 3000
    reference particles a Δt, 15 000 links)."""
    example = Path(__file__).parents[2] / "examples" / "score_your_code.py"
    argv = [sys.executable, str(example), "--dataset", str(run / "dataset")]
    printed = subprocess.run([*argv, "--out", str(tmp_path)], capture_output=True, text=True)
    assert printed.returncode == 0, printed.stderr
    *per_dt, links = printed.stdout.splitlines()
    assert len(per_dt) == 5 and (tmp_path / "positions.csv").is_file()
    number = r"(\d+\.\d+)"
    for line in per_dt:
        found = re.search(rf"yield {number}, .* rms x, y, z {number}, {number}, {number} µm", line)
        assert found, line
        assert float(found[1]) == pytest.approx(0.95, abs=0.016)
        assert [float(v) for v in found.groups()[1:]] == pytest.approx([10.0] * 3, abs=0.6)
    wrong = re.search(rf"{number} wrong", links)
    assert wrong and float(wrong[1]) == pytest.approx(0.02, abs=0.005)


def test_synptv_matched_points_score_as_synptv_run_reports(run, tmp_path, capsys):
    """The model-free rung's results.h5 keeps the matched points synptv run scored."""
    rung = run / "ptv" / "model-free"
    result = score(
        capsys,
        "--dataset",
        str(run / "dataset"),
        "--positions",
        str(rung / "results.h5"),
        "--out",
        str(tmp_path / "report"),
    )
    matching = json.loads((rung / "matching.json").read_text())
    assert 0.85 < matching["yield"] < 1 and 0 < matching["ghost_fraction"] < 0.1
    assert result["yield"] == matching["yield"]
    assert result["ghost_fraction"] == matching["ghost_fraction"]
    assert result["sheet"]["yield"] == matching["sheet_yield"]
    assert result["sheet"]["ghost_fraction"] == matching["sheet_ghost_fraction"]
    assert (result["n_reference"], result["n_found"]) == (
        matching["particles"],
        matching["matches"],
    )
    assert result["alignment"]["rotation"] == matching["frame_rotation"]
    assert not result["statistics"]["computed"]  # frame a only: no S2
    assert "both frames a and b" in result["statistics"]["reason"]


def test_synptv_ptv_output_scores_as_synptv_run_reports(run, tmp_path, capsys):
    """``synptv ptv`` with the run's calibration keeps the matched points of every
    frame; those synptv run scores (frame a at Δt_0) give its yield and ghosts."""
    out = tmp_path / "ptv"
    calibration = run / "calibrations" / "model-free.h5"
    # synptv run matches in the laser sheet (and 1 mm), which the CI traverse's 6 mm does
    # not cover, and analyses its 70 × 70 × 8 mm core: the same volumes here.
    settings = tmp_path / "run_volumes.toml"
    settings.write_text(
        "[matching]\nvolume = [[-0.051, -0.051, -0.006], [0.051, 0.051, 0.006]]\n"
        "[statistics]\nanalysis_volume = [[-0.035, -0.035, -0.004], [0.035, 0.035, 0.004]]\n"
    )
    argv = ["ptv", "--dataset", str(run / "dataset"), "--calibration", str(calibration)]
    assert main([*argv, "--settings", str(settings), "--out", str(out), "--quiet"]) == 0
    capsys.readouterr()
    with h5py.File(out / "results.h5") as f:
        g = f["positions"]
        columns = [g[name][()] for name in ("dt", "snapshot", "frame", "x", "y", "z")]
    assert set(columns[0].tolist()) == set(range(5)) and set(columns[2]) == {b"a", b"b"}
    scored = (columns[0] == 0) & (columns[2] == b"a")
    snapshot, x, y, z = (columns[i][scored] for i in (1, 3, 4, 5))
    rows = [(0, int(m), "a", *p) for m, *p in zip(snapshot, x, y, z, strict=True)]
    dataset = ["--dataset", str(run / "dataset")]
    frame_a = write_csv(tmp_path / "frame_a.csv", rows, ("dt", "snapshot", "frame", "x", "y", "z"))
    result = score(capsys, *dataset, "--positions", str(frame_a), "--out", str(tmp_path / "a"))
    matching = json.loads((run / "ptv" / "model-free" / "matching.json").read_text())
    assert (result["yield"], result["ghost_fraction"]) == (
        matching["yield"],
        matching["ghost_fraction"],
    )
    every = score(capsys, *dataset, "--positions", str(out / "results.h5"), "--out", str(out))
    assert len(every["per_dt"]) == 5 and every["statistics"]["computed"]
    assert every["statistics"]["linked_by"] == "synptv's linker"
    assert every["statistics"]["shared_first_frame"]
    assert abs(every["statistics"]["epsilon"]["relative_to_exact_d_ll"]) < 0.15


def bad(capsys, tmp_path, run, positions, *extra, dataset=None):
    """The one-line error of a bad call, after checking that it wrote nothing."""
    out = tmp_path / "never"
    dataset = run / "dataset" if dataset is None else dataset
    argv = ["score", "--dataset", str(dataset), "--positions", str(positions), "--out", str(out)]
    code = main([*argv, *extra])
    err = capsys.readouterr().err
    assert code == 2 and not out.exists()
    assert len(err.strip().splitlines()) == 1 and err.startswith("synptv score: error: ")
    return err


def test_bad_input_is_one_line_naming_the_file_row_and_column(run, tmp_path, capsys):
    rows = perturbed_truth(run / "dataset" / "truth.h5")[:300]
    header = ("dt", "snapshot", "frame", "x", "y", "z", "track")
    in_mm = [(*r[:3], *(1e3 * v for v in r[3:6]), r[6]) for r in rows]
    err = bad(capsys, tmp_path, run, write_csv(tmp_path / "mm.csv", in_mm))
    assert "mm.csv line 2, column x, y, z" in err and "metres" in err
    unknown_dt = [rows[0], (7, *rows[1][1:]), *rows[2:]]
    err = bad(capsys, tmp_path, run, write_csv(tmp_path / "dt.csv", unknown_dt))
    assert "dt.csv line 3, column dt: 7" in err and "5 Δt" in err
    unknown_snapshot = [*rows[:4], (rows[4][0], 2, *rows[4][2:]), *rows[5:]]
    err = bad(capsys, tmp_path, run, write_csv(tmp_path / "m.csv", unknown_snapshot))
    assert "m.csv line 6, column snapshot: 2" in err
    no_z = [r[:5] + r[6:] for r in rows]
    no_z_header = header[:5] + header[6:]
    err = bad(capsys, tmp_path, run, write_csv(tmp_path / "z.csv", no_z, no_z_header))
    assert "z.csv line 1: no column 'z'" in err
    with_nan = [*rows[:9], (*rows[9][:4], float("nan"), *rows[9][5:]), *rows[10:]]
    err = bad(capsys, tmp_path, run, write_csv(tmp_path / "nan.csv", with_nan))
    assert "nan.csv line 11, column y: nan" in err
    err = bad(capsys, tmp_path, run, write_csv(tmp_path / "ok.csv", rows), dataset=tmp_path)
    assert "no truth.h5" in err
    untracked = [r[:6] for r in rows]
    untracked = write_csv(tmp_path / "t.csv", untracked, header[:6])
    err = bad(capsys, tmp_path, run, untracked, "--tracks")
    assert "no column 'track'" in err
    twice = [*rows, rows[0]]
    err = bad(capsys, tmp_path, run, write_csv(tmp_path / "twice.csv", twice), "--tracks")
    assert f"twice.csv line {len(twice) + 1}, column track" in err and "twice" in err
    with h5py.File(tmp_path / "bad.h5", "w") as f:
        for name, values in zip(header[:6], zip(*rows, strict=True), strict=False):
            f[name] = np.array(values, dtype="S1" if name == "frame" else None)
        del f["snapshot"]
        f["snapshot"] = np.zeros(len(rows), dtype=float)
    err = bad(capsys, tmp_path, run, tmp_path / "bad.h5")
    assert "bad.h5: /snapshot: must hold integers" in err
