"""Where the work of a run or a study runs: in this process, or on Dask workers.

An :class:`Executor` maps a top-level (picklable) function over items and yields each
result with its item's index as it finishes. The same call runs

- in this process (:class:`InProcess`, one item after another);
- on a ``LocalCluster`` of single-threaded worker processes (``--workers N``);
- on a running Dask scheduler (``--scheduler ADDRESS``), whose workers must be able to
  import synptv.

Workers never touch the output folder unless told to (the caller writes what comes
back), so a remote scheduler needs no shared file system. Large inputs every call needs
(calibrations, the rig) are sent to each worker once (``shared``). At most a few items
per worker are in flight at a time, so items produced lazily (chunks read from disk)
stay bounded in memory.

Results must not depend on where they were computed: callers combine them in item
order, never in order of arrival, and every function seeds its randomness from its item.
"""

import logging
import os
import signal
import threading
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING, Protocol

if TYPE_CHECKING:  # dask is imported when a cluster is used, not by every synptv command
    from distributed import Client

log = logging.getLogger(__name__)

#: Seconds to wait for an existing scheduler before giving up.
CONNECT_TIMEOUT_S = 10

#: Environment of local worker processes: one thread each for numba and OpenCV too (Dask
#: already sets OMP/MKL/OpenBLAS to one), so N workers use N cores. It is set before the
#: process starts ("pre-spawn"): a spawned process first runs the parent's main module,
#: which may import numba, and numba reads its thread count at import. Set afterwards,
#: two single-threaded workers on two cores each ran two OpenMP threads and rendered 30
#: instead of 45 images/s.
SINGLE_THREADED = {"NUMBA_NUM_THREADS": "1", "OPENCV_FOR_THREADS_NUM": "1"}
_PRE_SPAWN = "distributed.nanny.pre-spawn-environ"
#: Dask's nannies set glibc's MALLOC_TRIM_THRESHOLD_, which turns off glibc's adaptive
#: mmap threshold: every large NumPy temporary is then mapped and unmapped afresh, and
#: the calibration tasks ran 2-3x slower (a third of their time in the kernel). Local
#: workers go without it.
TRIM_THRESHOLD = f"{_PRE_SPAWN}.MALLOC_TRIM_THRESHOLD_"
#: Items in flight per worker.
IN_FLIGHT = 4


class Executor(Protocol):
    """Maps a function over items, yielding ``(index, result)`` as results arrive."""

    workers: int

    def map(
        self, fn: Callable, items: Iterable, *, shared: dict | None = None
    ) -> Iterator[tuple[int, object]]:
        """``fn(item, **shared)`` for every item; (index of the item, result) in order of
        completion. Stopping the iteration early cancels what is still running."""
        ...


class InProcess:
    """:class:`Executor` that runs every item here, in order."""

    workers = 1

    def map(
        self, fn: Callable, items: Iterable, *, shared: dict | None = None
    ) -> Iterator[tuple[int, object]]:
        """``fn(item, **shared)`` item after item."""
        for i, item in enumerate(items):
            yield i, fn(item, **(shared or {}))


class DaskExecutor:
    """:class:`Executor` on a Dask client's workers.

    Parameters
    ----------
    client : distributed.Client
        Connected to the workers.
    """

    def __init__(self, client: "Client") -> None:
        self.client = client
        self.workers = max(1, sum(client.nthreads().values()))

    def map(
        self, fn: Callable, items: Iterable, *, shared: dict | None = None
    ) -> Iterator[tuple[int, object]]:
        """``fn(item, **shared)`` on the workers, at most :data:`IN_FLIGHT` per worker."""
        from distributed import as_completed

        sent = {
            k: self.client.scatter([v], broadcast=True, hash=False)[0]
            for k, v in (shared or {}).items()
        }
        pending = iter(enumerate(items))
        index: dict = {}
        running = as_completed()

        def submit() -> bool:
            try:
                i, item = next(pending)
            except StopIteration:
                return False
            # Sent ahead as data, not inside the task graph (items may be megabytes).
            data = self.client.scatter([item], hash=False)[0]
            future = self.client.submit(fn, data, pure=False, **sent)
            index[future] = i
            running.add(future)
            return True

        for _ in range(IN_FLIGHT * self.workers):
            if not submit():
                break
        try:
            for future in running:
                i = index.pop(future)
                result = future.result()
                submit()
                yield i, result
        finally:
            if index:
                self.client.cancel(list(index))


