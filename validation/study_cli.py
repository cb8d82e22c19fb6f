"""``synptv study``: parameter sweeps of a scenario on Dask, resumable, with a table and figure.

Studies: ``planes`` and ``obliquity`` (calibration, :mod:`validation.study_calibration`)
and ``dt``, ``noise`` and ``seeding`` (multi-Δt statistics,
:mod:`validation.study_multi_dt`). Every sweep point is one Dask task; its result is
saved as it finishes, so an interrupted study run again with the same inputs computes
only the missing points. Output, under ``<out>/<study>/``::

    points/<point id>.json   inputs and result of each point
    <study>.json             the table: a list of rows
    <study>.csv              the same table
    <study>.png              the summary figure
"""

import csv
import io
import os
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from matplotlib.figure import Figure

from simulator.presets import flow_preset
from validation.calibration_study import relative_to_most_planes
from validation.figures import obliquity_curves, plane_count_curves, save_figure
from validation.files import write_json_atomic, write_text_atomic
from validation.parallel import dask_client
from validation.progress import ProgressBar
from validation.scenario import Scenario, load_scenario, scenario_presets
from validation.study_calibration import obliquity_sweep, planes_sweep
from validation.study_figures import multi_dt_figure
from validation.study_multi_dt import DEFAULT_NOISE_UM, dt_sweep, noise_sweep, seeding_sweep
from validation.study_runner import Sweep, run_sweep


@dataclass(frozen=True)
class StudySettings:
    """What a study takes beyond its scenario.

    Attributes
    ----------
    dot_noise_px : float
        Dot-centre noise of the calibration studies, px.
    position_noise_um : float
        Position noise per component of the dt and seeding studies, µm.
    snapshots : int or None
        Snapshots per Δt of the multi-Δt studies (None: the scenario's frame pairs, at
        most :data:`validation.study_multi_dt.MAX_SNAPSHOTS`).
    """

    dot_noise_px: float = 0.05
    position_noise_um: float = DEFAULT_NOISE_UM
    snapshots: int | None = None


@dataclass(frozen=True)
class StudyFiles:
    """What a study wrote, and which points it computed now or took from earlier runs."""

    table: Path
    csv: Path
    figure: Path
    computed: tuple[str, ...]
    reused: tuple[str, ...]


def _calibration_figure(
    curves: Callable[[list[dict]], Figure],
) -> Callable[[Sweep, list[dict], list[dict]], Figure]:
    """A study figure from a figure of the rows alone."""
    return lambda sweep, rows, results: curves(rows)


def _multi_dt_figure(sweep: Sweep, rows: list[dict], results: list[dict]) -> Figure:
    """:func:`validation.study_figures.multi_dt_figure` of a dt, noise or seeding sweep."""
    eta = flow_preset(sweep.settings["flow"]["preset"]).parameters.eta
    return multi_dt_figure(sweep.study, rows, [r["curves"] for r in results], eta=eta)


@dataclass(frozen=True)
class _Study:
    """A study: its sweep, its table from the points' rows and its figure."""

    sweep: Callable[[Scenario, StudySettings], Sweep]
    table: Callable[[list[dict]], list[dict]]
    figure: Callable[[Sweep, list[dict], list[dict]], Figure]
    about: str


def _same(rows: list[dict]) -> list[dict]:
    """The points' rows as they are."""
    return rows


STUDIES = {
    "planes": _Study(
        lambda sc, s: planes_sweep(sc, noise_px=s.dot_noise_px),
        relative_to_most_planes,
        _calibration_figure(plane_count_curves),
        "calibration planes 2-13 spanning the depth (model-free; Table 1 and model error)",
    ),
    "obliquity": _Study(
        lambda sc, s: obliquity_sweep(sc, noise_px=s.dot_noise_px),
        _same,
        _calibration_figure(obliquity_curves),
        "window obliquity 0-20 deg in the camera plane and diagonally, every method",
    ),
    "dt": _Study(
        lambda sc, s: dt_sweep(sc, snapshots=s.snapshots, noise_um=s.position_noise_um),
        _same,
        _multi_dt_figure,
        "2-5 dt values spread over the preset's set, fixed number of frame pairs",
    ),
    "noise": _Study(
        lambda sc, s: noise_sweep(sc, snapshots=s.snapshots),
        _same,
        _multi_dt_figure,
        "position noise 0-30 um on one simulated sample",
    ),
    "seeding": _Study(
        lambda sc, s: seeding_sweep(sc, snapshots=s.snapshots, noise_um=s.position_noise_um),
        _same,
        _multi_dt_figure,
        "250-2000 particles per snapshot in the analysis volume, fixed snapshots",
    ),
}

_OPTION_LABELS = {
    "noise_px": "dot noise {:g} px",
    "plate": "{} plate",
    "particles": "P = {}",
    "snapshots": "M = {} per Δt",
    "frame_pairs": "{} frame pairs",
    "noise_um": "σ = {:g} µm",
}


