"""The ``synptv`` command line.

Errors in the user's input end the command with exit status 2 and a one-line message
on stderr; results go to stdout (``--json`` prints one JSON object).
"""

import argparse
import dataclasses
import json
import logging
import sys
from pathlib import Path

import numpy as np

from ptv.calibration.plate_offsets import MODES as PLATE_OFFSET_MODES
from simulator.presets import FLOW_PRESETS, flow_preset
from simulator.rigs import load_rig, rig_presets
from simulator.spectra import SPECTRA
from simulator.turbulence import NU_WATER, TurbulenceParameters
from validation.export.command import add_export_parser
from validation.run.scenario import SIZE_LIMITS, FlowSection
from validation.score.command import add_score_parser
from validation.studies.cli import add_study_parser
from validation.truth.flow_summary import FlowSettings, summarize_flow
from validation.workflow.files import (
    check_output_folder,
    hold_new_folder,
    hold_output_folder,
    staged_output,
    write_json_atomic,
)
from validation.workflow.progress import ProgressBar, say_interrupted


class UsageError(ValueError):
    """Bad command-line input; reported in one line with exit status 2."""


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line, exit status 2 (see :func:`main`)."""

    def error(self, message: str):
        raise _ParseError(f"{self.prog}: error: {message} (see {self.prog} -h)")


class _ParseError(Exception):
    """A bad command line, already worded for the user."""


def _integer_at_least(minimum: int, maximum: int | None = None, why: str = ""):
    """An argparse type: an integer from ``minimum`` (to ``maximum``), else an error
    naming the option and the limit."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be an integer, got {text!r}") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"must be an integer >= {minimum}, got {value}")
        if maximum is not None and value > maximum:
            raise argparse.ArgumentTypeError(f"must be at most {maximum}{why}, got {value}")
        return value

    return parse


def _size(name: str):
    """An argparse type for the size ``name`` of :data:`SIZE_LIMITS`."""
    return _integer_at_least(*SIZE_LIMITS[name])


SEED = _integer_at_least(0)
COUNT = _integer_at_least(1)


def _flow_parameters(args: argparse.Namespace) -> TurbulenceParameters:
    given = [v is not None for v in (args.u_rms, args.epsilon)]
    if any(given) and not all(given):
        raise UsageError("give both --u-rms and --epsilon, or a --preset")
    if all(given):
        return TurbulenceParameters(u_rms=args.u_rms, epsilon=args.epsilon, nu=args.nu)
    return flow_preset(args.preset).parameters


def _print_flow(summary: dict) -> None:
    p, r, s = summary["prescribed"], summary["realized"], summary["spectrum"]
    print(
        f"spectrum        {s['kind']}, {s['n_modes']} modes, "
        f"k = {s['k_min']:.4g} … {s['k_max']:.4g} 1/m"
    )
    print(
        f"                modes carry {s['modes_energy_over_k_t']:.4f} k_t and "
        f"{s['modes_dissipation_over_epsilon']:.4f} epsilon"
    )
    print(
        f"prescribed      u' = {p['u_rms']:.4g} m/s   epsilon = {p['epsilon']:.4g} m^2/s^3   "
        f"nu = {p['nu']:.3g} m^2/s"
    )
    print(
        f"                eta = {p['eta'] * 1e6:.1f} um   tau_eta = {p['tau_eta'] * 1e3:.3f} ms   "
        f"R_lambda = {p['R_lambda']:.1f}   L_int = u'^3/eps = {p['L_int'] * 100:.2f} cm"
    )
    print(f"realized        u' = {r['u_rms']:.4g} ± {r['u_rms_stderr']:.2g} m/s")
    lo, hi = r["s2_r_range"]
    print(
        f"                sample-truth S2 vs exact D_LL over {lo * 1e3:.2f} … {hi * 1e3:.1f} mm: "
        f"max |rel. error| = {100 * r['s2_max_rel_err']:.2f} % "
        f"(largest standard error {100 * r['s2_max_rel_stderr']:.2f} %)"
    )


def _run_flow(args: argparse.Namespace) -> int:
    settings = FlowSettings(
        parameters=_flow_parameters(args),
        spectrum=args.spectrum,
        particles=args.particles,
        snapshots=args.snapshots,
        n_modes=args.modes,
        unsteadiness=args.unsteadiness,
        seed=args.seed,
    )
    bar = ProgressBar("flow", enabled=not args.quiet)
    summary = summarize_flow(settings, progress=bar)
    if args.json:
        json.dump(summary, sys.stdout, indent=2, allow_nan=False)
        print()
    else:
        _print_flow(summary)
    return 0


