"""The report of ``synptv run``: ``results.json`` and ``report.html`` from the stage folders.

Everything is read from the JSON files the stages wrote, so the report of a finished
run can be rebuilt alone. ``results.json`` holds every number of the report and
nothing that depends on where or when the run happened (no paths, no timings: those go
to ``run_log.json`` and the report's last table, :mod:`validation.report.run_log`), so the
same scenario and seed give the same file.
"""

import html
import json
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

from ptv.calibration.io import load_calibrations
from simulator.rigs import load_rig
from simulator.turbulence import TurbulenceParameters
from validation.report.dns_report import dns_html
from validation.report.html_parts import number, percent, table
from validation.report.ipr_report import FIGURE as IPR_FIGURE
from validation.report.ipr_report import ipr_html, judged_rungs, reconstruction_figure
from validation.report.linking_table import linking_table
from validation.report.png import save_figure
from validation.report.run_figures import budget_figure, noise_figure
from validation.report.run_log import time_section, write_run_log
from validation.report.sheet_region_table import sheet_region_table
from validation.run.checks import error_budget
from validation.run.dns_checks import dns_section
from validation.run.experiment import REFERENCE_VARIANTS, ExperimentStages, run_label
from validation.run.ipr_stage import PREFIX as IPR_PREFIX
from validation.run.rung_comparisons import compare_rungs
from validation.run.scenario import Scenario
from validation.run.verdict import (
    IPR_RULE,
    RULE,
    calibration_check,
    dns_rows,
    failed_rung_checks,
    ipr_rows,
    plateau_row,
    run_checks,
    rung_checks,
    sample_row,
    shown_value,
    verdict,
    verdict_line,
)
from validation.score.tolerances import float_array
from validation.truth.truth_file import TruthFile
from validation.workflow.files import write_text_atomic

#: What each rung of the error budget adds, and the rung it is compared with.
_RUNGS = {
    "exact": ("the multi-Δt method itself (finite Δt)", None),
    "detection": ("detection (sub-pixel centres, missed particles)", "exact"),
    "true-cameras": ("stereo matching and linking", "detection"),
}


def _read(path: Path) -> dict:
    return json.loads(Path(path).read_text())


def _table3(summary: dict, truth: dict) -> list[dict]:
    """Table 3 recovered (u' from the Eulerian fit, ε from the plateau) against the input
    and against the reference: what a perfect measurement recovers (the sample u' and
    the plateau estimator on the exact D_LL), with the scales derived from each pair."""
    p = truth["parameters"]
    up = summary["u_prime"]["value"] if summary["u_prime"] else None
    plateau = summary["epsilon"]["plateau"]
    eps = plateau["epsilon"] if plateau else None
    reference = (truth["u_rms_sample"], truth["epsilon_exact_d_ll"])
    rows = [
        ("u' (m/s)", up, p["u_rms"], reference[0]),
        ("ε (m²/s³)", eps, p["epsilon"], reference[1]),
    ]

    def scales(u_rms, epsilon) -> dict:
        if u_rms is None or epsilon is None:
            return dict.fromkeys(("eta", "tau_eta", "R_lambda", "L_int"))
        return TurbulenceParameters(u_rms=u_rms, epsilon=epsilon, nu=p["nu"]).as_dict()

    rec, ref = scales(up, eps), scales(*reference)
    for label, key, unit in (
        ("η (µm)", "eta", 1e6),
        ("τ_η (ms)", "tau_eta", 1e3),
        ("R_λ", "R_lambda", 1.0),
        ("L_int = u'³/ε (cm)", "L_int", 100.0),
    ):
        rows.append(
            (label, *(None if v is None else v * unit for v in (rec[key], p[key], ref[key])))
        )
    return [{"quantity": q, "recovered": v, "input": t, "reference": r} for q, v, t, r in rows]


def _portable(scenario: Scenario) -> dict:
    """The scenario as a dict that does not depend on where its files lie (a rig file is
    named by its file name and described by its content) nor on what is kept beside the
    results (``[output]``)."""
    spec = scenario.as_dict()
    spec.pop("output")
    rig = load_rig(scenario.rig.name)
    spec["rig"] = {"name": Path(scenario.rig.name).name, "spec": rig.spec}
    return spec


