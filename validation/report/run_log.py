"""Where a run's time went: ``run_log.json``, the report's table and the terminal's line.

Each stage keeps, in its ``stage.json``, the wall and CPU time its build took
(:mod:`validation.workflow.clock`), so a run that reuses a stage still shows what it
cost. ``results.json`` holds none of it: the same scenario and seed give the same
``results.json`` on any machine, at any speed.
"""

import html
import json
from pathlib import Path

from validation.workflow.clock import StageTime
from validation.workflow.files import write_text_atomic

__all__ = ["run_log", "time_line", "time_section", "write_run_log"]


def run_log(times: dict[str, StageTime]) -> dict:
    """The JSON of ``run_log.json``.

    Parameters
    ----------
    times : dict of str to StageTime
        Every stage's times, in the order they ran (the flow, render, …, each rung).

    Returns
    -------
    dict
        ``stages`` (name → ``wall_s``, ``cpu_s``, ``reused``: a reused stage's times are
        those of its earlier build), ``this_run`` (the sums over the stages built in this
        run, s) and ``reused`` (whether each stage folder was reused; the flow, built in
        memory, is not a folder).
    """
    now = [t for t in times.values() if not t.reused]
    return {
        "stages": {name: t.as_dict() for name, t in times.items()},
        "this_run": {
            "wall_s": round(sum(t.wall_s for t in now), 2),
            "cpu_s": round(sum(t.cpu_s for t in now), 2),
        },
        "reused": {name: t.reused for name, t in times.items() if name != "flow"},
    }


def write_run_log(out: Path, times: dict[str, StageTime]) -> dict:
    """Write :func:`run_log`'s JSON to ``out/run_log.json``; return it."""
    log = run_log(times)
    write_text_atomic(Path(out) / "run_log.json", json.dumps(log, indent=2) + "\n")
    return log


def _duration(seconds: float) -> str:
    """'0.4 s', '41 s', '2.5 min', '1.3 h'."""
    if seconds < 10:
        return f"{seconds:.1f} s"
    if seconds < 120:
        return f"{seconds:.0f} s"
    if seconds < 7200:
        return f"{seconds / 60:.1f} min"
    return f"{seconds / 3600:.1f} h"


def time_line(log: dict) -> str:
    """The terminal's one line, from :func:`run_log`'s JSON: each stage built in this run
    (the PTV and IPR rungs and the tracks summed, with their count), the sums, and the
    stages reused.

    Examples
    --------
    >>> from validation.report.run_log import run_log, time_line
    >>> from validation.workflow.clock import StageTime
    >>> times = {
    ...     "render": StageTime(92.0, 180.0),
    ...     "truth": StageTime(2.3, 2.2, reused=True),
    ...     "calibrate": StageTime(13.4, 13.1),
    ...     "ptv exact": StageTime(2.8, 2.7),
    ...     "ptv model-free": StageTime(9.7, 18.9),
    ... }
    >>> print(time_line(run_log(times)))
    time: render 92 s, calibrate 13 s, ptv 12 s (2 rungs); 118 s wall, 3.6 min CPU; reused: truth
    """
    groups: dict[str, list[float]] = {}
    for name, t in log["stages"].items():
        if not t["reused"]:
            groups.setdefault(name.split(" ")[0], []).append(t["wall_s"])
    parts = [
        f"{group} {_duration(sum(walls))}" + (f" ({len(walls)} rungs)" if len(walls) > 1 else "")
        for group, walls in groups.items()
    ]
    if not parts:
        return "time: every stage reused"
    total = log["this_run"]
    line = f"time: {', '.join(parts)}; {_duration(total['wall_s'])} wall, "
    line += f"{_duration(total['cpu_s'])} CPU"
    reused = [name for name, t in log["stages"].items() if t["reused"]]
    return line + (f"; reused: {', '.join(reused)}" if reused else "")


def time_section(log: dict) -> list[str]:
    """The report's "Where the time went" table, from :func:`run_log`'s JSON."""
    rows = []
    for name, t in log["stages"].items():
        share = t["cpu_s"] / t["wall_s"] if t["wall_s"] > 0 else float("nan")
        when = "reused (built earlier)" if t["reused"] else "this run"
        rows.append(
            f"<tr><td style='text-align:left'>{html.escape(name)}</td>"
            f"<td>{_duration(t['wall_s'])}</td><td>{_duration(t['cpu_s'])}</td>"
            f"<td>{share:.2f}</td><td style='text-align:left'>{when}</td></tr>"
        )
    total = log["this_run"]
    return [
        "<h2>Where the time went</h2>",
        "<p>Wall and CPU time of each stage's build (CPU: this process and its local "
        "workers; CPU/wall near the worker count means the stage kept every worker busy). "
        f"Stages built in this run: {_duration(total['wall_s'])} wall, "
        f"{_duration(total['cpu_s'])} CPU. Also in run_log.json.</p>",
        "<table><tr><th>stage</th><th>wall</th><th>CPU</th><th>CPU / wall</th>"
        f"<th>built</th></tr>{''.join(rows)}</table>",
    ]
