"""Map a function over the chunks of a run, keeping each result on disk as it arrives.

:func:`map_chunks` runs ``fn`` on every chunk of snapshots through an executor
(:mod:`validation.workflow.parallel`) and returns the results in chunk order, whatever order
they arrived in. With a cache folder, each result is saved there (pickle, written under
a temporary name and renamed) the moment it arrives, and results already saved are
loaded instead of computed: an interrupted stage, run again with the same inputs (the
cache lives in the stage's own temporary folder, :func:`validation.workflow.stages.staging_folder`),
computes only the chunks it had not finished.
"""

import os
import pickle
from collections.abc import Callable, Sequence
from pathlib import Path

from validation.workflow.parallel import Executor

Progress = Callable[[int, int], None]


def _path(cache: Path, name: str, chunk: tuple[int, int]) -> Path:
    return cache / f"{name}-{chunk[0]:06d}-{chunk[1]:06d}.pickle"


def map_chunks(
    executor: Executor,
    fn: Callable,
    chunks: Sequence[tuple[int, int]],
    item: Callable[[tuple[int, int]], object],
    *,
    shared: dict | None = None,
    cache: Path | None = None,
    name: str = "chunk",
    progress: Progress | None = None,
) -> list:
    """``fn(item(chunk), **shared)`` for every chunk, in chunk order.

    Parameters
    ----------
    executor : Executor
        Where ``fn`` runs.
    fn : callable
        A top-level function (picklable).
    chunks : sequence of (int, int)
        Snapshot ranges.
    item : callable((int, int)) -> object
        The input of ``fn`` for a chunk, made here (e.g. read from disk) when the chunk
        is sent, so that only a few are in memory at a time.
    shared : dict, optional
        Keyword arguments every call takes (sent once to each worker).
    cache : Path, optional
        Folder (created) where results are kept as they arrive, and found again.
    name : str
        Prefix of the cache files.
    progress : callable(done, total), optional
        Called after each chunk is available.

    Returns
    -------
    list
        One result per chunk.
    """
    results: list = [None] * len(chunks)
    todo = []
    for i, chunk in enumerate(chunks):
        path = None if cache is None else _path(cache, name, chunk)
        if path is not None and path.is_file():
            results[i] = pickle.loads(path.read_bytes())
        else:
            todo.append(i)
    done = len(chunks) - len(todo)
    if progress is not None and done:
        progress(done, len(chunks))
    if cache is not None:
        cache.mkdir(parents=True, exist_ok=True)
    for j, result in executor.map(fn, (item(chunks[i]) for i in todo), shared=shared):
        i = todo[j]
        results[i] = result
        if cache is not None:
            path = _path(cache, name, chunks[i])
            tmp = path.with_name(f".{path.name}.{os.getpid()}.partial")
            tmp.write_bytes(pickle.dumps(result, protocol=pickle.HIGHEST_PROTOCOL))
            os.replace(tmp, path)
        done += 1
        if progress is not None:
            progress(done, len(chunks))
    return results
