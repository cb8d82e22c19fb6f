"""``synptv run --scenario paper-10hz`` as a user runs it: where the time goes, the
peak memory and the disk it takes.

The command runs in a new process (its default workers, one per CPU) into a temporary
folder. Its process tree's resident memory is sampled every half second (the sum over
the run and its Dask workers); its own ``run_log.json`` gives the wall and CPU seconds
of each stage and rung (:mod:`validation.report.run_log`). ``--quick`` runs the ``ci``
scenario instead, which shows the shape, not the targets.

Targets (issue #53): the paper's size in ≤ 10 min on the 2-core machine, peak memory
≤ 2.7 GiB, ≤ 2 GB on disk; every required check passing.
"""

import json
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import psutil

from benchmarks.machine import machine

TARGET_S = 600.0
TARGET_PEAK_GIB = 2.7
TARGET_DISK_GB = 2.0
#: Seconds between two samples of the process tree's memory.
SAMPLE_S = 0.5


def _tree_rss(process: psutil.Process) -> int:
    """Resident bytes of ``process`` and its descendants (0 for those that ended)."""
    total = 0
    for p in (process, *process.children(recursive=True)):
        try:
            total += p.memory_info().rss
        except (psutil.NoSuchProcess, psutil.AccessDenied):
            pass
    return total


def _peak_rss(pid: int, stop: threading.Event, peak: list) -> None:
    """Sample the tree of ``pid`` until ``stop``; its largest resident size in ``peak[0]``."""
    try:
        process = psutil.Process(pid)
    except psutil.NoSuchProcess:
        return
    while not stop.wait(SAMPLE_S):
        try:
            peak[0] = max(peak[0], _tree_rss(process))
        except psutil.NoSuchProcess:
            return


def _disk_bytes(folder: Path) -> int:
    """Bytes of the files under ``folder``, each hard-linked file counted once."""
    sizes = {p.stat().st_ino: p.stat().st_size for p in folder.rglob("*") if p.is_file()}
    return sum(sizes.values())


def run(quick: bool) -> dict:
    """Run the scenario end to end; its stage times, peak memory, disk and checks."""
    scenario = "ci" if quick else "paper-10hz"
    with tempfile.TemporaryDirectory(prefix="synptv-bench-paper-") as folder:
        out = Path(folder) / scenario
        command = [sys.executable, "-m", "validation.cli", "run", "--scenario", scenario]
        stop, peak = threading.Event(), [0]
        start = time.perf_counter()
        process = subprocess.Popen(
            [*command, "--out", str(out), "--quiet"], stdout=subprocess.PIPE, text=True
        )
        sampler = threading.Thread(target=_peak_rss, args=(process.pid, stop, peak))
        sampler.start()
        printed, _ = process.communicate()
        seconds = time.perf_counter() - start
        stop.set()
        sampler.join()
        log = json.loads((out / "run_log.json").read_text())
        checks = json.loads((out / "results.json").read_text())["must_hold"]
        disk = _disk_bytes(out)
    time_line = next((line for line in printed.splitlines() if line.startswith("time:")), None)
    peak_gib, disk_gb = peak[0] / 2**30, disk / 1e9
    meets = seconds <= TARGET_S and peak_gib <= TARGET_PEAK_GIB and disk_gb <= TARGET_DISK_GB
    return {
        "machine": machine(),
        "scenario": scenario,
        "exit_status": process.returncode,
        "seconds_total": round(seconds, 1),
        "time_line": time_line,
        "stages": log["stages"],
        "this_run": log["this_run"],
        "peak_rss_gib": round(peak_gib, 2),
        "disk_gb": round(disk_gb, 2),
        "checks_passed": sum(c["passed"] for c in checks),
        "checks": len(checks),
        "targets": {"seconds": TARGET_S, "peak_gib": TARGET_PEAK_GIB, "disk_gb": TARGET_DISK_GB},
        "meets_targets": None if quick else meets,
    }