def without_failed(scenario: Scenario, failed: dict) -> Scenario:
    """The scenario as its report shows it: without the baselines whose calibration
    failed (they have no rung; the checks name them and why)."""
    if not failed:
        return scenario
    methods = tuple(m for m in scenario.ptv.methods if m not in failed)
    return replace(scenario, ptv=replace(scenario.ptv, methods=methods))


def build_results(scenario: Scenario, stages: ExperimentStages, out: Path) -> dict:
    """Compare every PTV variant with the truth and write the figures of the report.

    Returns
    -------
    dict
        The content of ``results.json``.
    """
    calibration = _read(stages.calibrations.folder / "table1.json")
    tsai_file = stages.calibrations.folder / "tsai.h5"
    if tsai_file.is_file():
        models = load_calibrations(tsai_file)
        calibration["tsai_reprojection_rms_px"] = {
            camera: float(model.reprojection_rms) for camera, model in models.items()
        }
    failed = calibration.get("failed", {})
    given, scenario = scenario, without_failed(scenario, failed)
    truth = _read(stages.truth.folder / "truth.json")
    detection = _read(stages.ptv["detection"].folder / "detection.json")
    p = truth["parameters"]
    compared = compare_rungs(
        scenario, truth, detection, {v: stage.folder for v, stage in stages.ptv.items()}
    )
    summaries, comparisons = compared.summaries, compared.comparisons
    matching, populations, noise = compared.matching, compared.populations, compared.noise
    check_range, noise_free = compared.check_range, compared.noise_free
    order = [(v, *_RUNGS[v]) for v in REFERENCE_VARIANTS]
    order += [(m, f"calibration ({m})", "true-cameras") for m in scenario.ptv.methods]
    ipr = ipr_rungs(scenario, stages)
    if ipr:
        order.append(("ipr-true-cameras", "IPR in place of detect-and-match", "true-cameras"))
        order += [
            (v, f"IPR, calibration ({v.removeprefix(IPR_PREFIX)})", "ipr-true-cameras")
            for v in ipr.judged
        ]
    main = ipr.judged[0] if ipr.judged else scenario.ptv.methods[0]  # the method under test
    figures = out / "figures"
    figures.mkdir(exist_ok=True)
    r = float_array(truth["r"])
    ratios = {v: float_array(c["c1_over_truth"]) for v, c in comparisons.items()}
    label = run_label(scenario)
    save_figure(budget_figure(r, ratios, check_range, label=label), figures / "error_budget.png")
    if ipr:
        save_figure(reconstruction_figure(ipr.scores, label=label), out / IPR_FIGURE)
    c2 = {
        v: (float_array(sf["noise"]), float_array(sf["se_noise"]))
        for v, s in summaries.items()
        if v != "exact"
        for sf in [s["structure_function"]]
    }
    save_figure(
        noise_figure(
            r,
            c2,
            noise[main],
            check_range,
            noise_free=noise_free[0],
            label=label,
            predicted_for=compared.noise_source[main],
        ),
        figures / "noise.png",
    )
    table1 = calibration["table1"]
    dns = None
    if stages.field is not None:
        dns = dns_section(
            stages.field.folder,
            flow={**p, **stages.flow},
            truth=TruthFile(stages.dataset.folder),
            ptv=scenario.ptv,
            seed=scenario.seed,
        )
    notes = [sample_row(comparisons[main]), plateau_row(scenario.ptv.plateau, p["eta"])]
    rungs = {
        m: failed_rung_checks(failed[m])
        if m in failed
        else rung_checks(comparisons[m], matching[m])
        for m in given.ptv.methods
    }
    rungs |= {
        v: rung_checks(comparisons[v], matching[v]) + ipr_rows(ipr.scores[v]) for v in ipr.judged
    }
    detected = run_checks(
        detection,
        comparisons["detection"],
        calibration_check(table1, load_rig(scenario.rig.name).spec),
    )
    if ipr:  # the method under test reconstructs instead of detecting
        detected = [
            {**row, "informative": IPR_DETECTION_NOTE} if _is_detection(row) else row
            for row in detected
        ]
    checks, must_hold = verdict(
        detected + dns_rows(dns) + [row for row in notes if row is not None],
        rungs,
        (*ipr.judged, *given.ptv.methods),
        {
            **table1,
            **{v: table1[m] for v in ipr.judged if (m := v.removeprefix(IPR_PREFIX)) in table1},
        },
        rule=IPR_RULE if ipr else RULE,
    )
    results = {
        "scenario": _portable(given),
        "flow": {**p, **stages.flow},
        "truth": truth,
        "calibration": calibration,
        "detection": detection,
        "matching": matching,
        "ptv": {
            v: {"summary": summaries[v], "checks": comparisons[v], "population": populations[v]}
            for v in summaries
        },
        "table3": _table3(summaries[main], truth),
        "error_budget": error_budget(comparisons, order),
        "checks": checks,
        "must_hold": must_hold,
    }
    if dns is not None:
        results["dns"] = dns
    if ipr:
        results["reconstruction"] = ipr.scores
    return results