#: What ``synptv render`` draws when neither these options nor ``--scenario`` say.
_RENDER_DEFAULTS = {
    "rig": "paper-stereo",
    "preset": "lem-10hz",
    "frames": 10,
    "particles": 1000,
    "planes": 13,
}


def _run_render(args: argparse.Namespace) -> int:
    from validation.dataset.render import RenderSettings, write_dataset
    from validation.workflow.parallel import check_parallel_options, executor

    check_parallel_options(args.workers, args.scheduler)
    out = check_output_folder(args.out)
    given = [f"--{name}" for name in _RENDER_DEFAULTS if getattr(args, name) is not None]
    if args.scenario is not None:
        from validation.run.experiment import render_settings
        from validation.run.scenario import load_scenario

        if given:
            raise UsageError(
                f"--scenario sets the rig, the flow and the sizes: drop {', '.join(given)}"
            )
        scenario = load_scenario(args.scenario)
        if args.seed is not None:
            scenario = scenario.with_seed(args.seed)
        rig, flow = load_rig(scenario.rig.name), scenario.flow
        settings = render_settings(scenario)
    else:
        chosen = {
            name: default if getattr(args, name) is None else getattr(args, name)
            for name, default in _RENDER_DEFAULTS.items()
        }
        rig, flow = load_rig(chosen["rig"]), FlowSection(preset=chosen["preset"])
        settings = RenderSettings(
            frames=chosen["frames"],
            particles=chosen["particles"],
            planes=chosen["planes"],
            seed=0 if args.seed is None else args.seed,
        )
    preset = flow.as_preset()
    print(flow.describe())
    bar = ProgressBar("render", enabled=not args.quiet)
    with hold_new_folder(out, "synptv render") as took_over:
        _say_took_over("render", took_over)
        with executor(workers=args.workers, scheduler=args.scheduler) as ex:
            write_dataset(out, rig, preset, settings, executor=ex, progress=bar)
    print(f"dataset written to {out}")
    return 0


def _say_took_over(command: str, note: str | None) -> None:
    """Print the line of a stale lock taken over, if any."""
    if note:
        print(f"synptv {command}: {note}", file=sys.stderr)


#: The methods ``synptv calibrate`` fits to a plate when --methods is not given.
PLATE_METHODS = "model-free,tsai,pinhole,soloff"


def _run_calibrate(args: argparse.Namespace) -> int:
    from ptv.experiment import has_point_target, read_experiment
    from validation.dataset.calibrate import calibrate_dataset, check_methods
    from validation.report.calibration_figures import plate_offsets_figure
    from validation.report.png import save_figure

    given = PLATE_METHODS if args.methods is None else args.methods
    methods = [m.strip() for m in given.split(",") if m.strip()]
    check_methods(methods)
    dataset = Path(args.dataset)
    if not dataset.is_dir():
        raise UsageError(f"--dataset {dataset}: no such folder")
    out = check_output_folder(args.out if args.out is not None else dataset / "calibrations")
    try:
        point_target = has_point_target(read_experiment(dataset, needs=("calibration",)))
    except FileNotFoundError as err:
        raise UsageError(str(err)) from None
    if point_target:
        if args.plate_offsets is not None:
            raise UsageError(
                f"--plate-offsets: {dataset / 'experiment.json'} gives a target of listed "
                "points, not a plate on a traverse"
            )
        return _calibrate_point_target(args, dataset, out)
    bar = ProgressBar("calibrate", enabled=not args.quiet)
    with hold_output_folder(out, "synptv calibrate") as took_over:
        _say_took_over("calibrate", took_over)
        try:
            result = calibrate_dataset(
                dataset,
                methods=methods,
                out=out,
                plate_offsets=args.plate_offsets,
                progress=bar,
            )
        except FileNotFoundError as err:
            raise UsageError(str(err)) from None
        if result.plate_offsets is not None:
            summary = result.plate_offsets.summary()
            offsets_json = write_json_atomic(out / "plate_offsets.json", summary)
            save_figure(plate_offsets_figure(result.plate_offsets), out / "plate_offsets.png")
    for line in result.warnings:
        print(f"synptv calibrate: warning: {line}", file=sys.stderr)
    if args.json:
        json.dump(
            {
                "table1": result.table1,
                "leave_one_plane_out": result.leave_one_plane_out,
                "files": result.files,
                "max_plane_residual_px": result.max_plane_residual_px,
                "plate_offsets": (
                    None if result.plate_offsets is None else result.plate_offsets.summary()
                ),
                "warnings": result.warnings,
            },
            sys.stdout,
            indent=2,
        )
        print()
        return 0
    print(
        "largest plane-fit residual (model-free T_j^-1), px: "
        + ", ".join(f"{k} {v:.3f}" for k, v in result.max_plane_residual_px.items())
    )
    print(f"{'method':12s} {'reference':9s} {'d_X':>7s} {'d_Y':>7s} {'d_Z':>7s} {'d':>7s}  (um)")
    for method, refs in result.table1.items():
        for ref, t in refs.items():
            print(
                f"{method:12s} {ref:9s} {t['d_X_um']:7.2f} {t['d_Y_um']:7.2f} "
                f"{t['d_Z_um']:7.2f} {t['d_um']:7.2f}"
            )
    for method, held in result.leave_one_plane_out.items():
        planes = ", ".join(f"{d:.1f}" for d in held["planes_d_um"])
        print(f"{method:12s} leave-one-plane-out d {held['d_um']:.2f} um (per plane {planes})")
    if result.plate_offsets is not None:
        _print_plate_offsets(result.plate_offsets, offsets_json)
    for method, path in result.files.items():
        print(f"{method} calibration written to {path}")
    return 0


