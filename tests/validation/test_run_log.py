"""Where a run's time went: a stage's build times kept in its stage.json and read back
when it is reused, CPU time counted in worker processes too, the log, line and table."""

import doctest
import json
import subprocess
import sys

from validation.report import run_log
from validation.workflow import clock
from validation.workflow.clock import StageTime, Stopwatch
from validation.workflow.stages import STAGE_FILE, run_stage

#: CPU seconds a child process burns: far above the clock's resolution.
BURN_S = 0.5
#: What /proc's CPU times can read short of the child's own clock: its user and system
#: times are each truncated to the kernel's 10 ms tick, and a tick's rounding besides.
SHORT_S = 0.03
BURN = f"import time\nwhile time.process_time() < {BURN_S}:\n    pass\n"


def test_the_examples_run():
    for module in (run_log, clock):
        assert doctest.testmod(module, optionflags=doctest.ELLIPSIS).failed == 0


def test_the_cpu_time_of_a_finished_child_process_is_counted():
    with Stopwatch() as watch:
        subprocess.run([sys.executable, "-c", BURN], check=True)
    assert watch.time.cpu_s >= BURN_S - SHORT_S


def test_the_cpu_time_of_a_live_worker_process_is_counted():
    """A Dask worker outlives the stage: its CPU time is read while it runs."""
    burn_then_wait = BURN + "print('burnt', flush=True)\ninput()\n"
    with Stopwatch() as watch:
        worker = subprocess.Popen(
            [sys.executable, "-c", burn_then_wait],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
        )
        assert worker.stdout.readline() == "burnt\n"
    worker.communicate("\n")
    assert watch.time.cpu_s >= BURN_S - SHORT_S


def test_a_reused_stage_keeps_the_times_of_its_build(tmp_path):
    def build(target):
        target.mkdir()
        subprocess.run([sys.executable, "-c", BURN], check=True)

    folder = tmp_path / "stage"
    built = run_stage(folder, {"n": 1}, build, name="burn")
    reused = run_stage(folder, {"n": 1}, build, name="burn")
    assert not built.reused and not built.time.reused and built.time.cpu_s >= BURN_S - SHORT_S
    assert built.time.wall_s >= 0
    recorded = json.loads((folder / STAGE_FILE).read_text())["built"]
    assert recorded == {"wall_s": round(built.time.wall_s, 2), "cpu_s": round(built.time.cpu_s, 2)}
    assert reused.reused and reused.time == StageTime(
        recorded["wall_s"], recorded["cpu_s"], reused=True
    )


def test_a_stage_built_before_times_were_kept_has_none(tmp_path):
    folder = tmp_path / "stage"
    run_stage(folder, {"n": 1}, lambda target: target.mkdir(), name="old")
    record = json.loads((folder / STAGE_FILE).read_text())
    del record["built"]
    (folder / STAGE_FILE).write_text(json.dumps(record))
    assert run_stage(folder, {"n": 1}, lambda target: target.mkdir(), name="old").time is None


def test_the_log_sums_only_the_stages_built_in_this_run(tmp_path):
    times = {
        "render": StageTime(60.0, 110.0, reused=True),
        "calibrate": StageTime(10.0, 9.5),
        "ptv exact": StageTime(3.0, 2.5),
        "ptv model-free": StageTime(20.0, 38.0),
    }
    log = run_log.write_run_log(tmp_path, times)
    assert json.loads((tmp_path / "run_log.json").read_text()) == log
    assert log["this_run"] == {"wall_s": 33.0, "cpu_s": 50.0}
    assert log["stages"]["render"] == {"wall_s": 60.0, "cpu_s": 110.0, "reused": True}
    assert log["reused"] == {name: name == "render" for name in times}
    assert run_log.time_line(log) == (
        "time: calibrate 10 s, ptv 23 s (2 rungs); 33 s wall, 50 s CPU; reused: render"
    )
    every = {name: StageTime(t.wall_s, t.cpu_s, reused=True) for name, t in times.items()}
    assert run_log.time_line(run_log.run_log(every)) == "time: every stage reused"
    table = "".join(run_log.time_section(log))
    assert table.count("<tr>") == 1 + len(times) and "reused (built earlier)" in table