#: Why a run whose method under test is IPR reports its 2-D detection checks only.
IPR_DETECTION_NOTE = (
    "the method under test (IPR) does not detect particles in each image; the 2-D "
    "detection is the detect-and-match baselines'"
)


def _is_detection(row: dict) -> bool:
    """A check of the 2-D detection (its error, its peak locking, its noise term)."""
    return row["id"].startswith("detection.") or row["id"].endswith("(detection)")


@dataclass(frozen=True)
class IprRungs:
    """A run's IPR rungs: ``judged`` (through the calibrations of ``[ipr] methods``, the
    first the method under test) and every IPR rung's ``reconstruction.json``."""

    judged: tuple[str, ...] = ()
    scores: dict = field(default_factory=dict)

    def __bool__(self) -> bool:
        return bool(self.scores)


def ipr_rungs(scenario: Scenario, stages: ExperimentStages) -> IprRungs:
    """The IPR rungs the run built (none without ``[ipr]``)."""
    if scenario.ipr is None:
        return IprRungs()
    built = [v for v in scenario.ipr.variants() if v in stages.ptv]
    scores = {v: _read(stages.ptv[v].folder / "reconstruction.json") for v in built}
    return IprRungs(tuple(v for v in built if v != "ipr-true-cameras"), scores)


def _img(path: str, caption: str) -> str:
    return (
        f'<figure><img src="{html.escape(path)}" alt="{html.escape(caption)}">'
        f"<figcaption>{html.escape(caption)}</figcaption></figure>"
    )


def what_this_run_shows(results: dict, methods: Sequence[str]) -> str:
    """The run's finding in a few sentences, from its numbers: how good each calibration
    is (Table 1), and what it costs downstream (matching, c1, ε), compared between the
    calibration methods the PTV ran with (``methods``, the first the main one)."""
    table1 = results["calibration"]["table1"]
    d = {m: table1[m]["nominal"]["d_um"] for m in methods if m in table1}
    sentences = []
    if d:
        best = min(d, key=d.get)
        sentences.append(
            "Table 1 against the nominal dots: "
            + ", ".join(f"{m} {v:.3g} µm" for m, v in d.items())
            + (
                "."
                if len(d) == 1
                else f": {max(d, key=d.get)} is {max(d.values()) / d[best]:.2g}× {best}."
            )
        )
    for m in methods:
        checks, matching = results["ptv"][m]["checks"], results["matching"][m]
        c1, epsilon = checks["c1"], checks["epsilon"]
        lo, hi = (v * 1e3 for v in c1["r_range_m"])
        sentences.append(
            f"With the {m} calibration, matching finds {percent(matching['yield'])} of the "
            f"particles of the analysis volume with {percent(matching['ghost_fraction'])} "
            f"ghosts; c1 stays within {percent(c1['max_abs_deviation'])} of the sample "
            f"truth over {lo:.3g}–{hi:.3g} mm (mean {percent(c1['mean_deviation'])}) and "
            f"the plateau ε within {percent(epsilon['relative_to_exact_d_ll'])} of the "
            "estimator on the exact D_LL."
        )
    steps = [b for b in results["error_budget"] if b.get("c1_added") is not None]
    if steps:
        largest = max(steps, key=lambda b: abs(b["c1_added"]))
        sentences.append(
            f"Along the error budget, the largest step in c1 comes from "
            f"{largest['adds']}: {100 * largest['c1_added']:+.2g} % on its mean deviation."
        )
    return " ".join(sentences)


