"""``synptv study``: parameter sweeps of a scenario, resumable, with a table and figure.

Studies: ``planes``, ``dt``, ``noise``, ``seeding`` and ``obliquity``, on two chains:

- ``rendered`` (default): every point through images, as ``synptv run`` measures
  (:mod:`validation.studies.rendered`); the points run one after the other, each
  rendering, detecting and matching its chunks on the executor (this process, a local
  Dask cluster or a scheduler), and reusing the stages it shares with other points;
- ``ideal``: the fast stand-in without images, exact dot projections plus noise
  (``planes``, ``obliquity``: :mod:`validation.studies.calibration_sweeps`) or KS positions plus
  noise (``dt``, ``noise``, ``seeding``: :mod:`validation.studies.multi_dt`), one Dask task
  per point.

``--seeds K`` repeats every point with K independent seeds. Each point is saved as it
finishes, so an interrupted study run again with the same inputs computes only the
missing points. The rendered chain's stages (datasets, detections, calibrations, PTV
runs) go to ``<out>/work/``, where every study of ``<out>`` finds them. Output, under
``<out>/<study>/``::

    points/<point id>.json   inputs and result of each point (per seed)
    study.json               {"study", "chain", "scenario", "points": the table}
    study.csv                the same table (:mod:`validation.studies.table`)
    study.png                the summary figure
"""

import os
from collections.abc import Callable
from dataclasses import dataclass, replace
from importlib.metadata import version
from pathlib import Path

from matplotlib.figure import Figure

from validation.report.calibration_figures import obliquity_curves, plane_count_curves
from validation.report.png import save_figure
from validation.run.scenario import Scenario, load_scenario, scenario_from_dict
from validation.studies.calibration_methods import relative_to_most_planes
from validation.studies.calibration_sweeps import obliquity_sweep, planes_sweep
from validation.studies.multi_dt import (
    DEFAULT_NOISE_UM,
    R_OVER_ETA,
    dt_sweep,
    noise_sweep,
    seeding_sweep,
    study_sizes,
)
from validation.studies.multi_dt_dns import dt_range_figure, dt_range_sweep
from validation.studies.multi_dt_figures import multi_dt_figure
from validation.studies.rendered import evaluate_point, study_points
from validation.studies.runner import Sweep, load_point, run_sweep
from validation.studies.table import csv_text, study_figure
from validation.workflow.files import (
    as_json,
    write_json_atomic,
    write_text_atomic,
)
from validation.workflow.parallel import Executor, check_parallel_options, dask_client, executor
from validation.workflow.progress import ProgressBar


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
        most :data:`validation.studies.multi_dt.MAX_SNAPSHOTS`).

    Examples
    --------
    ``synptv study``'s defaults, and a noisier calibration study:

    >>> import validation
    >>> validation.StudySettings()
    StudySettings(dot_noise_px=0.05, position_noise_um=15.0, snapshots=None)
    >>> validation.StudySettings(dot_noise_px=0.1).dot_noise_px  # px
    0.1
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
    """:func:`~validation.studies.multi_dt_figures.multi_dt_figure` of a dt, noise or
    seeding sweep."""
    eta = scenario_from_dict(sweep.settings).flow.as_preset().parameters.eta
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
    "density": _Study(
        lambda sc, s: _rendered_only("density"),
        _same,
        _multi_dt_figure,
        "the LPT Challenge's 0.005-0.16 particles per pixel: IPR beside detect-and-match "
        "(a scenario with [ipr]; rendered chain)",
    ),
}


def _rendered_only(study: str):
    """The sweep of a study that exists on the rendered chain only."""
    raise ValueError(f"the {study} study runs on rendered images only (--chain rendered)")


_OPTION_LABELS = {
    "noise_px": "dot noise {:g} px",
    "plate": "{} plate",
    "particles": "P = {}",
    "snapshots": "M = {} per Δt",
    "frame_pairs": "{} frame pairs",
    "noise_um": "σ = {:g} µm",
}


def _title(sweep: Sweep) -> str:
    flow, rig = scenario_from_dict(sweep.settings).flow, sweep.settings["rig"]["name"]
    shown = [_OPTION_LABELS[k].format(v) for k, v in sweep.options.items() if k in _OPTION_LABELS]
    return (
        f"study {sweep.study}: scenario {sweep.settings['name']} "
        f"(rig {Path(rig).name}, flow {flow.label}, seed {sweep.settings['seed']}); "
        + ", ".join(shown)
    )


