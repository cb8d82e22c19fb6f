"""What ``synptv run`` writes of a recorded scenario: results.json, report.html, the verdict.

The checks that must hold are those of the tracks of the calibration under test (the
scenario's first PTV method); the true cameras' tracks are reported beside them, the
part of the error the calibration does not cause. Thresholds:

- ``tracks.tracked`` ≥ 95 % of the particle-frames that enough cameras image;
- ``tracks.fragmentation`` ≤ 1.1 segments per true trajectory;
- ``tracks.mislinks`` ≤ 0.5 % of the links between two true particles;
- ``tracks.ghost_tracks`` ≤ 1 % of the tracks;
- ``fit.acceleration_floor`` ≤ 1.2: the fitted acceleration's rms error over that of
  the same fit on the true positions plus the measured noise;
- ``lagrangian.acceleration_noise``: the noise-removed ⟨|a|²⟩ within 3 % of the same
  estimator on the true positions of the same points (its deviation from the exact
  value, a property of the flow at the frame rate, is reported beside:
  :mod:`validation.run.lagrangian_scores`);
- ``lagrangian.s2``: the noise-removed S2ᴸ(τ) within 3 % of the exact value at every
  lag of at least half a Kolmogorov time (the largest deviation);

the last two within three of their standard errors where those are larger (a recording
smaller than the tr scenario's).
"""

import html
import json
from pathlib import Path

from validation.report.run_log import time_section, write_run_log
from validation.workflow.clock import this_run_seconds
from validation.workflow.files import write_text_atomic

#: (id, what, key path in scores.json, bound, "max" or "min").
TRACK_CHECKS = (
    ("tracks.tracked", "true particle-frames tracked", ("scores", "tracked"), 0.95, "min"),
    (
        "tracks.fragmentation",
        "segments per true trajectory",
        ("scores", "fragmentation"),
        1.1,
        "max",
    ),
    (
        "tracks.mislinks",
        "links that jump to another particle",
        ("scores", "mislinks"),
        0.005,
        "max",
    ),
    (
        "tracks.ghost_tracks",
        "tracks mostly of ghost points",
        ("scores", "ghost_tracks"),
        0.01,
        "max",
    ),
    (
        "fit.acceleration_floor",
        "fitted acceleration error / its floor",
        ("fit", "floor_ratio"),
        1.2,
        "max",
    ),
)
#: Relative tolerance of the noise-removed Lagrangian statistics against the exact ones.
LAGRANGIAN_TOLERANCE = 0.03


def _get(scores: dict, path: tuple[str, ...]):
    for key in path:
        scores = scores[key]
    return scores


def _check(check_id: str, what: str, value, bound: float, sense: str) -> dict:
    passed = value is not None and (value >= bound if sense == "min" else value <= bound)
    tolerance = f"{'>=' if sense == 'min' else '<='} {bound:g}"
    return {"id": check_id, "what": what, "value": value, "tolerance": tolerance, "passed": passed}


def _relative_check(check_id: str, what: str, deviation: float, se: float) -> dict:
    """|ratio − 1| (``deviation``) within max(3 %, 3 standard errors of the ratio)."""
    bound = max(LAGRANGIAN_TOLERANCE, 3 * se)
    check = _check(check_id, what, abs(deviation), bound, "max")
    check["tolerance"] = f"<= {bound:.3g} (max of 3 % and 3 SE = {3 * se:.3g})"
    return check


def recording_checks(scores: dict) -> list[dict]:
    """The checks of one variant's scores.json (module docstring)."""
    checks = [
        _check(cid, what, _get(scores, path), bound, sense)
        for cid, what, path, bound, sense in TRACK_CHECKS
    ]
    lagrangian = scores["lagrangian"]
    a = lagrangian["acceleration_variance"]
    checks.append(
        _relative_check(
            "lagrangian.acceleration_noise",
            "noise-removed <|a|²> / the estimator's without noise − 1",
            a["ratio"] - 1,
            a["ratio_se"],
        )
    )
    checked = [lag for lag in lagrangian["s2"] if lag["checked"] and lag["ratio"] is not None]
    worst = max(
        checked,
        key=lambda lag: abs(lag["ratio"] - 1) / max(LAGRANGIAN_TOLERANCE, 3 * lag["ratio_se"]),
    )
    checks.append(
        _relative_check(
            "lagrangian.s2",
            f"noise-removed S2L / exact − 1 at τ >= {lagrangian['checked_from_tau_eta']:g} τ_η, "
            f"worst lag ({worst['lag']} frames)",
            worst["ratio"] - 1,
            worst["ratio_se"],
        )
    )
    return checks