def _title(sweep: Sweep) -> str:
    flow, rig = sweep.settings["flow"], sweep.settings["rig"]["name"]
    shown = [_OPTION_LABELS[k].format(v) for k, v in sweep.options.items() if k in _OPTION_LABELS]
    return (
        f"study {sweep.study}: scenario {sweep.settings['name']} "
        f"(rig {Path(rig).name}, flow {flow['preset']}, seed {sweep.settings['seed']}); "
        + ", ".join(shown)
    )


def _csv_text(rows: list[dict]) -> str:
    """The rows as CSV (columns in order of first appearance; lists as JSON)."""
    columns = list(dict.fromkeys(key for row in rows for key in row))
    stream = io.StringIO()
    writer = csv.DictWriter(stream, fieldnames=columns, lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow(
            {k: " ".join(map(str, v)) if isinstance(v, list) else v for k, v in row.items()}
        )
    return stream.getvalue()


def run_study(
    study: str,
    scenario: str | Path | Scenario,
    out: Path,
    *,
    settings: StudySettings = StudySettings(),
    workers: int | None = None,
    scheduler: str | None = None,
    quiet: bool = False,
    on_saved: Callable[[str], None] | None = None,
) -> StudyFiles:
    """Run (or resume) one study and write its table, CSV and figure.

    Parameters
    ----------
    study : str
        One of :data:`STUDIES`.
    scenario : str, Path or Scenario
        A scenario preset name, a scenario file, or a scenario.
    out : Path
        Output folder; the study writes ``<out>/<study>/`` (module docstring).
    settings : StudySettings
        Noise levels and sizes beyond the scenario.
    workers : int or None
        Local worker processes (None: one per CPU, at most one per point to compute).
    scheduler : str or None
        Address of a running Dask scheduler instead of a local cluster.
    quiet : bool
        No progress bar.
    on_saved : callable(point id), optional
        Called after each point is saved (see :func:`validation.study_runner.run_sweep`).

    Returns
    -------
    StudyFiles

    Raises
    ------
    ValueError
        Unknown study or scenario, both ``workers`` and ``scheduler``, bad options,
        an unreachable scheduler.
    """
    if study not in STUDIES:
        raise ValueError(f"unknown study {study!r}; known: {', '.join(STUDIES)}")
    if workers is not None and scheduler is not None:
        raise ValueError("give --workers or --scheduler, not both")
    if workers is not None and workers < 1:
        raise ValueError(f"--workers must be >= 1, got {workers}")
    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario)
    spec = STUDIES[study]
    sweep = spec.sweep(scenario, settings)
    folder = Path(out) / study
    folder.mkdir(parents=True, exist_ok=True)

    def connect(pending: int):
        if scheduler is not None:
            return dask_client(scheduler=scheduler)
        return dask_client(workers=min(workers or os.cpu_count() or 1, pending))

    outcome = run_sweep(
        sweep,
        folder / "points",
        connect,
        progress=ProgressBar(f"study {study}", enabled=not quiet),
        on_saved=on_saved,
    )
    results = list(outcome.results.values())
    rows = spec.table([row for result in results for row in result["rows"]])
    figure = spec.figure(sweep, rows, results)
    figure.suptitle(_title(sweep), fontsize=9)
    return StudyFiles(
        table=write_json_atomic(folder / f"{study}.json", rows),
        csv=write_text_atomic(folder / f"{study}.csv", _csv_text(rows)),
        figure=save_figure(figure, folder / f"{study}.png"),
        computed=outcome.computed,
        reused=outcome.reused,
    )


def _run_study_command(args) -> int:
    settings = StudySettings(
        dot_noise_px=args.noise, position_noise_um=args.position_noise, snapshots=args.snapshots
    )
    try:
        files = run_study(
            args.study,
            args.scenario,
            Path(args.out),
            settings=settings,
            workers=args.workers,
            scheduler=args.scheduler,
            quiet=args.quiet,
        )
    except KeyboardInterrupt:
        print(
            f"\nsynptv study: interrupted; finished points are saved under "
            f"{Path(args.out) / args.study / 'points'}: run the same command to resume",
            file=sys.stderr,
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
        help="parameter sweeps on Dask (planes, obliquity, dt, noise, seeding): table + figure",
        description=f"Sweep one parameter of a scenario, one Dask task per point, saving each "
        f"point as it finishes (run again to resume). {about}.",
    )
    study.add_argument("study", metavar="STUDY", help=f"one of {', '.join(STUDIES)}")
    study.add_argument(
        "--scenario",
        default="default",
        help=f"{', '.join(scenario_presets())} or a .toml file (rig, flow, sizes, seed)",
    )
    study.add_argument(
        "--workers", type=int, help="local Dask worker processes (default: one per CPU)"
    )
    study.add_argument(
        "--scheduler", metavar="ADDRESS", help="a running Dask scheduler, e.g. tcp://host:8786"
    )
    study.add_argument("--out", default="synptv-study", help="output folder")
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
    study.set_defaults(run=_run_study_command)