def _print_plate_offsets(offsets, path: Path) -> None:
    """The self-calibrated plate's figures, one line each."""
    summary = offsets.summary()
    rms, largest = summary["rms_offset_um"], summary["max_abs_offset_um"]
    residual = summary["map_residual_rms_um"]
    print(
        f"plate offsets ({offsets.mode}): dX rms {rms[0]:.1f} um (max {largest[0]:.1f}), "
        f"dY rms {rms[1]:.1f} um (max {largest[1]:.1f}); plane-map residual "
        f"{residual['nominal']:.1f} -> {residual['corrected']:.1f} um; in {path} "
        "and plate_offsets.png"
    )


def _calibrate_point_target(args: argparse.Namespace, dataset: Path, out: Path) -> int:
    """``synptv calibrate`` on a dataset whose target is a 3-D target of listed points."""
    from validation.dataset.calibrate import POINT_TARGET_METHOD, calibrate_point_dataset

    if args.methods is not None and args.methods.strip() != POINT_TARGET_METHOD:
        raise UsageError(
            f"--methods {args.methods}: {dataset / 'experiment.json'} gives a target of "
            f"listed points, imaged once per camera, which calibrates with "
            f"{POINT_TARGET_METHOD} only"
        )
    bar = ProgressBar("calibrate", enabled=not args.quiet)
    with hold_output_folder(out, "synptv calibrate") as took_over:
        _say_took_over("calibrate", took_over)
        try:
            result = calibrate_point_dataset(dataset, out=out, progress=bar)
        except FileNotFoundError as err:
            raise UsageError(str(err)) from None
    summary = result.as_dict()
    if args.json:
        json.dump(summary, sys.stdout, indent=2)
        print()
        return 0
    print(
        f"{'camera':12s} {'points':>6s} {'blobs':>6s} {'seeds':>5s} {'rms (px)':>8s}  "
        "model (f_x, f_y; c_x, c_y px)"
    )
    for name, cam in summary["cameras"].items():
        (fx, fy), (cx, cy) = cam["focal_px"], cam["principal_point_px"]
        print(
            f"{name:12s} {cam['points']:6d} {cam['blobs']:6d} {cam['seeds']:5d} "
            f"{cam['rms_px']:8.3f}  {cam['model']} ({fx:.0f}, {fy:.0f}; {cx:.0f}, {cy:.0f})"
            + (", behind its window" if "window" in cam else "")
        )
    t = summary["target_points"]
    print(
        f"target points seen by two or more cameras, triangulated back: {t['points']}; "
        f"d_X {t['d_X_um']:.1f}, d_Y {t['d_Y_um']:.1f}, d_Z {t['d_Z_um']:.1f}, "
        f"d {t['d_um']:.1f} um"
    )
    for method, path in summary["files"].items():
        print(f"{method} calibration written to {path}")
    return 0