def _common_row(row: dict, seed: int) -> dict:
    """An ideal-chain row with the columns of every study table (null where the chain
    does not measure them; see :mod:`validation.studies.table`), its other columns kept.

    A quantity the sweeps give under a name of their own goes to its common column
    alone, not repeated under both names: the calibration sweeps' ``model_d_um`` (the
    mean 3-D error at random points) is ``model_error_um``, the multi-Δt sweeps'
    ``c1_error_<n>eta`` and ``c1_se_<n>eta`` are ``c1_rel_err`` and ``c1_rel_se``
    ``{"<n>": …}``, their ``epsilon_error`` is ``epsilon_rel_err``.
    """
    row = dict(row)
    common = {
        "seed": seed,
        "table1_d_um": row.pop("table1_d_um", None),
        "model_error_um": row.pop("model_d_um", None),
        "yield": None,
        "ghosts": None,
        "c1_rel_err": None,
        "c1_rel_se": None,
        "epsilon_rel_err": row.pop("epsilon_error", None),
        "epsilon_rel_se": None,
    }
    if "c1_error_10eta" in row:
        common["c1_rel_err"] = {str(n): row.pop(f"c1_error_{n}eta") for n in R_OVER_ETA}
        common["c1_rel_se"] = {str(n): row.pop(f"c1_se_{n}eta") for n in R_OVER_ETA}
    return {**common, **row}


def _run_ideal(
    study: str,
    scenario: Scenario,
    folder: Path,
    *,
    settings: StudySettings,
    seeds: int,
    workers: int | None,
    scheduler: str | None,
    quiet: bool,
    on_saved: Callable[[str], None] | None,
) -> tuple[list[dict], Figure, tuple, tuple]:
    """The ideal chain (no images): the sweeps of every seed on Dask."""
    spec = STUDIES[study]
    rows, computed, reused, figure = [], [], [], None
    for s in range(seeds):
        seeded = scenario.with_seed(scenario.seed + s)
        sweep = spec.sweep(seeded, settings)
        outcome = run_sweep(
            sweep,
            folder / "points" / f"seed-{seeded.seed}",
            _connect(workers, scheduler),
            progress=ProgressBar(f"study {study} seed {seeded.seed}", enabled=not quiet),
            on_saved=on_saved,
        )
        results = list(outcome.results.values())
        table = spec.table([row for result in results for row in result["rows"]])
        rows += [_common_row(row, seeded.seed) for row in table]
        computed += [f"seed-{seeded.seed}/{p}" for p in outcome.computed]
        reused += [f"seed-{seeded.seed}/{p}" for p in outcome.reused]
        if figure is None:
            figure = spec.figure(sweep, table, results)
            figure.suptitle(_title(sweep), fontsize=9)
    return rows, figure, tuple(computed), tuple(reused)


def _run_dns_dt(
    scenario: Scenario,
    out: Path,
    *,
    settings: StudySettings,
    seeds: int,
    workers: int | None,
    scheduler: str | None,
    quiet: bool,
    on_saved: Callable[[str], None] | None,
) -> tuple[list[dict], Figure, tuple, tuple]:
    """The dt study on a DNS: the Δt-range sweep (:mod:`validation.studies.multi_dt_dns`)
    on the scenario's flow stage ``<out>/flow``, built or reused first (the stage of
    ``synptv run --out <out>``)."""
    from validation.run.flow_stage import dns_run_flow

    _, stage = dns_run_flow(scenario, out, progress=ProgressBar("flow", enabled=not quiet))
    particles, snapshots = study_sizes(scenario, settings.snapshots)
    snapshots = min(snapshots, scenario.particles.frames)
    folder = out / "dt"
    rows, computed, reused = [], [], []
    for s in range(seeds):
        seeded = scenario.with_seed(scenario.seed + s)
        sweep = dt_range_sweep(
            seeded,
            particles=particles,
            snapshots=snapshots,
            noise_um=settings.position_noise_um,
            field=stage.folder,
        )
        sweep = replace(sweep, options={**sweep.options, "field_key": stage.key})
        outcome = run_sweep(
            sweep,
            folder / "points" / f"seed-{seeded.seed}",
            _connect(workers, scheduler),
            progress=ProgressBar(f"study dt seed {seeded.seed}", enabled=not quiet),
            on_saved=on_saved,
        )
        for result in outcome.results.values():
            rows += [_common_row(row, seeded.seed) for row in result["rows"]]
        computed += [f"seed-{seeded.seed}/{p}" for p in outcome.computed]
        reused += [f"seed-{seeded.seed}/{p}" for p in outcome.reused]
    figure = dt_range_figure(
        rows,
        f"study dt on a Navier–Stokes flow: the Δt³ bias of c₁; scenario {scenario.name} "
        f"(flow {scenario.flow.label}), P = {particles}, M = {snapshots}",
    )
    return rows, figure, tuple(computed), tuple(reused)