@contextmanager
def dask_client(*, workers: int | None = None, scheduler: str | None = None) -> Iterator["Client"]:
    """A Dask client: on an existing scheduler, or on a new local cluster.

    Parameters
    ----------
    workers : int or None
        Worker processes of the local cluster, single-threaded (None: one per CPU).
    scheduler : str or None
        Address of a running scheduler (``tcp://host:port``); its workers must be able
        to import synptv. Excludes ``workers``.

    Raises
    ------
    ValueError
        Both or bad values given, or no scheduler answering at ``scheduler``.
    """
    import dask
    from distributed import Client, LocalCluster

    if workers is not None and scheduler is not None:
        raise ValueError("give --workers or --scheduler, not both")
    # Dask logs at this process's level, on the workers too (errors only unless -v).
    level = logging.getLogger().getEffectiveLevel()
    logging.getLogger("distributed").setLevel(level)
    if scheduler is not None:
        try:
            client = Client(scheduler, timeout=CONNECT_TIMEOUT_S)
        except (OSError, TimeoutError, ValueError, TypeError) as err:
            raise ValueError(
                f"cannot connect to a Dask scheduler at {scheduler!r}: {err}"
            ) from None
        with client:
            yield client
        return
    n = (os.cpu_count() or 1) if workers is None else workers
    if not isinstance(n, int) or n < 1:
        raise ValueError(f"--workers must be an integer >= 1, got {workers!r}")
    # Read by each worker's Dask as it starts: it logs at this process's level.
    worker_environ = {
        **SINGLE_THREADED,
        "DASK_LOGGING__DISTRIBUTED": logging.getLevelName(level).lower(),
    }
    environment = {f"{_PRE_SPAWN}.{key}": value for key, value in worker_environ.items()}
    # The nannies write these variables into this process's os.environ before spawning
    # a worker; put this process's values back once the workers are up and at the end.
    # Left at one thread, the statistics computed here between the chunks would run on
    # one core, and numba refuses to compile once the variable no longer matches its
    # running threads.
    saved = {key: os.environ.get(key) for key in worker_environ}
    try:
        with dask.config.set({TRIM_THRESHOLD: None, **environment}):
            with _workers_ignore_ctrl_c():
                cluster = LocalCluster(
                    n_workers=n,
                    threads_per_worker=1,
                    processes=True,
                    # A port of its own: with None the scheduler's HTTP server still
                    # tries the default 8787, and warns when another cluster holds it.
                    dashboard_address=":0",
                    env=worker_environ,
                    # Each worker watches for its first compile (one line per command).
                    preload=["validation.workflow.compile_note"],
                )
            with cluster, Client(cluster) as client:
                _set_environment(saved)
                yield client
    finally:
        _set_environment(saved)


@contextmanager
def _workers_ignore_ctrl_c() -> Iterator[None]:
    """Ignore SIGINT while the workers are spawned, so that they inherit that: Ctrl-C
    reaches every process of the terminal's group, and the workers would each print a
    KeyboardInterrupt traceback; this process closes them instead. Only the main thread
    can change signal handlers (elsewhere this does nothing)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def _set_environment(values: dict[str, str | None]) -> None:
    """Set (or, for None, remove) variables of ``os.environ``."""
    for key, value in values.items():
        if value is None:
            os.environ.pop(key, None)
        else:
            os.environ[key] = value


def check_parallel_options(workers: int | None, scheduler: str | None) -> None:
    """Refuse bad ``--workers`` / ``--scheduler`` values before any work starts.

    Raises
    ------
    ValueError
        Both given, ``workers`` < 1, or a scheduler address that is not host:port.
    """
    if workers is not None and scheduler is not None:
        raise ValueError("give --workers or --scheduler, not both")
    if workers is not None and (isinstance(workers, bool) or workers < 1):
        raise ValueError(f"--workers must be an integer >= 1, got {workers}")
    if scheduler is not None and ":" not in scheduler:
        raise ValueError(f"--scheduler must be an address host:port, got {scheduler!r}")


@contextmanager
def executor(*, workers: int | None = None, scheduler: str | None = None) -> Iterator[Executor]:
    """The executor a command asked for.

    Parameters
    ----------
    workers : int or None
        1: this process only; N > 1: a local cluster of N workers; None: one worker per
        CPU (this process alone on a single-CPU machine).
    scheduler : str or None
        A running Dask scheduler instead.

    Raises
    ------
    ValueError
        Bad options (:func:`check_parallel_options`), an unreachable scheduler.
    """
    check_parallel_options(workers, scheduler)
    n = (os.cpu_count() or 1) if workers is None and scheduler is None else workers
    if scheduler is None and n == 1:
        yield InProcess()
        return
    with dask_client(workers=n, scheduler=scheduler) as client:
        yield DaskExecutor(client)