def _run_experiment(args: argparse.Namespace) -> int:
    from validation.report.run_report import write_report
    from validation.run.experiment import run_stages
    from validation.run.scenario import load_scenario
    from validation.run.verdict import summary_lines
    from validation.workflow.parallel import check_parallel_options, executor

    check_parallel_options(args.workers, args.scheduler)
    scenario = load_scenario(args.scenario)
    if args.seed is not None:
        scenario = scenario.with_seed(args.seed)
    out = check_output_folder(args.out if args.out is not None else f"synptv-{scenario.name}")
    print(scenario.flow.describe())

    def bar(stage: str) -> ProgressBar:
        return ProgressBar(stage, enabled=not args.quiet)

    with hold_output_folder(out, "synptv run") as took_over:
        _say_took_over("run", took_over)
        try:
            with executor(workers=args.workers, scheduler=args.scheduler) as ex:
                stages = run_stages(
                    scenario, out, progress=bar, executor=ex, keep_images=args.keep_images
                )
        except KeyboardInterrupt:
            say_interrupted(
                f"synptv run: interrupted; finished stages and chunks are kept in {out}: "
                "run the same command to resume"
            )
            return 130
        html_path, json_path = write_report(scenario, stages, out)
    results = json.loads(json_path.read_text())
    for line in summary_lines(results):
        print(line)
    print(f"report written to {html_path}")
    print(f"every figure in {json_path}")
    return 0 if all(check["passed"] for check in results["must_hold"]) else 1


def _run_mutations(args: argparse.Namespace) -> int:
    from validation.mutations.report import kill_table
    from validation.mutations.runner import run_mutations

    def progress(done) -> None:
        if not args.quiet:
            what = done.name or "control (no mutation)"
            print(
                f"mutations: {what} done in {done.seconds:.0f} s, {len(done.failed)} of "
                f"{len(done.checked)} claims failed",
                file=sys.stderr,
            )

    control, outcomes = run_mutations(
        "full" if args.full else "quick",
        seed=args.seed,
        names=args.mutation or None,
        workers=args.workers,
        progress=progress,
    )
    if control.failed:
        print(f"claims failing without any mutation: {', '.join(control.failed)}", file=sys.stderr)
    if args.json:
        json.dump([o.as_dict() for o in outcomes], sys.stdout, indent=2, allow_nan=False)
        print()
    else:
        for line in kill_table(outcomes):
            print(line)
    return 0 if not control.failed and all(o.ok for o in outcomes) else 1


def _run_claims(args: argparse.Namespace) -> int:
    from validation.claims import ClaimContext, run_claims

    if args.mutations or args.mutation:
        return _run_mutations(args)
    ctx = ClaimContext("full" if args.full else "quick", seed=args.seed)
    bar = ProgressBar("claims", enabled=not args.quiet)
    results = run_claims(ctx, progress=bar)
    if args.json:
        json.dump([r.as_dict() for r in results], sys.stdout, indent=2, allow_nan=False)
        print()
    else:
        for r in results:
            mark = "PASS" if r.passed else "FAIL"
            print(f"{mark}  {r.id:42s} {r.value:10.4g}   {r.tolerance}   [{r.source}]")
        failed = sum(not r.passed for r in results)
        print(f"{len(results) - failed} passed, {failed} failed")
    return 0 if all(r.passed for r in results) else 1


def _ptv_settings(args: argparse.Namespace):
    """The settings file's options (defaults without one), with the command line's
    --max-speed, --snapshots and --min-cameras over them."""
    from ptv.settings import PtvSettings, load_settings

    settings = PtvSettings() if args.settings is None else load_settings(args.settings)
    given = {
        name: getattr(args, name)
        for name in ("max_speed", "snapshots", "min_cameras")
        if getattr(args, name) is not None
    }
    return dataclasses.replace(settings, pipeline=dataclasses.replace(settings.pipeline, **given))


