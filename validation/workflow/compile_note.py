"""One line on stderr when a command starts compiling the numerical kernels.

The kernels (numba) compile at their first call and are cached on disk (``cache=True``:
next to the installed sources, or in the user's cache folder where those cannot be
written), so a fresh install pays for them once, in its first runs; later runs load
them. The line is printed when the first kernel actually compiles (numba's compile
event, which a cache hit does not raise), in this process or in a local Dask worker
(:func:`dask_setup`, which :func:`validation.workflow.parallel.dask_client` preloads),
once per command: the first process to create a marker file says it. It is not
printed on later runs, whose kernels all come from the cache, nor with ``--quiet``.
"""

import os
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager

from numba.core import event

#: The environment variable that gives the local workers the marker file.
MARKER = "SYNPTV_COMPILE_NOTE"
#: Seconds a fresh install added to the first ``synptv run`` of the default scenario on
#: the 2-core development machine, its two workers compiling at once (58 s: 191 s
#: against 134 s for the next run; 42 s in one process, benchmarks/bench_first_run.py).
COMPILE_S = 60


class _FirstCompile(event.Listener):
    """Says the line at this process's first compile, unless another process of the
    command said it first (the marker file exists)."""

    def __init__(self, marker: str) -> None:
        self.marker = marker
        self.heard = False

    def on_start(self, ev: event.Event) -> None:
        """At a compile's start: the line, if it is the first here and nobody said it."""
        if self.heard:
            return
        self.heard = True
        try:
            os.close(os.open(self.marker, os.O_CREAT | os.O_EXCL | os.O_WRONLY))
        except OSError:  # said already, or the command is over
            return
        stream = sys.stderr
        isatty = getattr(stream, "isatty", None)
        start = "\n" if isatty and isatty() else ""  # after a progress bar's unfinished line
        print(
            f"{start}synptv: compiling the numerical kernels once (about {COMPILE_S} s on "
            "2 cores; later runs reuse them)",
            file=stream,
            flush=True,
        )

    def on_end(self, ev: event.Event) -> None:
        """Nothing at the end of a compile."""


@contextmanager
def watch(*, quiet: bool = False) -> Iterator[None]:
    """Within the block, say the line at the first compile, here or in a local worker.

    Parameters
    ----------
    quiet : bool
        The command's ``--quiet``: say nothing.
    """
    if quiet:
        yield
        return
    before = os.environ.get(MARKER)
    with tempfile.TemporaryDirectory(prefix="synptv-compile-note-") as folder:
        os.environ[MARKER] = os.path.join(folder, "said")
        listener = _FirstCompile(os.environ[MARKER])
        event.register("numba:compile", listener)
        try:
            yield
        finally:
            event.unregister("numba:compile", listener)
            if before is None:
                del os.environ[MARKER]
            else:
                os.environ[MARKER] = before


def dask_setup(worker: object) -> None:
    """Dask's preload hook: a local worker of a watched command watches too."""
    marker = os.environ.get(MARKER)
    if marker:
        event.register("numba:compile", _FirstCompile(marker))