def _verdict_cell(check: dict | None) -> str:
    """A check's table cell: PASS or FAIL and its value (– where there is no such check)."""
    if check is None:
        return "<td>–</td>"
    mark, css = ("PASS", "pass") if check["passed"] else ("FAIL", "fail")
    return f'<td class="{css}">{mark} {html.escape(shown_value(check))}</td>'


def _rungtable(checks: dict) -> str:
    """The checks of every calibration rung: a row per check, a column per rung."""
    rungs = checks["rungs"]
    by_id = {m: {c["id"]: c for c in rung["checks"]} for m, rung in rungs.items()}
    ids = list(dict.fromkeys(i for checks_of in by_id.values() for i in checks_of))
    head = ["check", "tolerance"] + [
        f"{m} ({rung['role']}: {'must hold' if rung['required'] else 'reported'})"
        for m, rung in rungs.items()
    ]
    rows = [
        "<tr><td>calibration: Table 1 d, nominal dots (µm)</td><td>reported</td>"
        + "".join(f"<td>{number(rung['table1_d_um'], 3)}</td>" for rung in rungs.values())
        + "</tr>"
    ]
    for i in ids:
        tolerance = next(by_id[m][i]["tolerance"] for m in rungs if i in by_id[m])
        rows.append(
            f"<tr><td>{html.escape(i)}</td><td>{html.escape(tolerance)}</td>"
            + "".join(_verdict_cell(by_id[m].get(i)) for m in rungs)
            + "</tr>"
        )
    header = "".join(f"<th>{html.escape(h)}</th>" for h in head)
    return f"<table><tr>{header}</tr>{''.join(rows)}</table>"


def _checks_section(results: dict, scenario: Scenario) -> list[str]:
    """The verdict; the checks of the run; those of every calibration rung, a column
    per rung (:mod:`validation.run.verdict`)."""
    checks = results["checks"]
    css = "pass" if checks["passed"] else "fail"
    parts = ["<h2>Checks against truth</h2>"]
    parts.append(f'<p class="{css}">Verdict: {html.escape(verdict_line(checks))}.</p>')
    parts.append(f"<p>{html.escape(checks['rule'])}</p>")
    parts.append("<h3>The run</h3>")
    rows = [
        f"<tr><td>{html.escape(c['id'])}</td><td>{html.escape(c['tolerance'])}</td>"
        f"{_verdict_cell(c)}</tr>"
        for c in checks["run"]
    ]
    header = "".join(f"<th>{h}</th>" for h in ("check", "tolerance", "verdict"))
    parts.append(f"<table><tr>{header}</tr>{''.join(rows)}</table>")
    parts.append("<h3>Every calibration rung</h3>")
    parts.append(_rungtable(checks))
    return parts


def _findings_section(results: dict, scenario: Scenario) -> list[str]:
    """The finding of the run in words ("what this run shows")."""
    parts = ["<h2>What this run shows</h2>"]
    parts.append(f"<p>{html.escape(what_this_run_shows(results, scenario.ptv.methods))}</p>")
    return parts


def _flow_section(results: dict, scenario: Scenario) -> list[str]:
    """The flow, its kind and its scales (a DNS's or a file's box side beside them)."""
    kinds = {"ks": "kinematic simulation", "dns": "Navier–Stokes DNS", "grid": "field file"}
    parts = [f"<h2>Flow: {kinds[scenario.flow.kind]}, {html.escape(scenario.flow.label)}</h2>"]
    p = results["flow"]
    if "box_side" in p:
        parts.append(
            f"<p>Periodic box of side {number(p['box_side'] * 1e3)} mm; u′ and R_λ below are "
            "measured on the field.</p>"
        )
    parts.append(
        table(
            ["u' (m/s)", "ε (m²/s³)", "ν (m²/s)", "η (µm)", "τ_η (ms)", "R_λ", "L_int (cm)"],
            [
                (
                    number(p["u_rms"]),
                    number(p["epsilon"]),
                    number(p["nu"]),
                    number(p["eta"] * 1e6),
                    number(p["tau_eta"] * 1e3),
                    number(p["R_lambda"]),
                    number(p["L_int"] * 100),
                )
            ],
        )
    )
    return parts


