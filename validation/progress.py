"""A text progress bar on stderr for long work (no third-party dependency)."""

import sys
import time
from typing import TextIO


class ProgressBar:
    """Callable ``(done, total)`` that redraws one line on a stream.

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

    def __call__(self, done: int, total: int) -> None:
        if not self.enabled:
            return
        now = time.monotonic()
        if done < total and now - self._last < 0.2:
            return
        self._last = now
        width = 30
        filled = int(width * done / max(total, 1))
        elapsed = now - self.start
        eta = elapsed / done * (total - done) if done else float("nan")
        self.stream.write(
            f"\r{self.label} [{'#' * filled}{'.' * (width - filled)}] {done}/{total} "
            f"{elapsed:5.0f} s elapsed, {eta:4.0f} s left"
        )
        if done >= total:
            self.stream.write("\n")
        self.stream.flush()