def _run_ptv(args: argparse.Namespace) -> int:
    from ptv.calibration.io import load_calibrations
    from ptv.dataset import open_dataset
    from ptv.frames import ImageDetector
    from ptv.pipeline import run_pipeline
    from ptv.recording import run_recording
    from ptv.results import save_results, save_tracks_csv, summary
    from ptv.settings import settings_toml
    from validation.report.ptv_figures import save_ptv_figures
    from validation.report.track_figure import save_tracks_figure

    if args.print_settings:
        print(settings_toml(_ptv_settings(args)), end="")
        return 0
    missing = [f"--{name}" for name in ("dataset", "calibration", "out") if not getattr(args, name)]
    if missing:
        raise UsageError(f"the following arguments are required: {', '.join(missing)}")
    out = check_output_folder(args.out)
    settings = _ptv_settings(args)
    try:
        dataset = open_dataset(args.dataset)
        calibrations = load_calibrations(args.calibration)
    except FileNotFoundError as err:
        raise UsageError(str(err)) from None
    if args.tracks and dataset.sequence is None:
        raise UsageError(
            f"--tracks needs a time-resolved recording ('time_resolved' in experiment.json, "
            f"docs/experiment.md §5), but {args.dataset} holds frame pairs"
        )
    if settings.pipeline.min_cameras > len(dataset.cameras):
        raise UsageError(
            f"min_cameras is {settings.pipeline.min_cameras} but the dataset has "
            f"{len(dataset.cameras)} cameras"
        )
    bar = ProgressBar("ptv", enabled=not args.quiet)
    run = run_recording if args.tracks else run_pipeline
    tracked = []  # tracks.csv and tracks.png, with --tracks
    with hold_output_folder(out, "synptv ptv") as took_over:
        _say_took_over("ptv", took_over)
        try:
            result = run(
                ImageDetector(dataset, settings.detection),
                calibrations,
                settings.pipeline,
                progress=bar,
                statistics=not args.positions_only,
            )
        except FileNotFoundError as err:
            raise UsageError(str(err)) from None
        with staged_output(out) as staging:  # results and figures replace the old together
            written = list(save_results(result, staging, calibration=str(args.calibration)))
            if not args.positions_only:
                written += save_ptv_figures(result, staging).values()
            if args.tracks:
                tracked = [
                    save_tracks_csv(result, staging),
                    save_tracks_figure(result.recording, staging),
                ]
    h5_path, json_path, *figures = (out / path.name for path in written)
    s = summary(result, calibration=str(args.calibration))
    for line in s["warnings"]:
        print(f"synptv ptv: warning: {line}", file=sys.stderr)
    _print_counts(s)
    if args.tracks:
        csv_path, png_path = (out / path.name for path in tracked)
        _print_tracks(s["tracks"])
        print(f"tracks written to {csv_path} and {h5_path} (/tracks), drawn in {png_path}")
    if args.positions_only:
        print(f"positions and links written to {h5_path} and {json_path}")
        return 0
    _print_statistics(s)
    print(f"results written to {h5_path} and {json_path}")
    print(f"figures written to {', '.join(str(p) for p in figures)}")
    return 0


def _print_tracks(t: dict) -> None:
    """The tracks of a ``synptv ptv --tracks`` summary: counts and lengths."""
    first, last = t["frames"]
    mean = "-" if t["mean_length"] is None else f"{t['mean_length']:.1f}"
    print(
        f"tracks          {t['tracks']} through frames {first} … {last} "
        f"({t['points_per_frame']:.0f} points per frame), mean length {mean} points"
    )
    edges, count = t["length_histogram"]["edges"], t["length_histogram"]["count"]
    bins = [
        f"{lo}: {n}" if hi == lo + 1 else f"{lo}-{hi - 1}: {n}"
        for lo, hi, n in zip(edges[:-1], edges[1:], count, strict=True)
    ]
    print(f"                lengths {', '.join(bins)}")


def _print_counts(s: dict) -> None:
    """The counts per Δt of a ``synptv ptv`` summary."""
    print(
        f"{'dt (ms)':>8s} {'snap':>5s} {'detections':>11s} {'matches':>8s} {'links':>7s} "
        f"{'outliers':>8s} {'used':>6s}"
    )
    for c in s["counts"]:
        det = sum(d["a"] + d["b"] for d in c["detections"].values())
        print(
            f"{c['dt'] * 1e3:8.4f} {c['snapshots_kept']:5d} {det:11d} "
            f"{c['matches']['a'] + c['matches']['b']:8d} {c['links']:7d} "
            f"{c['outliers']:8d} {c['links_used']:6d}"
        )


def _print_statistics(s: dict) -> None:
    """u', the plateau ε, its Δt subsets and the mean displacement of a summary."""
    up = s["u_prime"]
    if up is not None and up["value"] is not None:
        print(f"u' (Eulerian variance fit)        {up['value']:.4g} ± {up['se']:.2g} m/s")
    p = s["epsilon"]["plateau"]
    if p is not None:
        print(
            f"epsilon plateau ({p['r_min'] * 1e3:g}-{p['r_max'] * 1e3:g} mm, C2 = "
            f"{s['epsilon']['kolmogorov_c2']:g}) {p['epsilon']:.4g} ± {p['se_epsilon']:.2g} "
            f"m^2/s^3  (paper's S2^1.5/r: {p['epsilon_paper_caption']:.4g})"
        )
    else:
        print("epsilon plateau                  none (no fitted bin in the plateau range)")
    for name, sub in s["subsets"].items():
        if sub["plateau"] is not None:
            print(
                f"  {name:30s} {sub['plateau']['epsilon']:.4g} ± "
                f"{sub['plateau']['se_epsilon']:.2g} m^2/s^3"
            )
    md = s["mean_displacement"]
    offset = ", ".join(
        f"{o * 1e6:.2f} ± {e * 1e6:.2f}"
        for o, e in zip(md["offset"], md["se_offset_scaled"], strict=True)
    )
    print(f"mean displacement vs dt: offset (X, Y, Z) {offset} um")


