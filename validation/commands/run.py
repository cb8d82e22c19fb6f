"""``synptv run``: a scenario end to end, against the truth (docs/run.md)."""

import argparse
import json

from validation.commands.common import SEED, add_parallel_options, say_took_over
from validation.run.scenario import scenario_presets
from validation.workflow.files import check_output_folder, hold_output_folder
from validation.workflow.progress import ProgressBar, say_interrupted


def _held_run(args: argparse.Namespace, out, run, report):
    """``run(progress, executor)`` into ``out`` while holding its lock, then
    ``report(stages)``; what the report returns, or None when interrupted (the finished
    stages kept)."""
    from validation.workflow.parallel import executor

    def bar(stage: str) -> ProgressBar:
        return ProgressBar(stage, enabled=not args.quiet)

    with hold_output_folder(out, "synptv run") as took_over:
        say_took_over("run", took_over)
        try:
            with executor(workers=args.workers, scheduler=args.scheduler) as ex:
                stages = run(bar, ex)
        except KeyboardInterrupt:
            say_interrupted(
                f"synptv run: interrupted; finished stages and chunks are kept in {out}: "
                "run the same command to resume"
            )
            return None
        return report(stages)


def run_experiment(args: argparse.Namespace) -> int:
    """Run the scenario's stages, write the report, print the verdict; exit status 1
    when a check that must hold fails."""
    from validation.report.run_log import time_line
    from validation.run.experiment import run_stages
    from validation.run.run_report import write_report
    from validation.run.scenario import load_scenario
    from validation.run.verdict import summary_lines
    from validation.workflow.parallel import check_parallel_options

    check_parallel_options(args.workers, args.scheduler)
    scenario = load_scenario(args.scenario)
    if args.seed is not None:
        scenario = scenario.with_seed(args.seed)
    out = check_output_folder(args.out if args.out is not None else f"synptv-{scenario.name}")
    print(scenario.flow.describe())
    if scenario.recording is not None:
        return run_recorded(args, scenario, out)
    p = scenario.ptv
    print(
        f"analysis: volume {' x '.join(f'{v * 1e3:.4g}' for v in p.analysis_size)} mm, "
        f"r {p.r_min * 1e3:.3g}-{p.r_max * 1e3:.3g} mm in {p.n_bins} bins, plateau "
        f"{p.plateau[0] * 1e3:.3g}-{p.plateau[1] * 1e3:.3g} mm, matching tolerance "
        + ("measured" if p.tolerance is None else f"{p.tolerance * 1e6:g} µm (given)")
        + ", max_speed "
        + ("measured on the data" if p.max_speed is None else f"{p.max_speed:g} m/s (given)")
    )

    written = _held_run(
        args,
        out,
        lambda bar, ex: run_stages(
            scenario, out, progress=bar, executor=ex, keep_images=args.keep_images
        ),
        lambda stages: write_report(scenario, stages, out),
    )
    if written is None:
        return 130
    html_path, json_path = written
    results = json.loads(json_path.read_text())
    if scenario.flow.kind == "grid":
        f = results["flow"]
        print(
            f"field file: u' = {f['u_rms']:.4g} m/s, R_lambda = {f['R_lambda']:.1f}, eta = "
            f"{f['eta'] * 1e6:.1f} um, box side {f['box_side'] * 1e3:.4g} mm, "
            f"{f['file_snapshots']} snapshots {f['file_step'] * 1e3:.4g} ms apart"
        )
        spacing = (f["snapshot_spacing"] or float("inf")) / f["eddy_time"]
        if spacing < 1:
            print(
                f"warning: the run's {scenario.particles.frames} snapshots are {spacing:.2g} "
                "eddy times T_L apart in the file: they are not independent, so the bootstrap "
                "errors read low and the checks that use them fail more often "
                "(docs/dns.md §12)"
            )
    if scenario.flow.kind == "dns":
        f = results["flow"]
        print(
            f"DNS measured: u' = {f['u_rms']:.4g} m/s, R_lambda = {f['r_lambda_measured']:.1f}, "
            f"eta = {f['eta'] * 1e6:.1f} um, box side {f['box_side'] * 1e3:.4g} mm, "
            f"T_L = {f['eddy_time']:.4g} s, dissipation/injection = "
            f"{f['epsilon_dissipation'] / f['epsilon']:.4f}"
        )
    # The baselines' checks already say what went wrong.
    baselines = set(scenario.ptv.methods[1:])
    if scenario.ipr is not None:  # IPR through the first of [ipr] methods is under test
        baselines = set(scenario.ptv.methods) | set(scenario.ipr.variants()[2:])
    for variant, rung in results["ptv"].items():
        for warning in [] if variant in baselines else rung["summary"]["warnings"]:
            print(f"warning ({variant}): {warning}")
    for line in summary_lines(results):
        print(line)
    print(time_line(json.loads((out / "run_log.json").read_text())))
    print(f"report written to {html_path}")
    print(f"every number in {json_path}")
    return 0 if all(check["passed"] for check in results["must_hold"]) else 1


