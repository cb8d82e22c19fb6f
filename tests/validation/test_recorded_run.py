"""``synptv run`` on a recorded scenario and ``synptv score --tracks`` on its tracks.

One small recording (300 tracers in the paper-stereo sheet, 30 frames at τ_η/10, 5
plate planes) is run end to end once. Its results must hold the scores of every variant
with the checks the report names, its figures must be written, and ``synptv score
--tracks`` must score the tracks a lab's code would hand in: synptv's own tracks.csv
scores as the run scored it, the truth written as a tracks file scores perfectly, and
bad files are refused with one line, exit status 2 and nothing written.
"""

import json

import matplotlib.image
import numpy as np
import pytest

from validation.cli import main
from validation.truth.recording_truth import read_recording_truth

SCENARIO = """name = "tr-tiny"
seed = 2
[flow]
preset = "lem-10hz"
[calibration]
planes = 5
methods = ["model-free"]
[particles]
count = 300
[ptv]
methods = ["model-free"]
n_boot = 20
[recording]
frames = 30
tau_tau_eta = 0.1
steps = [1, 2, 3, 4]
"""


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("recorded")
    scenario = folder / "tr-tiny.toml"
    scenario.write_text(SCENARIO)
    out = folder / "run"
    status = main(["run", "--scenario", str(scenario), "--out", str(out), "--quiet"])
    return out, status


def test_the_run_reports_every_check_and_figure(run):
    out, status = run
    results = json.loads((out / "results.json").read_text())
    ids = [c["id"] for c in results["must_hold"]]
    assert ids == [
        "tracks.tracked",
        "tracks.fragmentation",
        "tracks.mislinks",
        "tracks.ghost_tracks",
        "fit.acceleration_floor",
        "lagrangian.acceleration_noise",
        "lagrangian.s2",
    ]
    assert status == (0 if all(c["passed"] for c in results["must_hold"]) else 1)
    assert set(results["tracks"]) == {"true-cameras", "model-free"}
    for variant in results["tracks"]:
        folder = out / "tracks" / variant
        for name in ("track_lengths.png", "fit_window.png", "lagrangian.png"):
            assert matplotlib.image.imread(folder / name).ndim == 3
        assert (folder / "sequence0" / "tracks.csv").is_file()
    scores = results["tracks"]["model-free"]
    # A sparse recording at τ_η/10 is tracked almost whole (the tr scenario's figures are
    # in docs/run.md §9; these bounds only catch a chain that stopped working).
    assert scores["scores"]["tracked"] > 0.9 and scores["scores"]["fragmentation"] < 1.2
    assert scores["fit"]["floor_ratio"] < 1.5
    assert "report.html" in {p.name for p in out.iterdir()}


def test_score_tracks_scores_synptv_own_tracks_as_the_run_did(run, tmp_path, capsys):
    out, _ = run
    tracks = out / "tracks" / "true-cameras" / "sequence0" / "tracks.csv"
    dataset = out / "dataset" / "sequence0"
    report = tmp_path / "score"
    argv = ["score", "--dataset", str(dataset), "--tracks", str(tracks), "--out", str(report)]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "fragmentation" in printed and "mislinks" in printed
    scored = json.loads((report / "score.json").read_text())
    # Every track, short ones too (the run scores those of 5 points or more).
    assert scored["tracked"] > 0.9 and scored["mislinks"] < 0.01
    assert scored["alignment"]["rotation_deg"] < 0.01  # true cameras: the world frame
    assert matplotlib.image.imread(report / "track_lengths.png").ndim == 3


def write_truth_tracks(path, truth, rows=None):
    rows = np.arange(len(truth.frame)) if rows is None else rows
    table = np.column_stack([truth.particle[rows], truth.frame[rows], truth.position[rows]])
    np.savetxt(
        path,
        table,
        fmt=["%d", "%d", "%.9g", "%.9g", "%.9g"],
        delimiter=",",
        header="track,frame,x,y,z",
        comments="",
    )
    return path


def test_the_truth_as_tracks_scores_perfectly(run, tmp_path):
    out, _ = run
    dataset = out / "dataset" / "sequence0"
    truth = read_recording_truth(dataset)
    observed = np.flatnonzero(truth.imaged_by(2))
    order = observed[np.lexsort((truth.frame[observed], truth.particle[observed]))]
    path = write_truth_tracks(tmp_path / "truth.csv", truth, order)
    report = tmp_path / "score"
    argv = ["score", "--dataset", str(dataset), "--tracks", str(path), "--out", str(report)]
    assert main([*argv, "--json"]) == 0
    scored = json.loads((report / "score.json").read_text())
    # A particle seen in one frame only is a track of one point, which tracks nothing.
    seen = np.bincount(truth.particle[order])
    alone = np.count_nonzero(seen == 1)
    assert scored["tracked"] == pytest.approx(1 - alone / len(order), abs=1e-12)
    assert scored["fragmentation"] == 1.0
    assert scored["mislinks"] == 0.0 and scored["ghost_tracks"] == 0.0
    assert max(scored["errors"]["position_um"].values()) < 1e-3


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda lines: [lines[0], lines[1], *lines[1:]], "given twice"),
        (lambda lines: [lines[0], lines[2], lines[1], *lines[3:]], "increas"),
        (lambda lines: [lines[0], "0,1,nan,0,0", *lines[2:]], "finite"),
        (lambda lines: ["track,frame,x,y", *[",".join(r.split(",")[:4]) for r in lines[1:]]], "z"),
        (lambda lines: [lines[0], "0,999,0,0,0"], "outside the recording's frames"),
    ],
)
def test_bad_tracks_files_are_refused_in_one_line(run, tmp_path, capsys, edit, message):
    out, _ = run
    dataset = out / "dataset" / "sequence0"
    truth = read_recording_truth(dataset)
    order = np.lexsort((truth.frame, truth.particle))[:50]
    good = write_truth_tracks(tmp_path / "good.csv", truth, order).read_text().splitlines()
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join(edit(good)) + "\n")
    report = tmp_path / "score"
    argv = ["score", "--dataset", str(dataset), "--tracks", str(bad), "--out", str(report)]
    assert main(argv) == 2
    error = capsys.readouterr().err.strip()
    assert len(error.splitlines()) == 1 and message in error
    assert not report.exists()


def test_score_tracks_wants_one_recording_and_no_positions(run, tmp_path, capsys):
    out, _ = run
    tracks = out / "tracks" / "true-cameras" / "sequence0" / "tracks.csv"
    report = tmp_path / "score"
    base = ["score", "--tracks", str(tracks), "--out", str(report)]
    assert main([*base, "--dataset", str(out / "dataset")]) == 2
    assert "name one of its recordings" in capsys.readouterr().err
    argv = [*base, "--dataset", str(out / "dataset" / "sequence0"), "--positions", str(tracks)]
    assert main(argv) == 2
    assert "leave out --positions" in capsys.readouterr().err
    assert not report.exists()