def _connect(workers: int | None, scheduler: str | None):
    """The Dask client of an ideal-chain sweep, given its number of pending points."""

    def connect(pending: int):
        if scheduler is not None:
            return dask_client(scheduler=scheduler)
        return dask_client(workers=min(workers or os.cpu_count() or 1, pending))

    return connect


def _relative_to_most_planes(rows: list[dict]) -> list[dict]:
    """The planes rows with their errors over those of the most planes, per seed and
    method (``table1_ratio``, ``model_ratio``: the paper's "7 planes +2 %")."""
    out = []
    for row in rows:
        same = [r for r in rows if (r["seed"], r["method"]) == (row["seed"], row["method"])]
        most = max(same, key=lambda r: r["planes"])
        out.append(
            {
                **row,
                "table1_ratio": row["table1_d_um"] / most["table1_d_um"],
                "model_ratio": row["model_error_um"] / most["model_error_um"],
            }
        )
    return out


def _point_inputs(study: str, point) -> dict:
    """What a rendered point's result depends on, as recorded in its file."""
    return as_json(
        {
            "synptv": version("synptv"),
            "study": study,
            "chain": "rendered",
            "scenario": point.scenario.as_dict(),
            "point": point.params,
        }
    )


def _run_rendered(
    study: str,
    scenario: Scenario,
    folder: Path,
    *,
    seeds: int,
    values: list | None,
    ex: Executor,
    quiet: bool,
    on_saved: Callable[[str], None] | None,
) -> tuple[list[dict], Figure, tuple, tuple]:
    """The rendered chain: each point through images, points saved as they finish."""
    points = study_points(study, scenario, seeds, values)
    saved_folder = folder / "points"
    saved_folder.mkdir(parents=True, exist_ok=True)
    rows, computed, reused = [], [], []
    todo = []
    for point in points:
        saved = load_point(saved_folder / f"{point.id}.json", _point_inputs(study, point))
        if saved is None:
            todo.append(point)
        else:
            rows.append((point.id, saved))
            reused.append(point.id)
    bar = ProgressBar(f"study {study}", enabled=not quiet)
    for point in todo:
        result = evaluate_point(
            point,
            folder.parent / "work",
            ex,
            progress=lambda name, p=point.id: ProgressBar(f"  {p}: {name}", enabled=not quiet),
        )
        record = as_json({"inputs": _point_inputs(study, point), "result": result})
        write_json_atomic(saved_folder / f"{point.id}.json", record)
        rows.append((point.id, record["result"]))
        computed.append(point.id)
        bar(len(rows), len(points))
        if on_saved is not None:
            on_saved(point.id)
    order = {p.id: i for i, p in enumerate(points)}
    table = [row for _, result in sorted(rows, key=lambda r: order[r[0]]) for row in result]
    if study == "planes":
        table = _relative_to_most_planes(table)
    count = scenario.particles.count
    tracers = "tracers from the density" if study == "density" else f"{count} tracers"
    title = (
        f"study {study} on rendered images: scenario {scenario.name} "
        f"(flow {scenario.flow.label}, {tracers}, "
        f"{scenario.particles.frames} frame pairs per Δt), "
        + (
            f"seed {scenario.seed}"
            if seeds == 1
            else f"seeds {scenario.seed}…{scenario.seed + seeds - 1}"
        )
    )
    return table, study_figure(study, table, title=title), tuple(computed), tuple(reused)


def _study_chain(study: str, scenario: Scenario, chain: str | None) -> str:
    """The chain a study runs on: as given, else ``rendered``; on a DNS flow the dt
    study runs on the DNS's trajectories (``ideal``) and the studies that draw kinematic
    simulation are refused."""
    if chain not in (None, "rendered", "ideal"):
        raise ValueError(f"--chain must be 'rendered' or 'ideal', got {chain!r}")
    if study == "density" and chain == "ideal":
        _rendered_only(study)
    if scenario.flow.kind == "ks":
        return chain or "rendered"
    kind = scenario.flow.kind
    if study in ("noise", "seeding"):
        raise ValueError(
            f"the {study} study draws kinematic simulation; on a {kind!r} flow only the dt "
            "study (and the calibration studies) are built"
        )
    if study == "dt":
        if chain == "rendered" or kind != "dns":
            raise ValueError(
                f"the dt study on a {kind!r} flow runs on the DNS's exact trajectories with "
                "position noise (--chain ideal, its default; docs/study.md); rendered Δt "
                "subsets of a DNS are not built"
            )
        return "ideal"
    return chain or "rendered"


