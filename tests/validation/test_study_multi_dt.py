"""The dt, noise and seeding sweeps: their points, sizes, task rows and figure."""

import math

import pytest

from validation.report.png import save_figure
from validation.run.scenario import load_scenario
from validation.studies.multi_dt import (
    dt_sweep,
    dt_task,
    noise_sweep,
    noise_task,
    seeding_sweep,
    seeding_task,
    spread_indices,
    study_sizes,
)
from validation.studies.multi_dt_figures import multi_dt_figure
from validation.studies.study import _common_row
from validation.workflow.files import as_json

DEFAULT = load_scenario("default")
SETTINGS = DEFAULT.as_dict()
TINY = {"particles": 300, "snapshots": 8}


def test_sizes_follow_the_scenario_with_a_cap():
    assert study_sizes(DEFAULT, None) == (784, 40)  # 2000 in the sheet, 39 % of it analysed
    assert study_sizes(load_scenario("paper-10hz"), None)[1] == 100
    assert study_sizes(DEFAULT, 7) == (784, 7)
    with pytest.raises(ValueError, match="--snapshots must be >= 2"):
        study_sizes(DEFAULT, 1)


def test_sweeps_and_their_points():
    assert spread_indices(5, 2) == [0, 4] and spread_indices(5, 3) == [0, 2, 4]
    assert spread_indices(5, 4) == [0, 1, 3, 4]
    dt = dt_sweep(DEFAULT, snapshots=None, noise_um=15.0)
    assert [p.params["snapshots_per_dt"] for p in dt.points] == [100, 67, 50, 40]
    assert dt.options == {"particles": 784, "noise_um": 15.0, "frame_pairs": 200}
    noise = noise_sweep(DEFAULT, snapshots=10)
    assert [p.id for p in noise.points] == [f"noise-{s}um" for s in (0, 5, 10, 15, 30)]
    seeding = seeding_sweep(DEFAULT, snapshots=None, noise_um=5.0)
    assert [p.params["particles"] for p in seeding.points] == [250, 500, 1000, 2000]
    with pytest.raises(ValueError, match="--position-noise"):
        seeding_sweep(DEFAULT, snapshots=None, noise_um=-1.0)


def test_tasks_give_rows_against_truth_and_curves(tmp_path):
    dt = dt_task(
        SETTINGS,
        {"particles": 300, "noise_um": 15.0, "frame_pairs": 16},
        {"dt_count": 2, "dt_indices": [0, 4], "snapshots_per_dt": 8},
    )
    row = dt["rows"][0]
    assert row["dt_over_tau_eta"] == [0.04, 0.21]
    assert row["c2_over_4sigma2"] == pytest.approx(1.0, abs=0.1)  # c2 = 4σ² (white noise)
    assert abs(row["c1_error_100eta"]) < 5 * row["c1_se_100eta"]
    assert row["raw_over_truth_10eta"] > 2  # claim 6: the raw S2 is far off at small r
    # In study.json each quantity is one column, under the name every chain uses.
    common = _common_row(row, seed=0)
    assert common["c1_rel_err"]["100"] == row["c1_error_100eta"]
    assert common["c1_rel_se"]["100"] == row["c1_se_100eta"]
    assert common["epsilon_rel_err"] == row["epsilon_error"]
    assert not {"c1_error_100eta", "c1_se_100eta", "epsilon_error"} & set(common)
    assert common["raw_over_truth_10eta"] == row["raw_over_truth_10eta"]  # its own, kept

    noise = [noise_task(SETTINGS, TINY, {"noise_um": s}) for s in (0.0, 10.0)]
    rows = [n["rows"][0] for n in noise]
    assert math.isnan(rows[0]["c2_over_4sigma2"])  # no noise: no c2/4σ²
    assert rows[0]["raw_over_truth_40eta"] < rows[1]["raw_over_truth_40eta"]
    assert rows[1]["noise_um"] == 10.0 and rows[1]["snapshots"] == 8

    seeding = seeding_task(SETTINGS, {"snapshots": 8, "noise_um": 15.0}, {"particles": 200})
    assert seeding["rows"][0]["particles"] == 200
    assert set(seeding["curves"]) == {
        "r_m",
        "c1",
        "se_c1",
        "c2_m2",
        "sample_truth",
        "exact_dll",
        "raw_s2_dt_min",
    }

    saved = [as_json(n) for n in noise]  # as read back from the point files (NaN → None)
    eta = DEFAULT.flow.as_preset().parameters.eta
    figure = multi_dt_figure(
        "noise", [s["rows"][0] for s in saved], [s["curves"] for s in saved], eta=eta
    )
    assert save_figure(figure, tmp_path / "noise.png").stat().st_size > 20_000
