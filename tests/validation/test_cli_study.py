"""``synptv study``: sweeps on Dask that save each point, resume, and report bad input."""

import csv
import json

import pytest
from distributed import LocalCluster

from validation.cli import main
from validation.run.scenario import load_scenario
from validation.studies.calibration_methods import relative_to_most_planes
from validation.studies.calibration_sweeps import planes_sweep
from validation.studies.study import run_study


class Stop(Exception):
    """Raised by the test hook to interrupt a study."""


IDEAL = ["--chain", "ideal"]


def test_plane_study_writes_points_table_csv_and_figure(tmp_path, capsys):
    args = ["study", "planes", *IDEAL, "--scenario", "default", "--out", str(tmp_path), "--quiet"]
    assert main([*args, "--workers", "2"]) == 0
    folder = tmp_path / "planes"
    table = json.loads((folder / "study.json").read_text())
    assert table["study"] == "planes" and table["chain"] == "ideal"
    rows = table["points"]
    assert [r["planes"] for r in rows] == [2, 3, 5, 7, 9, 13]
    assert rows[-1]["table1_ratio"] == 1.0 and rows[-1]["model_ratio"] == 1.0
    assert all(r["seed"] == 0 and r["yield"] is None for r in rows)
    # The model error once, under the name the rendered chain gives it too.
    assert all(r["model_error_um"] > 0 and "model_d_um" not in r for r in rows)
    with open(folder / "study.csv") as stream:
        csv_rows = list(csv.DictReader(stream))
    assert [int(r["planes"]) for r in csv_rows] == [2, 3, 5, 7, 9, 13]
    assert (folder / "study.png").stat().st_size > 10_000
    point = json.loads((folder / "points" / "seed-0" / "planes-07.json").read_text())
    assert point["inputs"]["study"] == "planes" and point["inputs"]["scenario"] == "default"
    assert point["inputs"]["settings"] == json.loads(json.dumps(load_scenario("default").as_dict()))
    assert point["inputs"]["point"] == {"planes": 7}
    assert "6 points computed, 0 reused" in capsys.readouterr().out
    assert main(args) == 0  # nothing left to compute: no cluster, same table
    assert "0 points computed, 6 reused" in capsys.readouterr().out
    assert json.loads((folder / "study.json").read_text())["points"] == rows


def test_an_interrupted_study_resumes_without_recomputing_finished_points(tmp_path):
    saved = []

    def stop_after_two(point_id):
        saved.append(point_id)
        if len(saved) == 2:
            raise Stop

    with pytest.raises(Stop):
        run_study(
            "planes",
            "default",
            tmp_path,
            chain="ideal",
            workers=2,
            quiet=True,
            on_saved=stop_after_two,
        )
    points = tmp_path / "planes" / "points" / "seed-0"
    assert sorted(p.stem for p in points.glob("*.json")) == sorted(saved)
    assert not list(points.glob(".*"))  # no temporary file left behind
    stamps = {p: (p.stat().st_mtime_ns, p.read_bytes()) for p in points.glob("*.json")}

    files = run_study("planes", "default", tmp_path, chain="ideal", workers=2, quiet=True)
    reused = {p.removeprefix("seed-0/") for p in files.reused}
    computed = {p.removeprefix("seed-0/") for p in files.computed}
    assert reused == set(saved)
    assert len(computed) == 4 and not computed & set(saved)
    for path, stamp in stamps.items():
        assert (path.stat().st_mtime_ns, path.read_bytes()) == stamp

    # The resumed table is what one uninterrupted run in this process gives.
    sweep = planes_sweep(load_scenario("default"), noise_px=0.05)
    direct = [sweep.task(sweep.settings, sweep.options, p.params)["rows"][0] for p in sweep.points]
    table = json.loads(files.table.read_text())["points"]
    for row, expected in zip(table, relative_to_most_planes(direct), strict=True):
        expected["model_error_um"] = expected.pop("model_d_um")
        assert {k: row[k] for k in expected} == pytest.approx(expected, rel=1e-9)


def test_a_study_runs_on_an_existing_scheduler(tmp_path, capsys):
    with LocalCluster(
        n_workers=1, threads_per_worker=1, processes=False, dashboard_address=":0"
    ) as cluster:
        args = ["study", "planes", *IDEAL, "--scheduler", cluster.scheduler_address]
        assert main([*args, "--out", str(tmp_path), "--quiet"]) == 0
    assert "6 points computed" in capsys.readouterr().out
    assert len(list((tmp_path / "planes" / "points" / "seed-0").glob("*.json"))) == 6


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["nope"], "unknown study 'nope'; known: planes, obliquity, dt, noise, seeding, density"),
        (["dt", "--scenario", "nope"], "unknown scenario 'nope'"),
        (["dt", "--workers", "2", "--scheduler", "tcp://127.0.0.1:1"], "not allowed with"),
        (["dt", "--workers", "0"], "--workers must be an integer >= 1"),
        (["dt", "--chain", "ideal", "--snapshots", "1"], "--snapshots must be >= 2"),
        (["planes", "--chain", "ideal", "--noise", "-1"], "must be >= 0 px"),
        (["planes", "--planes", "1,7"], "--planes must be counts from 2 to 13"),
        (["dt", "--dt-subsets", "0,4;2,7"], "unknown Δt index in [2, 7]"),
        (["dt", "--dt-subsets", "3"], "two or more distinct indices"),
        (["dt", "--planes", "3,5"], "--planes is an option of the planes study"),
        (["planes", "--seeds", "0"], "--seeds must be an integer >= 1"),
        (["noise", "--scheduler", "127.0.0.1"], "host:port"),
        (["density"], "scenario 'default' has no [ipr] table"),
        (["density", "--scenario", "dense-ci", "--ppp", "0.05,0.5"], "--ppp must be densities"),
        (["density", "--scenario", "dense-ci", "--ppp", "a"], "cannot read the values 'a'"),
        (["density", "--scenario", "dense-ci", "--chain", "ideal"], "rendered images only"),
        (["planes", "--ppp", "0.05"], "--ppp is an option of the density study"),
    ],
)
def test_bad_input_is_reported_in_one_line(tmp_path, capsys, extra, message):
    assert main(["study", *extra, "--out", str(tmp_path), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
    assert not list(tmp_path.iterdir())  # nothing written


def test_a_scenario_with_an_unknown_rig(tmp_path, capsys):
    scenario = tmp_path / "odd.toml"
    scenario.write_text('name = "odd"\n[rig]\nname = "nope"\n')
    args = ["study", "planes", "--scenario", str(scenario), "--out", str(tmp_path / "out")]
    assert main([*args, "--quiet"]) == 2
    assert "unknown rig" in capsys.readouterr().err
