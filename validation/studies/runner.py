"""Parameter sweeps on Dask that save every point as it finishes, and resume.

A :class:`Sweep` is a top-level (picklable) task function, the plain inputs every point
shares (the scenario's settings and the study's options) and the points. Each point
runs as one Dask task on a :func:`validation.workflow.parallel.dask_client` (a ``LocalCluster``
of single-threaded worker processes, or an existing scheduler). The parent process
writes each result as ``<folder>/<point id>.json`` the moment it arrives (temporary
file, then rename), with the inputs it was computed from; a later run reuses a point
only when its recorded inputs equal the current ones, so an interrupted sweep resumes
where it stopped.
"""

import json
import logging
import zlib
from collections.abc import Callable
from contextlib import AbstractContextManager
from dataclasses import dataclass
from importlib.metadata import version
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from validation.workflow.files import as_json, write_json_atomic

if TYPE_CHECKING:  # dask is imported when a sweep runs, not by every synptv command
    from distributed import Client

log = logging.getLogger(__name__)

Task = Callable[[dict, dict, dict], dict]


@dataclass(frozen=True)
class SweepPoint:
    """One point of a sweep.

    Attributes
    ----------
    id : str
        Name of the point's file (letters, digits, ``-``, ``.``, ``_``).
    params : dict
        The point's parameters (JSON-able), passed to the task.
    """

    id: str
    params: dict


@dataclass(frozen=True)
class Sweep:
    """A study's points and how each is computed.

    Attributes
    ----------
    study : str
        The study's name.
    task : callable(settings, options, params) -> dict
        A top-level function returning a JSON-able result for one point.
    settings : dict
        The scenario as :meth:`validation.run.scenario.Scenario.as_dict` gives it.
    options : dict
        The study's JSON-able options shared by every point.
    points : tuple of SweepPoint
        The sweep, in the order of the summary table.
    """

    study: str
    task: Task
    settings: dict
    options: dict
    points: tuple[SweepPoint, ...]

    def inputs(self, point: SweepPoint) -> dict:
        """Everything the point's result depends on, as recorded in its file."""
        return as_json(
            {
                "synptv": version("synptv"),
                "study": self.study,
                "scenario": self.settings["name"],
                "settings": self.settings,
                "options": self.options,
                "point": point.params,
            }
        )


@dataclass(frozen=True)
class SweepOutcome:
    """The results of a sweep, by point id in sweep order, and which points ran now."""

    results: dict[str, dict]
    computed: tuple[str, ...]
    reused: tuple[str, ...]


def seed_sequence(seed: int, *keys: object) -> np.random.SeedSequence:
    """A seed derived from an integer seed and keys (str, numbers, dicts).

    The same seed and keys, in the same order, give the same sequence in every process
    and Python session (CRC-32 of each key's canonical JSON, so the order of a dict's
    entries does not matter; not ``hash``).
    """
    words = [zlib.crc32(json.dumps(key, sort_keys=True).encode()) for key in keys]
    return np.random.SeedSequence([int(seed), *words])


def load_point(path: Path, inputs: dict) -> dict | None:
    """The saved result of a point if its file records exactly ``inputs``, else None."""
    try:
        saved = json.loads(path.read_text())
    except FileNotFoundError:
        return None
    except (OSError, ValueError) as err:
        log.warning("%s unreadable (%s): recomputing the point", path, err)
        return None
    if not isinstance(saved, dict) or saved.get("inputs") != inputs or "result" not in saved:
        log.info("%s was computed from other inputs: recomputing the point", path)
        return None
    return saved["result"]


def run_sweep(
    sweep: Sweep,
    folder: Path,
    connect: Callable[[int], AbstractContextManager["Client"]],
    *,
    progress: Callable[[int, int], None] | None = None,
    on_saved: Callable[[str], None] | None = None,
) -> SweepOutcome:
    """Compute the points of a sweep that have no valid saved result, saving each.

    Parameters
    ----------
    sweep : Sweep
        The points and their task.
    folder : Path
        Where point files live (created).
    connect : callable(int) -> context manager of distributed.Client
        Called with the number of points to compute (only when there are some) for
        the client that runs them, e.g. ``lambda n: dask_client(workers=min(n, 2))``.
    progress : callable(done, total), optional
        Called after each point is available (points saved earlier count at once).
    on_saved : callable(point id), optional
        Called after each newly computed point is saved; an exception raised there (or
        a KeyboardInterrupt) stops the sweep, cancelling the tasks not yet finished.

    Returns
    -------
    SweepOutcome
        Results as saved (a JSON round trip: NaN reads as None), by point id.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    ids = [point.id for point in sweep.points]
    if len(set(ids)) != len(ids):
        raise ValueError(f"{sweep.study}: point ids must be unique, got {ids}")
    results = {}
    for point in sweep.points:
        saved = load_point(folder / f"{point.id}.json", sweep.inputs(point))
        if saved is not None:
            results[point.id] = saved
    reused = tuple(i for i in ids if i in results)
    total = len(ids)
    if progress is not None and reused:
        progress(len(reused), total)
    from distributed import as_completed

    pending = [point for point in sweep.points if point.id not in results]
    computed = []
    if pending:
        with connect(len(pending)) as client:
            futures = {
                client.submit(sweep.task, sweep.settings, sweep.options, p.params, pure=False): p
                for p in pending
            }
            try:
                for future in as_completed(list(futures)):
                    point = futures[future]
                    record = as_json({"inputs": sweep.inputs(point), "result": future.result()})
                    write_json_atomic(folder / f"{point.id}.json", record)
                    results[point.id] = record["result"]
                    computed.append(point.id)
                    log.info("%s: point %s saved", sweep.study, point.id)
                    if progress is not None:
                        progress(len(results), total)
                    if on_saved is not None:
                        on_saved(point.id)
            finally:
                unfinished = [f for f in futures if not f.done()]
                if unfinished:
                    client.cancel(unfinished)
    return SweepOutcome({i: results[i] for i in ids}, tuple(computed), reused)