def _calibration_section(results: dict, scenario: Scenario) -> list[str]:
    """Table 1 of every method and the Fig. 3 error maps."""
    parts = ["<h2>Calibration (Table 1, Fig. 3)</h2>"]
    rows = []
    for method, refs in results["calibration"]["table1"].items():
        for ref, t in refs.items():
            rows.append(
                (method, ref, *(number(t[k], 3) for k in ("d_X_um", "d_Y_um", "d_Z_um", "d_um")))
            )
    parts.append(table(["method", "against", "d_X (µm)", "d_Y (µm)", "d_Z (µm)", "d (µm)"], rows))
    for method, failure in results["calibration"].get("failed", {}).items():
        parts.append(
            f"<p><span class='fail'>FAIL</span> {html.escape(method)} (a baseline) could not "
            f"calibrate camera {html.escape(failure['camera'])}: "
            f"{html.escape(failure['reason'])}. The run went on without it.</p>"
        )
    parts.append(
        "<p>“nominal”: the paper's metric (dots at their design positions); “true”: against "
        "the dots' true centres (the plate's imperfections removed). The difference is "
        "mostly in Z: the plate's tilt and the traverse errors, which no calibration built "
        "on the nominal positions can know; they make the calibration frame differ from "
        "the world by a rigid motion (the frame rotation below).</p>"
    )
    parts += _tsai_note(results, scenario)
    parts.append(_img("calibrations/fig3_error_maps.png", "Fig. 3: error maps"))
    return parts


def _tsai_note(results: dict, scenario: Scenario) -> list[str]:
    """Why Tsai falls short on a rig of Scheimpflug cameras: its sensor is square to the
    optical axis (empty when Tsai was not fitted or no camera is tilted)."""
    rms = results["calibration"].get("tsai_reprojection_rms_px")
    tilted = [c["name"] for c in load_rig(scenario.rig.name).spec["cameras"] if c["scheimpflug"]]
    if not rms or not tilted:
        return []
    per_camera = ", ".join(f"{html.escape(c)} {rms[c]:.3g} px" for c in tilted if c in rms)
    return [
        "<p>Tsai's model is a pinhole with one radial distortion term and a sensor square to "
        "the optical axis. The Scheimpflug cameras of this rig (their sensors tilted to bring "
        "the sheet into focus) and the refraction at the windows are outside it: its "
        f"reprojection RMS on the calibration dots is {per_camera}, against a few hundredths "
        "of a pixel of dot detection. That is the model error the model-free calibration "
        "removes, not a failed fit.</p>"
    ]


def _detection_section(results: dict, scenario: Scenario) -> list[str]:
    """Detection errors, peak locking and matching quality."""
    parts = ["<h2>Detection and matching</h2>"]
    d = results["detection"]
    rows = [
        (
            cam,
            number(d["rms_error_px"][i][0], 3),
            number(d["rms_error_px"][i][1], 3),
            number(d["found"][i], 4),
            number(d["spurious"][i], 3),
        )
        for i, cam in enumerate(d["cameras"])
    ]
    parts.append(table(["camera", "rms x (px)", "rms y (px)", "found", "spurious"], rows))
    noise = ", ".join(f"{v * 1e6:.2f}" for v in d["position_noise_m"])
    parts.append(
        f"<p>Position noise (X, Y, Z) with the true cameras, particles in the analysis "
        f"volume: {noise} µm.</p>"
    )
    parts.append(_img("ptv/detection/peak_locking.png", "Peak-locking diagnostic"))
    rows = [
        (
            v,
            number(m["yield"], 4),
            number(m["ghost_fraction"], 3),
            m["particles"],
            number(m["sheet_yield"], 4),
            number(m["sheet_ghost_fraction"], 3),
            number(m["frame_rotation_deg"], 3),
        )
        for v, m in results["matching"].items()
    ]
    header = ["cameras", "yield", "ghost fraction", "particles"]
    header += ["yield (sheet)", "ghosts (sheet)", "frame rotation (°)"]
    parts.append(table(header, rows))
    parts.append(
        "<p>Matching scored on frame a of the first snapshots: matched points and true "
        "particles are paired one-to-one within one voxel, and a paired point is a hit "
        "(synptv score scores any code's positions the same way). Yield, ghosts and "
        "particles count the analysis volume; “sheet” the whole lit sheet, whose dim wings "
        "lose more particles to detection.</p>"
    )
    return parts + sheet_region_table(results)