def run_recorded(args: argparse.Namespace, scenario, out) -> int:
    """``synptv run`` on a scenario with ``[recording]``: render, calibrate, track, fit
    and score the recordings; exit status 1 when a check that must hold fails."""
    from validation.report.recording_report import summary_lines, write_recording_report
    from validation.report.run_log import time_line
    from validation.run.recording_run import run_recording_stages

    r = scenario.recording
    timing = (
        f"{r.frame_rate:g} Hz"
        if r.frame_rate is not None
        else f"a frame every {r.tau_tau_eta:g} τ_η"
    )
    print(
        f"recording: {r.sequences} sequence(s) of {r.frames} frames at {timing}, "
        f"{scenario.particles.count} tracers in the sheet, Δt steps {list(r.steps)} frames"
    )

    written = _held_run(
        args,
        out,
        lambda bar, ex: run_recording_stages(scenario, out, progress=bar, executor=ex),
        lambda stages: write_recording_report(scenario, stages, out),
    )
    if written is None:
        return 130
    html_path, json_path = written
    results = json.loads(json_path.read_text())
    for line in summary_lines(results):
        print(line)
    print(time_line(json.loads((out / "run_log.json").read_text())))
    print(f"report written to {html_path}")
    print(f"every number in {json_path}")
    return 0 if all(check["passed"] for check in results["must_hold"]) else 1


def add_run_parser(sub) -> None:
    """The ``synptv run`` subcommand."""
    run = sub.add_parser(
        "run",
        help="a whole virtual experiment: simulate, render, calibrate, PTV, report vs truth",
        description="Run a scenario end to end: simulate the flow and render the plate and "
        "particle images, calibrate with every method, run 3D-PTV with the model-free and "
        "Tsai calibrations (and the true cameras, for the error budget), compare S2, epsilon "
        "and u' with the truth and write report.html and results.json. A scenario with "
        "[recording] (tr, tr-ci) records the flow time-resolved instead, and tracks, fits and "
        "scores the recording against the true trajectories (docs/run.md §11). Finished "
        "stages are reused when their inputs are unchanged. Exit status 1 when a check "
        "against the truth fails.",
    )
    run.add_argument(
        "--scenario",
        default="default",
        help=f"a preset ({', '.join(scenario_presets())}) or a scenario .toml file",
    )
    run.add_argument("--out", help="output folder (default ./synptv-<scenario>)")
    run.add_argument("--seed", type=SEED, help="override the scenario's seed")
    run.add_argument(
        "--keep-images",
        action="store_true",
        help="also write the particle images (16-bit TIFF) into DIR/dataset",
    )
    add_parallel_options(run)
    run.add_argument("--quiet", action="store_true", help="no progress bars")
    run.set_defaults(run=run_experiment)