def _run_scene(args: argparse.Namespace) -> int:
    from simulator.particles import SHEET
    from simulator.scene import save_scene_png
    from simulator.target import PlateDesign, build_plate, traverse_positions

    rig = load_rig(args.rig)
    plate = build_plate(PlateDesign(), traverse_positions()) if args.plate else None
    particles = SHEET.sample(args.particles, np.random.default_rng(0)) if args.particles else None
    out = save_scene_png(rig, args.out, plate=plate, plate_plane=6, particles=particles)
    print(f"scene picture written to {out}")
    return 0


def _add_parallel_options(parser: argparse.ArgumentParser) -> None:
    """--workers and --scheduler, exclusive."""
    where = parser.add_mutually_exclusive_group()
    where.add_argument(
        "--workers",
        type=int,
        help="local Dask worker processes (default: one per CPU; 1: this process only)",
    )
    where.add_argument(
        "--scheduler", metavar="ADDRESS", help="a running Dask scheduler, e.g. tcp://host:8786"
    )


def _add_run_parser(sub) -> None:
    """The ``synptv run`` subcommand."""
    run = sub.add_parser(
        "run",
        help="a whole virtual experiment: simulate, render, calibrate, PTV, report vs truth",
        description="Run a scenario end to end: simulate the flow and render the plate and "
        "particle images, calibrate with every method, run 3D-PTV with the model-free and "
        "Tsai calibrations (and the true cameras, for the error budget), compare S2, epsilon "
        "and u' with the truth and write report.html and results.json. Finished stages are "
        "reused when their inputs are unchanged. Exit status 1 when a check against the "
        "truth fails.",
    )
    run.add_argument(
        "--scenario",
        default="default",
        help="a preset (default, ci, box-3cam, paper-8hz, paper-10hz, paper-12hz) or a scenario "
        ".toml file",
    )
    run.add_argument("--out", help="output folder (default ./synptv-<scenario>)")
    run.add_argument("--seed", type=SEED, help="override the scenario's seed")
    run.add_argument(
        "--keep-images",
        action="store_true",
        help="also write the particle images (16-bit TIFF) into DIR/dataset",
    )
    _add_parallel_options(run)
    run.add_argument("--quiet", action="store_true", help="no progress bars")
    run.set_defaults(run=_run_experiment)


def _add_flow_parser(sub) -> None:
    """The ``synptv flow`` subcommand."""
    flow = sub.add_parser(
        "flow",
        help="build a KS flow, sample particles, print prescribed and realized statistics",
        description="Build a kinematic-simulation flow from a preset of the paper's Table 3 "
        "(or from --u-rms and --epsilon), sample particles in the analysis volume, and "
        "compare the realized u' and sample-truth S2 with the prescribed values.",
    )
    flow.add_argument("--preset", default="lem-10hz", help=f"one of {', '.join(FLOW_PRESETS)}")
    flow.add_argument("--u-rms", type=float, help="u' in m/s (with --epsilon, instead of a preset)")
    flow.add_argument("--epsilon", type=float, help="dissipation rate in m^2/s^3")
    flow.add_argument("--nu", type=float, default=NU_WATER, help="kinematic viscosity, m^2/s")
    flow.add_argument("--spectrum", default="pope", choices=sorted(SPECTRA))
    flow.add_argument(
        "--particles", type=_size("count"), default=2000, help="particles per snapshot"
    )
    flow.add_argument(
        "--snapshots", type=_size("frames"), default=1000, help="independent realizations"
    )
    flow.add_argument("--modes", type=_size("modes"), default=200, help="KS modes")
    flow.add_argument("--unsteadiness", type=float, default=0.5, help="lambda in omega_n")
    flow.add_argument("--seed", type=SEED, default=0)
    flow.add_argument("--json", action="store_true", help="print one JSON object")
    flow.add_argument("--quiet", action="store_true", help="no progress bar")
    flow.set_defaults(run=_run_flow)