def _under_test(results: dict, scenario: Scenario) -> str:
    """The rung of the method under test: IPR through its first calibration where the
    scenario has ``[ipr]``, else the PTV stack through the first ``[ptv]`` method."""
    return (*judged_rungs(results), scenario.ptv.methods[0])[0]


def _statistics_section(results: dict, scenario: Scenario) -> list[str]:
    """The particles each S2 used, and Figs. 5 and 6 of every PTV run."""
    parts = ["<h2>Statistics (Fig. 5, Fig. 6)</h2>"]
    rows = []
    for variant, entry in results["ptv"].items():
        pop, counted = entry["summary"]["population"], entry["population"]
        if pop is not None:
            associated = "–" if counted is None else counted["associated"]
            counts = (pop["snapshots"], pop["particles"], pop["trajectory_outliers"])
            rows.append((variant, *counts, associated))
    if rows:
        header = ["measurement", "snapshots", "particles in S2", "trajectory outliers"]
        parts.append(table([*header, "with a true particle"], rows))
        parts.append(
            "<p>S2 uses the particles linked at every Δt (frame a is shared) that pass the "
            "trajectory test; c1 is compared with the sample truth of those particles' "
            "pairs (the true particle within one voxel of each), so a particle a "
            "measurement misses does not count as its error.</p>"
        )
    parts += linking_table(results)
    judged = judged_rungs(results)
    for variant in (*judged, *scenario.ptv.methods):
        how = "IPR" if variant in judged else "PTV"
        method = variant.removeprefix(IPR_PREFIX)
        parts.append(f"<h3>{how} with the {html.escape(method)} calibration</h3>")
        for fig, caption in (
            ("fig5a_raw_s2.png", "Fig. 5a: raw S2 per Δt"),
            ("fig5b_q_vs_dt2.png", "Fig. 5b: ⟨q⟩ against Δt² and the fits"),
            ("fig6a_s2.png", "Fig. 6a: noise-free S2 with the sample truth"),
            ("fig6b_epsilon.png", "Fig. 6b: ε(r), reference: the estimator on the exact D_LL"),
        ):
            parts.append(_img(f"ptv/{variant}/{fig}", caption))
    return parts


def _table3_section(results: dict, scenario: Scenario) -> list[str]:
    """Table 3: the recovered flow against the input and the reference."""
    main = _under_test(results, scenario)
    parts = ["<h2>Table 3: recovered against truth</h2>"]
    rows = [
        (t["quantity"], number(t["recovered"]), number(t["input"]), number(t["reference"]))
        for t in results["table3"]
    ]
    parts.append(
        table(
            [
                "quantity",
                f"recovered ({main})",
                "input",
                "reference: sample u', estimator on the exact D_LL",
            ],
            rows,
        )
    )
    e = results["ptv"][main]["checks"]["epsilon"]
    parts.append(
        f"<p>The plateau estimator on the exact D_LL gives {number(e['estimator_on_exact_d_ll'])} "
        f"m²/s³, {number(100 * e['plateau_deficit_of_estimator'], 3)} % from the input ε: the "
        "finite-Reynolds plateau deficit of the spectrum, not a measurement error. The "
        "recovered row is to be read against the reference column, whose scales follow "
        "from the same estimator; the input column differs from both by that deficit "
        "(η ∝ ε^(−1/4), R_λ ∝ ε^(−1/2), L_int ∝ 1/ε).</p>"
    )
    return parts


