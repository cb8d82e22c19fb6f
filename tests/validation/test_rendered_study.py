"""Studies on the rendered chain: every point through images, stages reused between
points, the table against the truth, resumed without recomputing."""

import json
import shutil
from importlib import resources

import pytest
from distributed import LocalCluster

from validation.cli import main
from validation.run.scenario import load_scenario
from validation.studies.study import run_study

TINY = """\
name = "tiny"
seed = 3

[rig]
name = "rig.toml"

[calibration]
planes = 5
methods = ["model-free"]

[particles]
count = 600
frames = 4

[ptv]
methods = ["model-free"]
bins = 8
n_boot = 20
"""


@pytest.fixture(scope="module")
def scenario(tmp_path_factory):
    root = tmp_path_factory.mktemp("rendered-study")
    path = root / "tiny.toml"
    path.write_text(TINY)
    shutil.copyfile(
        resources.files("simulator") / "rig_presets" / "paper-stereo.toml", root / "rig.toml"
    )
    return load_scenario(path)


@pytest.fixture(scope="module")
def planes(scenario, tmp_path_factory):
    """A planes study of two points, on a running scheduler."""
    out = tmp_path_factory.mktemp("out")
    with LocalCluster(
        n_workers=1, threads_per_worker=1, processes=False, dashboard_address=":0"
    ) as cluster:
        files = run_study(
            "planes", scenario, out, values=[2, 5], scheduler=cluster.scheduler_address, quiet=True
        )
    return out, files


def test_every_point_is_measured_against_the_truth(planes):
    out, files = planes
    table = json.loads(files.table.read_text())
    assert table["chain"] == "rendered" and table["study"] == "planes"
    rows = table["points"]
    assert [(r["planes"], r["seed"], r["method"]) for r in rows] == [
        (2, 3, "model-free"),
        (5, 3, "model-free"),
    ]
    for row in rows:
        # The chain works: micrometre calibration, most particles matched, c1 and ε
        # within a few of their bootstrap errors of the truth (four snapshots).
        assert 1 < row["table1_d_um"] < 30 and 1 < row["model_error_um"] < 30
        assert row["yield"] > 0.9 and row["ghosts"] < 0.05
        for n in ("40", "100"):
            assert abs(row["c1_rel_err"][n]) < 4 * row["c1_rel_se"][n] + 0.02
        assert abs(row["epsilon_rel_err"]) < 4 * row["epsilon_rel_se"] + 0.02
    # Two planes calibrate from the ends of the traverse only: not better than five.
    assert rows[0]["model_error_um"] >= 0.95 * rows[1]["model_error_um"]
    assert (out / "planes" / "study.png").stat().st_size > 10_000
    assert files.table.with_name("study.csv").read_text().count("\n") == 3


def test_the_points_share_the_render_and_differ_by_their_calibration(planes):
    out, _ = planes
    work = out / "work" / "seed-3"
    assert sorted(p.name for p in work.iterdir() if not p.name.startswith(".")) == [
        "calibrations",
        "calibrations-planes-02",
        "dataset",
        "detections",
        "ptv",
        "truth",
    ]


def test_a_finished_study_is_read_back_without_computing(planes, scenario):
    out, files = planes
    again = run_study("planes", scenario, out, values=[2, 5], workers=1, quiet=True)
    assert again.computed == () and set(again.reused) == set(files.computed)
    assert again.table.read_text() == files.table.read_text()


def test_a_planes_count_beyond_the_traverse_is_refused_before_any_work(tmp_path, capsys):
    assert main(["study", "planes", "--planes", "3,20", "--out", str(tmp_path)]) == 2
    assert "--planes must be counts from 2 to 13" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())


def test_a_dt_study_reuses_the_render_and_refits_subsets_two_ways(planes, scenario):
    out, _ = planes
    files = run_study("dt", scenario, out, values=[[0, 4], [0, 1, 2, 3, 4]], workers=1, quiet=True)
    rows = json.loads(files.table.read_text())["points"]
    assert [(r["dt_subset"], r["dt_population"]) for r in rows] == [
        ("0-4", "these dt alone"),
        ("0-4", "every dt"),
        ("0-1-2-3-4", "every dt"),
    ]
    # One render for both studies: the work folder holds one dataset.
    assert [p.name for p in (out / "work").iterdir()] == ["seed-3"]
    for row in rows:
        assert abs(row["epsilon_rel_err"]) < 4 * row["epsilon_rel_se"] + 0.02
