"""``synptv study``: parameter sweeps of a scenario (docs/study.md); the sweeps themselves
are :mod:`validation.studies`."""

import sys
from pathlib import Path

from validation.commands.common import add_parallel_options
from validation.run.scenario import scenario_presets
from validation.studies.multi_dt import DEFAULT_NOISE_UM
from validation.studies.study import STUDIES, StudySettings, run_study
from validation.workflow.files import check_output_folder, hold_output_folder
from validation.workflow.progress import say_interrupted


def _values(text: str | None, study: str) -> list | None:
    """--planes "3,5,7,13", --dt-subsets "0,1,2,3,4;2,3,4;0,4" or --ppp "0.01,0.05" as a
    list."""
    if text is None:
        return None
    try:
        if study == "planes":
            return [int(v) for v in text.split(",")]
        if study == "density":
            return [float(v) for v in text.split(",")]
        return [[int(v) for v in part.split(",")] for part in text.split(";")]
    except ValueError:
        raise ValueError(
            f"cannot read the values {text!r}: numbers separated by , (and ;)"
        ) from None


def run_study_command(args) -> int:
    """``synptv study`` (docs/study.md)."""
    settings = StudySettings(
        dot_noise_px=args.noise, position_noise_um=args.position_noise, snapshots=args.snapshots
    )
    given = {"planes": args.planes, "dt": args.dt_subsets, "density": args.ppp}
    extra = [name for name, v in given.items() if v is not None and name != args.study]
    if extra:
        option = {"planes": "--planes", "dt": "--dt-subsets", "density": "--ppp"}[extra[0]]
        raise ValueError(f"{option} is an option of the {extra[0]} study, not of {args.study}")
    check_output_folder(args.out)
    try:
        with hold_output_folder(args.out, f"synptv study {args.study}") as took_over:
            if took_over:
                print(f"synptv study: {took_over}", file=sys.stderr)
            files = run_study(
                args.study,
                args.scenario,
                Path(args.out),
                chain=args.chain,
                seeds=args.seeds,
                values=_values(given.get(args.study), args.study),
                settings=settings,
                workers=args.workers,
                scheduler=args.scheduler,
                quiet=args.quiet,
            )
    except KeyboardInterrupt:
        say_interrupted(
            f"synptv study: interrupted; finished points are saved under "
            f"{Path(args.out) / args.study / 'points'}: run the same command to resume"
        )
        return 130
    print(
        f"{len(files.computed)} points computed, {len(files.reused)} reused; table written to "
        f"{files.table} and {files.csv}, figure to {files.figure}"
    )
    return 0


def add_study_parser(subparsers) -> None:
    """Add the ``study`` subcommand to the ``synptv`` parser's subparsers."""
    about = "; ".join(f"{name}: {s.about}" for name, s in STUDIES.items())
    study = subparsers.add_parser(
        "study",
        help="parameter sweeps (planes, obliquity, dt, noise, seeding): table + figure",
        description="Sweep one parameter of a scenario, on rendered images (--chain "
        "rendered, default: every point renders or reuses images, detects, calibrates, "
        "matches and compares with the truth) or on the fast stand-in without images "
        f"(--chain ideal: {about}). Each point is saved as it finishes (run again to "
        "resume); --seeds K repeats every point with independent seeds.",
    )
    study.add_argument("study", metavar="STUDY", help=f"one of {', '.join(STUDIES)}")
    study.add_argument(
        "--scenario",
        default="default",
        help=f"{', '.join(scenario_presets())} or a .toml file (rig, flow, sizes, seed)",
    )
    add_parallel_options(study)
    study.add_argument("--out", default="synptv-study", help="output folder")
    study.add_argument(
        "--chain",
        choices=("rendered", "ideal"),
        help="through images (default) or the fast stand-in without images (the dt "
        "study of a DNS scenario runs on its trajectories: ideal)",
    )
    study.add_argument(
        "--seeds", type=int, default=1, help="independent seeds per point (error bars)"
    )
    study.add_argument(
        "--planes", help="plane counts of the planes study, e.g. 3,5,7,13 (rendered chain)"
    )
    study.add_argument(
        "--dt-subsets",
        help="Δt index subsets of the dt study, e.g. '0,1,2,3,4;2,3,4;0,4' (rendered chain)",
    )
    study.add_argument(
        "--ppp",
        help="densities of the density study, particles per pixel, e.g. 0.01,0.05,0.08",
    )
    study.add_argument(
        "--noise", type=float, default=0.05, help="dot-centre noise, px (planes, obliquity)"
    )
    study.add_argument(
        "--position-noise",
        type=float,
        default=DEFAULT_NOISE_UM,
        help="position noise per component, um (dt, seeding)",
    )
    study.add_argument(
        "--snapshots",
        type=int,
        help="snapshots per dt (dt, noise, seeding; default: the scenario's frames, at most 100)",
    )
    study.add_argument("--quiet", action="store_true", help="no progress bar")
    study.set_defaults(run=run_study_command)