def _add_render_parser(sub) -> None:
    """The ``synptv render`` subcommand."""
    render = sub.add_parser(
        "render",
        help="render a dataset: plate images, particle image pairs per dt, truth",
        description="Simulate the flow, render the calibration plate at every traverse "
        "position and double-frame particle images at every dt for every camera of a rig, "
        "and write them as 16-bit TIFF with experiment.json and truth.h5 (see README).",
    )
    render.add_argument(
        "--scenario",
        help="a scenario preset or .toml file: its rig, flow, sizes, plate, lighting and "
        "sensor (instead of --rig, --preset, --frames, --particles and --planes)",
    )
    render.add_argument(
        "--rig", help=f"{', '.join(rig_presets())} or a .toml file (default paper-stereo)"
    )
    render.add_argument("--preset", help=f"one of {', '.join(FLOW_PRESETS)} (default lem-10hz)")
    render.add_argument("--out", required=True, help="new folder to write")
    render.add_argument("--frames", type=_size("frames"), help="frame pairs per dt (default 10)")
    render.add_argument(
        "--particles", type=_size("count"), help="particles in the sheet (default 1000)"
    )
    render.add_argument(
        "--planes", type=_size("planes"), help="calibration traverse positions (default 13)"
    )
    render.add_argument("--seed", type=SEED, help="default 0, or the scenario's seed")
    _add_parallel_options(render)
    render.add_argument("--quiet", action="store_true", help="no progress bar")
    render.set_defaults(run=_run_render)


def _add_calibrate_parser(sub) -> None:
    """The ``synptv calibrate`` subcommand."""
    cal = sub.add_parser(
        "calibrate",
        help="calibrate a dataset's cameras from its plate images (or dot lists); print the "
        "Table 1 metric",
        description="Find and index the dots on every plate image of a dataset folder (or "
        "read the dot lists its experiment.json names instead), "
        "calibrate each camera with each method, write one calibration file per method "
        "and print the paper's Table 1 metric (against the nominal dot positions, and "
        "against the true centres when the folder holds truth.h5). A dataset whose target "
        "is a 3-D target of listed points (one image per camera) gets one pinhole per "
        "camera (fitted through the camera's glass wall when experiment.json gives its "
        "window), its reprojection RMS and the target points triangulated back.",
    )
    cal.add_argument("--dataset", required=True, help="folder written by synptv render")
    cal.add_argument(
        "--methods",
        help=f"comma-separated: model-free, tsai, pinhole, soloff (default {PLATE_METHODS}; "
        "pinhole only for a point target)",
    )
    cal.add_argument(
        "--out", help="folder for the calibration files (default DATASET/calibrations)"
    )
    cal.add_argument(
        "--plate-offsets",
        choices=PLATE_OFFSET_MODES,
        help="self-calibrate the plate: estimate each column's and row's (or each dot's) "
        "offset from the nominal grid with the calibration, fit every method on the "
        "corrected grid and add Table 1 against it (plate_offsets.json and .png in OUT)",
    )
    cal.add_argument("--json", action="store_true", help="print one JSON object")
    cal.add_argument("--quiet", action="store_true", help="no progress bar")
    cal.set_defaults(run=_run_calibrate)


def _add_claims_parser(sub) -> None:
    """The ``synptv claims`` subcommand."""
    claims = sub.add_parser(
        "claims",
        help="regress the paper's claims against truth; exit status 1 if one fails",
        description="Measure every regressable statement of the paper (docs/claims.md) "
        "against the simulator's truth and compare it with its tolerance.",
    )
    size = claims.add_mutually_exclusive_group()
    size.add_argument(
        "--quick", action="store_true", help="CI size (default, under a minute on 2 cores)"
    )
    size.add_argument("--full", action="store_true", help="the sizes the tolerances assume")
    claims.add_argument("--json", action="store_true", help="print a JSON list of claims")
    claims.add_argument("--seed", type=SEED, default=0)
    claims.add_argument("--quiet", action="store_true", help="no progress bar")
    claims.add_argument(
        "--mutations",
        action="store_true",
        help="break the code one named way at a time (docs/claims.md §5) and report which "
        "claims catch each; exit status 1 if one is not caught as expected",
    )
    claims.add_argument(
        "--mutation",
        action="append",
        metavar="NAME",
        help="run only this mutation (repeatable; implies --mutations)",
    )
    claims.add_argument(
        "--workers", type=COUNT, default=2, help="mutations run at once (default 2)"
    )
    claims.set_defaults(run=_run_claims)


