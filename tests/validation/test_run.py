"""``synptv run`` end to end on a tiny scenario: the report, stage reuse after an
interruption, reproducibility, and the error budget's noise-free rung against truth."""

import json
import re
import shutil
from importlib import resources

import numba
import pytest

import validation.run.experiment
from validation.cli import main

TINY = """\
name = "tiny"
description = "a tiny end-to-end run"
seed = 3

[rig]
name = "rig.toml"

[calibration]
planes = 3
methods = ["model-free", "tsai"]

[particles]
count = 300
frames = 4

[ptv]
methods = ["model-free", "tsai"]
bins = 8
n_boot = 20
"""

STAGES = [
    "render",
    "detect",
    "truth",
    "calibrate",
    "ptv exact",
    "ptv detection",
    "ptv true-cameras",
]


class Interrupted(Exception):
    """Stands for a KeyboardInterrupt in the first calibration rung."""


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Run A (on a local cluster of two workers) is interrupted in its first calibration
    rung (model-free; the tsai rung after it never starts), then resumed; run B is a
    fresh run of the same scenario named by another path, from another folder, in this
    process on one thread."""
    root = tmp_path_factory.mktemp("run")
    scenario = root / "tiny.toml"
    scenario.write_text(TINY)
    shutil.copyfile(
        resources.files("simulator") / "rig_presets" / "paper-stereo.toml", root / "rig.toml"
    )
    rung = validation.run.experiment.ptv_rung

    def interrupt_for_model_free(store, cameras, *args, **kwargs):
        if type(cameras[0]).__name__ != "Camera":  # a calibration, not the true cameras
            raise Interrupted
        return rung(store, cameras, *args, **kwargs)

    argv = ["run", "--scenario", str(scenario), "--quiet", "--workers", "2", "--out"]
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(validation.run.experiment, "ptv_rung", interrupt_for_model_free)
        with pytest.raises(Interrupted):
            main([*argv, str(root / "a")])
    left_by_interruption = sorted(str(p.relative_to(root / "a")) for p in (root / "a").rglob("*"))
    status_a = main([*argv, str(root / "a")])
    threads = numba.get_num_threads()
    with pytest.MonkeyPatch.context() as patch:
        patch.chdir(root)
        numba.set_num_threads(1)
        try:
            status_b = main(
                ["run", "--scenario", "tiny.toml", "--quiet", "--workers", "1", "--out", "b"]
            )
        finally:
            numba.set_num_threads(threads)
    return root, left_by_interruption, status_a, status_b


def test_an_interrupted_run_leaves_no_partial_output(runs):
    _, left, _, _ = runs
    assert "results.json" not in left and "report.html" not in left
    assert "ptv/model-free" not in left  # the interrupted stage's folder never appeared
    # What remains of it is its temporary folder, kept for the next run to go on from.
    partial = {name.split("/")[1] for name in left if ".partial-" in name}
    assert len(partial) == 1 and partial.pop().startswith(".model-free.partial-")


def test_the_resumed_run_reuses_the_stages_finished_before_the_interruption(runs):
    root, _, _, _ = runs
    reused = json.loads((root / "a" / "run_log.json").read_text())["reused"]
    assert reused == {**dict.fromkeys(STAGES, True), "ptv model-free": False, "ptv tsai": False}
    fresh = json.loads((root / "b" / "run_log.json").read_text())["reused"]
    assert not any(fresh.values())


def test_the_same_scenario_and_seed_give_identical_results(runs):
    root, _, _, _ = runs
    assert (root / "a" / "results.json").read_bytes() == (root / "b" / "results.json").read_bytes()


def test_the_exit_status_says_whether_every_check_passed(runs):
    root, _, status_a, status_b = runs
    checks = json.loads((root / "a" / "results.json").read_text())["must_hold"]
    assert status_a == status_b == (0 if all(c["passed"] for c in checks) else 1)


def test_the_checks_run_on_every_calibration_rung_and_the_first_must_hold(runs):
    root, _, status_a, _ = runs
    results = json.loads((root / "a" / "results.json").read_text())
    rungs = results["checks"]["rungs"]
    assert list(rungs) == ["model-free", "tsai"]
    assert [r["required"] for r in rungs.values()] == [True, False]
    for rung in rungs.values():
        ids = {c["id"] for c in rung["checks"]}
        assert {"matching.yield", "matching.ghost_fraction", "stats.c1_matches_truth"} <= ids
    # The baseline's checks are reported, not required: the exit status ignores them.
    must_hold = [c["id"] for c in results["must_hold"]]
    assert "matching.ghost_fraction (model-free)" in must_hold
    assert not any("(tsai)" in i for i in must_hold)
    assert results["checks"]["passed"] == (status_a == 0)
    page = (root / "a" / "report.html").read_text()
    assert "<th>model-free (method under test: must hold)</th>" in page
    assert "<th>tsai (baseline: reported)</th>" in page


def test_the_report_shows_every_figure_it_names(runs):
    root, _, _, _ = runs
    page = (root / "a" / "report.html").read_text()
    images = re.findall(r'<img src="([^"]+)"', page)
    assert {"calibrations/fig3_error_maps.png", "figures/error_budget.png"} <= set(images)
    assert "ptv/model-free/fig6a_s2.png" in images
    for image in images:
        assert (root / "a" / image).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", image


def test_results_hold_table1_table3_and_the_error_budget(runs):
    root, _, _, _ = runs
    results = json.loads((root / "a" / "results.json").read_text())
    assert set(results["calibration"]["table1"]) == {"model-free", "tsai"}
    assert [row["variant"] for row in results["error_budget"]] == [
        "exact",
        "detection",
        "true-cameras",
        "model-free",
        "tsai",
    ]
    quantities = [row["quantity"] for row in results["table3"]]
    assert quantities[:2] == ["u' (m/s)", "ε (m²/s³)"]
    # The reference column's scales follow from its u' and ε as the input's from theirs:
    # η ∝ ε^(-1/4) at fixed ν, L_int = u'³/ε.
    rows = {row["quantity"]: row for row in results["table3"]}
    u, eps = rows["u' (m/s)"], rows["ε (m²/s³)"]
    eta, l_int = rows["η (µm)"], rows["L_int = u'³/ε (cm)"]
    assert eta["reference"] / eta["input"] == pytest.approx(
        (eps["input"] / eps["reference"]) ** 0.25, rel=1e-9
    )
    assert l_int["reference"] / l_int["input"] == pytest.approx(
        (u["reference"] / u["input"]) ** 3 * eps["input"] / eps["reference"], rel=1e-9
    )


def test_the_report_says_what_the_run_shows_with_its_numbers(runs):
    root, _, _, _ = runs
    results = json.loads((root / "a" / "results.json").read_text())
    page = (root / "a" / "report.html").read_text()
    assert "What this run shows" in page
    d = results["calibration"]["table1"]["model-free"]["nominal"]["d_um"]
    epsilon = results["ptv"]["model-free"]["checks"]["epsilon"]["relative_to_exact_d_ll"]
    assert f"model-free {d:.3g} µm" in page
    assert f"the plateau ε within {100 * epsilon:.3g} %" in page


def test_noise_free_trajectories_give_the_sample_truth_within_their_error(runs):
    """The exact rung sees the sample truth's particle pairs without noise: what remains is
    the finite-Δt term δv·δa Δt, whose mean over the few pairs of a tiny run is not yet
    zero; the bootstrap error covers it (3 standard errors in every bin)."""
    root, _, _, _ = runs
    checks = json.loads((root / "a" / "results.json").read_text())["ptv"]["exact"]["checks"]
    assert checks["c1"]["bins"] >= 3
    assert checks["c1"]["max_deviation_in_se"] <= 3.0
    assert abs(checks["c2"]["median_m2"]) < 1e-12  # no noise: |c2| ≪ (1 µm)²


def test_a_finished_run_can_be_moved_and_reported_again(runs, tmp_path):
    root, _, _, _ = runs
    moved = tmp_path / "moved"
    shutil.copytree(root / "a", moved)
    before = (moved / "results.json").read_bytes()
    scenario = root / "tiny.toml"
    main(["run", "--scenario", str(scenario), "--quiet", "--out", str(moved)])
    reused = json.loads((moved / "run_log.json").read_text())["reused"]
    assert all(reused.values())
    assert (moved / "results.json").read_bytes() == before
