"""A text progress bar on stderr for long work (no third-party dependency)."""

import sys
import time
from typing import TextIO

#: Seconds between redraws on a terminal, and between lines in a log file.
TERMINAL_INTERVAL_S = 0.2
LOG_INTERVAL_S = 10.0


class ProgressBar:
    """Callable ``(done, total)`` that redraws one line on a terminal; written to a file
    or a pipe (a log), one plain line every :data:`LOG_INTERVAL_S` and one at the end.

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
        self._last = 0.0
        isatty = getattr(self.stream, "isatty", None)
        self.terminal = bool(isatty and isatty())

    def __call__(self, done: int, total: int) -> None:
        if not self.enabled:
            return
        now = time.monotonic()
        interval = TERMINAL_INTERVAL_S if self.terminal else LOG_INTERVAL_S
        if done < total and now - self._last < interval:
            return
        self._last = now
        elapsed = now - self.start
        eta = elapsed / done * (total - done) if done else float("nan")
        timing = f"{done}/{total} {elapsed:5.0f} s elapsed, {eta:4.0f} s left"
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


def say_interrupted(line: str, stream: TextIO | None = None) -> None:
    """Print ``line`` for a command stopped by Ctrl-C, on a line of its own: after the
    terminal's ``^C`` and a progress bar's unfinished line, but no blank line in a log."""
    stream = sys.stderr if stream is None else stream
    print(("\n" if stream.isatty() else "") + line, file=stream)