def _budget_section(results: dict, scenario: Scenario) -> list[str]:
    """The error budget: what each source of error adds to c1 and ε."""
    parts = ["<h2>Error budget</h2>"]
    rows = [
        (
            b["variant"],
            b["adds"],
            number(None if b["c1_mean_deviation"] is None else 100 * b["c1_mean_deviation"], 3),
            number(None if b.get("c1_added") is None else 100 * b["c1_added"], 3),
            number(None if b["epsilon_relative"] is None else 100 * b["epsilon_relative"], 3),
            number(None if b.get("epsilon_added") is None else 100 * b["epsilon_added"], 3),
        )
        for b in results["error_budget"]
    ]
    parts.append(
        table(
            [
                "rung",
                "adds",
                "c1 − truth (%)",
                "added (%)",
                "ε − estimator on D_LL (%)",
                "added (%)",
            ],
            rows,
        )
    )
    parts.append(
        "<p>c1 − truth: mean relative deviation from the sample-truth S2 over the check "
        "range; each rung adds one source of error to the one before it (calibrations are "
        "compared with the true cameras).</p>"
    )
    parts.append(_img("figures/error_budget.png", "c1 / sample truth for every rung"))
    return parts


def _noise_section(results: dict, scenario: Scenario) -> list[str]:
    """The noise term c2 against the noise measured against the truth."""
    main = _under_test(results, scenario)
    parts = ["<h2>Noise</h2>"]
    c = results["ptv"][main]["checks"]
    ratio_detection = results["ptv"]["detection"]["checks"]["c2"].get("median_over_prediction")
    ratio_main = c["c2"].get("median_over_prediction")
    parts.append(
        "<p>The noise term c2, less the c2 the same fit gives on the exact positions (the "
        "flow's own terms beyond Δt², which the intercept takes up), against the c2 "
        "predicted from the displacement noise, measured against the truth, of the "
        "particles each S2 used (median ratio over "
        f"the check range): truth-paired detections {number(ratio_detection, 3)}, "
        f"the {html.escape(main)} run {number(ratio_main, 3)} "
        "(its ghosts and mislinks add noise that no true particle can be blamed for). "
        "Part of the detection error is common to frames a and b (mostly an unresolved "
        "neighbour's light), so the measured noise grows with Δt: the band spans the "
        "intercepts that allows. The part growing as Δt² goes into c1: at most "
        f"{number(100 * c['c1'].get('noise_part_max', float('nan')), 2)} % of S2 in the "
        "check range.</p>"
    )
    parts.append(_img("figures/noise.png", "c2 against the noise measured against truth"))
    return parts


#: The report's sections, in page order.
_SECTIONS = (
    _checks_section,
    _findings_section,
    _flow_section,
    _calibration_section,
    _detection_section,
    lambda results, scenario: ipr_html(results.get("reconstruction", {})),
    _statistics_section,
    _table3_section,
    _budget_section,
    _noise_section,
    dns_html,
)


def render_html(results: dict, scenario: Scenario, log: dict | None = None) -> str:
    """The report page (figures referenced by relative paths under the run folder), with
    where the time went when ``log`` (:func:`validation.report.run_log.run_log`) is given."""
    parts = [
        "<!doctype html><html><head><meta charset='utf-8'>",
        f"<title>synptv run: {html.escape(scenario.name)}</title>",
        "<style>body{font-family:sans-serif;max-width:1100px;margin:2em auto;}"
        "table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #bbb;"
        "padding:3px 8px;text-align:right}th{background:#eee}img{max-width:100%}"
        ".fail{color:#b00;font-weight:bold}.pass{color:#070}</style></head><body>",
        f"<h1>Virtual experiment “{html.escape(scenario.name)}”</h1>",
        f"<p>{html.escape(scenario.description)} (seed {scenario.seed}).</p>",
    ]
    for section in _SECTIONS:
        parts += section(results, scenario)
    parts += [] if log is None else time_section(log)
    parts.append("</body></html>")
    return "\n".join(parts)


def write_report(scenario: Scenario, stages: ExperimentStages, out: Path) -> tuple[Path, Path]:
    """Write ``results.json``, ``report.html`` and ``run_log.json``
    (:mod:`validation.report.run_log`) into ``out``.

    Returns
    -------
    (Path, Path)
        The HTML report and the JSON results.
    """
    out = Path(out)
    results = build_results(scenario, stages, out)
    json_path, html_path = out / "results.json", out / "report.html"
    write_text_atomic(json_path, json.dumps(results, indent=2, allow_nan=False) + "\n")
    log = write_run_log(out, stages.times)
    failed = results["calibration"].get("failed", {})
    write_text_atomic(html_path, render_html(results, without_failed(scenario, failed), log))
    return html_path, json_path
