"""A text progress bar on stderr for long work (no third-party dependency)."""

import sys
import threading
import time
import weakref
from typing import TextIO

#: Seconds between redraws on a terminal, and between lines in a log file.
TERMINAL_INTERVAL_S = 0.2
LOG_INTERVAL_S = 10.0


class ProgressBar:
    """Callable ``(done, total)`` that redraws one line on a terminal; written to a file
    or a pipe (a log), one plain line at least every :data:`LOG_INTERVAL_S` while the bar
    lives, and one at the end.

    In a log, a line comes every :data:`LOG_INTERVAL_S` even when the work reports
    nothing (a long chunk, the statistics after the last chunk): a background thread
    writes ``still working`` lines until the bar is closed or dropped.

    Parameters
    ----------
    label : str
        What is progressing.
    stream : text stream
        Where to draw (stderr by default); nothing is drawn when ``enabled`` is False.
    enabled : bool
        Draw or stay silent.
    """

    def __init__(self, label: str, *, stream: TextIO | None = None, enabled: bool = True):
        self.label = label
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = enabled
        self.start = time.monotonic()
        self._last = self.start
        self._state: tuple[int, int] | None = None
        self._first: tuple[int, float] | None = None  # the first report: (done, time)
        self._lock = threading.Lock()
        isatty = getattr(self.stream, "isatty", None)
        self.terminal = bool(isatty and isatty())
        self._stop = threading.Event()
        if enabled and not self.terminal:
            weakref.finalize(self, self._stop.set)
            threading.Thread(
                target=_keep_alive, args=(weakref.ref(self), self._stop), daemon=True
            ).start()

    def __call__(self, done: int, total: int) -> None:
        if not self.enabled:
            return
        now = time.monotonic()
        interval = TERMINAL_INTERVAL_S if self.terminal else LOG_INTERVAL_S
        with self._lock:
            self._state = (done, total)
            if done < total and now - self._last < interval and self._last > self.start:
                return
            self._last = now
            elapsed = now - self.start
            left = self._left(done, total, now)
            timing = f"{_count(done, total)} {elapsed:5.0f} s elapsed, {left}"
            if self.terminal:
                width = 30
                filled = int(width * done / max(total, 1))
                bar = f"[{'#' * filled}{'.' * (width - filled)}]"
                self.stream.write(f"\r{self.label} {bar} {timing}")
                if done >= total:
                    self.stream.write("\n")
            else:
                self.stream.write(f"{self.label}: {timing}\n")
            self.stream.flush()

    def _left(self, done: int, total: int, now: float) -> str:
        """The time left, from the pace since the first report: the first unit of work
        also pays for starting up (compiling kernels, opening files), so its pace is no
        guide; ``? s left`` until a second report."""
        if done >= total:
            return "   0 s left"
        if self._first is None and done > 0:
            self._first = (done, now)
        if self._first is None or done <= self._first[0] or now <= self._first[1]:
            return "   ? s left"
        pace = (now - self._first[1]) / (done - self._first[0])
        return f"{pace * (total - done):4.0f} s left"

    def beat(self) -> None:
        """In a log, a ``still working`` line when none was written for
        :data:`LOG_INTERVAL_S` (the background thread calls this)."""
        with self._lock:
            now = time.monotonic()
            if self._stop.is_set() or now - self._last < LOG_INTERVAL_S:
                return
            self._last = now
            done = "starting" if self._state is None else _count(*self._state)
            self.stream.write(
                f"{self.label}: {done} {now - self.start:5.0f} s elapsed, still working\n"
            )
            self.stream.flush()

    def close(self) -> None:
        """Stop the ``still working`` lines (also done when the bar is dropped)."""
        self._stop.set()


def _count(done: float, total: float) -> str:
    """``done/total`` for counts, a percentage for fractions of work (floats)."""
    if isinstance(total, float) or isinstance(done, float):
        return f"{100 * done / total:3.0f} %"
    return f"{done}/{total}"


def _keep_alive(bar: "weakref.ref[ProgressBar]", stop: threading.Event) -> None:
    """The background loop of a log's bar: a beat every quarter interval until stopped
    or the bar is gone (it holds the bar only weakly)."""
    while not stop.wait(LOG_INTERVAL_S / 4):
        alive = bar()
        if alive is None:
            return
        alive.beat()
        del alive


def say_interrupted(line: str, stream: TextIO | None = None) -> None:
    """Print ``line`` for a command stopped by Ctrl-C, on a line of its own: after the
    terminal's ``^C`` and a progress bar's unfinished line, but no blank line in a log."""
    stream = sys.stderr if stream is None else stream
    print(("\n" if stream.isatty() else "") + line, file=stream)