def _checked_study(
    study: str,
    scenario: str | Path | Scenario,
    chain: str | None,
    seeds: int,
    values: list | None,
    settings: StudySettings,
) -> tuple[Scenario, str]:
    """The scenario and chain of a study whose options are all checked (see
    :func:`run_study`)."""
    if study not in STUDIES:
        raise ValueError(f"unknown study {study!r}; known: {', '.join(STUDIES)}")
    if isinstance(seeds, bool) or not isinstance(seeds, int) or seeds < 1:
        raise ValueError(f"--seeds must be an integer >= 1, got {seeds!r}")
    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario)
    chain = _study_chain(study, scenario, chain)
    if chain == "rendered":
        study_points(study, scenario, 1, values)  # checks the values
    elif values is not None:
        raise ValueError("--planes and --dt-subsets choose points of the rendered chain only")
    elif scenario.flow.kind == "dns" and study == "dt":
        study_sizes(scenario, settings.snapshots)  # checks --snapshots
    else:
        STUDIES[study].sweep(scenario, settings)  # checks the options
    return scenario, chain


def run_study(
    study: str,
    scenario: str | Path | Scenario,
    out: Path,
    *,
    chain: str | None = None,
    seeds: int = 1,
    values: list | None = None,
    settings: StudySettings = StudySettings(),
    workers: int | None = None,
    scheduler: str | None = None,
    quiet: bool = False,
    on_saved: Callable[[str], None] | None = None,
) -> StudyFiles:
    """Run (or resume) one study and write ``study.json``, ``study.csv`` and ``study.png``.

    Parameters
    ----------
    study : str
        One of :data:`STUDIES`.
    scenario : str, Path or Scenario
        A scenario preset name, a scenario file, or a scenario.
    out : Path
        Output folder; the study writes ``<out>/<study>/`` (module docstring).
    chain : {"rendered", "ideal"} or None
        Through images (every stage of ``synptv run``) or the fast stand-in (None:
        rendered, except the dt study of a DNS flow, which runs on its trajectories).
    seeds : int
        Independent repetitions of every point (seeds scenario.seed, +1, …).
    values : list, optional
        The swept values to run (rendered chain): plane counts, Δt index lists, or
        densities (particles per pixel of the volume's image).
    settings : StudySettings
        Noise levels and sizes of the ideal chain.
    workers : int or None
        Local worker processes (None: one per CPU).
    scheduler : str or None
        Address of a running Dask scheduler instead of a local cluster.
    quiet : bool
        No progress bar.
    on_saved : callable(point id), optional
        Called after each point is saved.

    Returns
    -------
    StudyFiles

    Raises
    ------
    ValueError
        Unknown study, chain or scenario, bad options or values, an unreachable
        scheduler: before any work starts.

    Examples
    --------
    The calibration planes study of the CI scenario on the fast chain (exact dot
    projections plus noise, no images)::

        files = validation.run_study("planes", "ci", "synptv-study", chain="ideal")
        files.table  # synptv-study/planes/study.json, also study.csv and study.png

    The options are checked before any work starts; an unknown study names the known
    ones:

    >>> import pathlib, tempfile
    >>> import validation
    >>> tmp = tempfile.TemporaryDirectory()
    >>> validation.run_study("speed", "ci", pathlib.Path(tmp.name))
    Traceback (most recent call last):
    ...
    ValueError: unknown study 'speed'; known: planes, obliquity, dt, noise, seeding, density
    >>> tmp.cleanup()
    """
    check_parallel_options(workers, scheduler)
    scenario, chain = _checked_study(study, scenario, chain, seeds, values, settings)
    folder = Path(out) / study
    if chain == "ideal" and scenario.flow.kind == "dns":
        folder.mkdir(parents=True, exist_ok=True)
        rows, figure, computed, reused = _run_dns_dt(
            scenario,
            Path(out),
            settings=settings,
            seeds=seeds,
            workers=workers,
            scheduler=scheduler,
            quiet=quiet,
            on_saved=on_saved,
        )
    elif chain == "rendered":
        with executor(workers=workers, scheduler=scheduler) as ex:
            folder.mkdir(parents=True, exist_ok=True)
            rows, figure, computed, reused = _run_rendered(
                study,
                scenario,
                folder,
                seeds=seeds,
                values=values,
                ex=ex,
                quiet=quiet,
                on_saved=on_saved,
            )
    else:
        folder.mkdir(parents=True, exist_ok=True)
        rows, figure, computed, reused = _run_ideal(
            study,
            scenario,
            folder,
            settings=settings,
            seeds=seeds,
            workers=workers,
            scheduler=scheduler,
            quiet=quiet,
            on_saved=on_saved,
        )
    table = {"study": study, "chain": chain, "scenario": scenario.name, "points": rows}
    return StudyFiles(
        table=write_json_atomic(folder / "study.json", table),
        csv=write_text_atomic(folder / "study.csv", csv_text(rows)),
        figure=save_figure(figure, folder / "study.png"),
        computed=computed,
        reused=reused,
    )