def recording_results(scenario, stages) -> dict:
    """results.json of a recorded run."""
    under_test = scenario.ptv.methods[0]
    variants = {
        variant: json.loads((stage.folder / "scores.json").read_text())
        for variant, stage in stages.tracks.items()
    }
    table1 = json.loads((stages.calibrations.folder / "table1.json").read_text())
    must_hold = recording_checks(variants[under_test]) if under_test in variants else []
    if under_test not in variants:
        must_hold.append(
            {
                "id": "calibration",
                "what": f"{under_test} calibrated every camera",
                "value": None,
                "tolerance": "",
                "passed": False,
            }
        )
    return {
        "scenario": scenario.as_dict(),
        "flow": stages.flow,
        "recording": {
            "frame_rate_hz": stages.plan.frame_rate,
            "frames": stages.plan.frames,
            "sequences": stages.plan.sequences,
            "steps": list(stages.plan.steps),
        },
        "seconds": this_run_seconds(stages.times),
        "calibration": table1,
        "method_under_test": under_test,
        "tracks": variants,
        "must_hold": must_hold,
        "checks": {
            variant: recording_checks(scores)
            for variant, scores in variants.items()
            if variant != under_test
        },
    }


def summary_lines(results: dict) -> list[str]:
    """What ``synptv run`` prints: every check of the calibration under test, those of
    the other variants as reported, then the verdict."""

    def line(c: dict) -> str:
        mark = "PASS" if c["passed"] else "FAIL"
        return f"{mark}  {c['id']:36s} {_value(c):>10s}   {c['tolerance']}"

    lines = [line(c) for c in results["must_hold"]]
    for variant, checks in results["checks"].items():
        lines.append(f"{variant} (reported, not required):")
        lines += [line(c) for c in checks]
    failed = [c["id"] for c in results["must_hold"] if not c["passed"]]
    lines.append(
        "verdict: "
        + ("every required check passes" if not failed else f"FAILS {', '.join(failed)}")
    )
    return lines


def _value(check: dict) -> str:
    return "-" if check["value"] is None else f"{check['value']:.4g}"


def _html(results: dict, figures: list[Path], out: Path, timing: list[str]) -> str:
    rows = "".join(
        f"<tr><td>{'PASS' if c['passed'] else 'FAIL'}</td><td>{html.escape(c['id'])}</td>"
        f"<td>{html.escape(c['what'])}</td><td>{_value(c)}</td>"
        f"<td>{html.escape(c['tolerance'])}</td></tr>"
        for c in results["must_hold"]
    )
    images = "".join(
        f"<h3>{html.escape(str(p.relative_to(out)))}</h3>"
        f'<img src="{p.relative_to(out)}" width="900">'
        for p in figures
    )
    name = html.escape(results["scenario"]["name"])
    return (
        f"<!doctype html><html><head><meta charset='utf-8'><title>synptv run {name}</title>"
        f"</head><body><h1>synptv run {name}: a time-resolved recording</h1>"
        f"<p>{html.escape(results['scenario']['description'])}</p>"
        f"<h2>Checks ({html.escape(results['method_under_test'])})</h2>"
        f"<table border='1'><tr><th></th><th>check</th><th>what</th><th>value</th>"
        f"<th>tolerance</th></tr>{rows}</table><h2>Figures</h2>{images}{''.join(timing)}"
        "</body></html>"
    )


def write_recording_report(scenario, stages, out: Path) -> tuple[Path, Path]:
    """Write ``results.json``, ``report.html`` and ``run_log.json``
    (:mod:`validation.report.run_log`) into ``out``.

    Returns
    -------
    (Path, Path)
        The HTML report and the JSON results.
    """
    out = Path(out)
    results = recording_results(scenario, stages)
    json_path, html_path = out / "results.json", out / "report.html"
    write_text_atomic(json_path, json.dumps(results, indent=2, allow_nan=False) + "\n")
    log = write_run_log(out, stages.times)
    figures = sorted(p for stage in stages.tracks.values() for p in stage.folder.glob("*.png"))
    write_text_atomic(html_path, _html(results, figures, out, time_section(log)))
    return html_path, json_path