def _add_ptv_parser(sub) -> None:
    """The ``synptv ptv`` subcommand."""
    ptv = sub.add_parser(
        "ptv",
        help="run 3D-PTV on a dataset: particles, links, multi-dt S2, epsilon, u'",
        description="Detect particles in every frame pair of a dataset folder, match them "
        "between cameras with a calibration file, link frame a to frame b, and compute the "
        "noise-free S2(r) by the multi-dt fit, epsilon(r) and its plateau, the dt subsets, "
        "the mean-displacement linearity check and u'. Writes results.h5, summary.json and "
        "the paper's Fig. 5a, 5b, 6a and 6b as PNG. On a time-resolved recording, --tracks "
        "also matches every frame and links the points into tracks: tracks.csv, /tracks in "
        "results.h5, tracks.png.",
    )
    ptv.add_argument("--dataset", help="folder in the synptv render layout (required)")
    ptv.add_argument("--calibration", help="calibration file, synptv calibrate's (required)")
    ptv.add_argument("--out", help="output folder, created if needed (required)")
    ptv.add_argument(
        "--settings",
        help="TOML file of every option: detection, matching, linking, statistics "
        "(--print-settings shows them)",
    )
    ptv.add_argument(
        "--print-settings",
        action="store_true",
        help="print the settings as a TOML file (the defaults, or --settings with the "
        "options below over it) and exit",
    )
    ptv.add_argument(
        "--max-speed", type=float, help="largest particle speed, m/s (link radius; default 1.5)"
    )
    ptv.add_argument("--snapshots", type=COUNT, help="process the first N snapshots per dt")
    ptv.add_argument(
        "--min-cameras",
        type=int,
        help="fewest cameras a match must use (default 2; matches seen by more are preferred)",
    )
    ptv.add_argument(
        "--positions-only",
        action="store_true",
        help="write the matched positions and the links only: no statistics and none of "
        "their figures",
    )
    ptv.add_argument(
        "--tracks",
        action="store_true",
        help="a time-resolved recording only: also match every frame and link the points "
        "frame to frame into tracks (tracks.csv, /tracks in results.h5, tracks.png)",
    )
    ptv.add_argument("--quiet", action="store_true", help="no progress bar")
    ptv.set_defaults(run=_run_ptv)


def _add_scene_parser(sub) -> None:
    """The ``synptv scene`` subcommand."""
    scene = sub.add_parser(
        "scene",
        help="draw a picture of a rig: tank, windows, cameras, laser sheet, plate",
        description="Render an offscreen picture (pyrender, EGL) of a rig: its tank "
        "(icosahedron or box), the part of each window its camera looks through, the "
        "cameras with their names, frusta and refracted corner rays, the laser sheet, the "
        "labelled axes, optionally the calibration plate and particles.",
    )
    scene.add_argument(
        "--rig", default="paper-stereo", help=f"{', '.join(rig_presets())} or a .toml file"
    )
    scene.add_argument("--out", default="scene.png", help="PNG file to write")
    scene.add_argument("--plate", action="store_true", help="draw the calibration plate")
    scene.add_argument(
        "--particles", type=_integer_at_least(0), default=300, help="particles to draw (0: none)"
    )
    scene.set_defaults(run=_run_scene)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``synptv`` and its subcommands."""
    parser = _Parser(prog="synptv", description="A virtual 3D-PTV laboratory.")
    parser.add_argument(
        "-v", "--verbose", action="store_true", help="log the libraries' details and warnings"
    )
    sub = parser.add_subparsers(dest="command", required=True)
    _add_run_parser(sub)
    _add_flow_parser(sub)
    _add_render_parser(sub)
    _add_calibrate_parser(sub)
    add_study_parser(sub)
    _add_claims_parser(sub)
    _add_ptv_parser(sub)
    add_score_parser(sub)
    add_export_parser(sub)
    _add_scene_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``synptv`` console script."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except _ParseError as err:
        print(err, file=sys.stderr)
        return 2
    logging.basicConfig(
        # The libraries' warnings are per snapshot or per chunk; each command sums them
        # up (summary.json, the report, its warning lines), so they show only with -v.
        level=logging.INFO if args.verbose else logging.ERROR,
        format="%(levelname)s %(name)s: %(message)s",
    )
    try:
        return args.run(args)
    except ValueError as err:  # bad input: one line, status 2
        print(f"synptv {args.command}: error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:  # run and study say what they keep and resume
        say_interrupted(f"synptv {args.command}: interrupted")
        return 130


if __name__ == "__main__":
    sys.exit(main())
