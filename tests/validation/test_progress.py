"""Progress on a terminal redraws one line; in a log it writes a few plain lines."""

import gc
import io
import time

from validation.workflow import progress
from validation.workflow.progress import ProgressBar


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_a_log_gets_plain_lines_not_thousands_of_redraws():
    log = io.StringIO()
    bar = ProgressBar("render", stream=log)
    for done in range(1, 5001):
        bar(done, 5000)
    lines = log.getvalue().splitlines()
    assert "\r" not in log.getvalue()
    assert 1 <= len(lines) <= 3  # the first update, maybe one 10 s later, the end
    assert lines[-1].startswith("render: 5000/5000")


def test_a_terminal_gets_one_redrawn_line_ending_with_a_newline():
    screen = _Terminal()
    bar = ProgressBar("detect", stream=screen)
    for done in range(1, 101):
        bar(done, 100)
    text = screen.getvalue()
    assert text.startswith("\rdetect [") and text.endswith("\n")
    assert text.count("\n") == 1
    assert "100/100" in text.rsplit("\r", 1)[-1]


def test_quiet_writes_nothing():
    log = io.StringIO()
    ProgressBar("truth", stream=log, enabled=False)(1, 1)
    assert log.getvalue() == ""


def _wait_for(predicate, seconds: float = 10.0) -> bool:
    """Poll ``predicate`` until it holds or ``seconds`` pass (a behaviour, not a speed)."""
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(0.01)
    return predicate()


def test_a_log_gets_a_line_while_the_work_reports_nothing(monkeypatch):
    monkeypatch.setattr(progress, "LOG_INTERVAL_S", 0.02)
    log = io.StringIO()
    bar = ProgressBar("statistics", stream=log)
    assert _wait_for(lambda: "statistics: starting" in log.getvalue())
    bar(3, 3)  # the chunks are done, the work goes on: still a line every interval
    assert _wait_for(lambda: "statistics: 3/3" in log.getvalue().split("left\n")[-1])
    assert "still working" in log.getvalue()
    bar.close()
    time.sleep(0.1)  # let a beat in flight finish
    written = log.getvalue()
    time.sleep(0.2)
    assert log.getvalue() == written


def test_a_dropped_bar_stops_writing(monkeypatch):
    monkeypatch.setattr(progress, "LOG_INTERVAL_S", 0.02)
    log = io.StringIO()
    ProgressBar("render", stream=log)(1, 2)
    gc.collect()
    time.sleep(0.1)
    written = log.getvalue()
    time.sleep(0.2)
    assert log.getvalue() == written


def test_a_terminal_gets_no_still_working_lines(monkeypatch):
    monkeypatch.setattr(progress, "LOG_INTERVAL_S", 0.02)
    screen = _Terminal()
    bar = ProgressBar("detect", stream=screen)
    time.sleep(0.2)
    assert screen.getvalue() == ""
    bar(1, 1)


def test_the_time_left_follows_the_pace_after_a_slow_start(monkeypatch):
    # A fake clock, not a measured speed: the first of ten units takes 100 s (compiling
    # kernels), the others 1 s each; the estimate waits for a second report, then gives
    # 8 units × 1 s, not 8 × 50 s.
    clock = iter([0.0, 100.0, 101.0])
    monkeypatch.setattr(progress.time, "monotonic", lambda: next(clock))
    screen = _Terminal()
    bar = ProgressBar("ptv", stream=screen)
    bar(1, 10)
    assert screen.getvalue().endswith("100 s elapsed,    ? s left")
    bar(2, 10)
    assert screen.getvalue().endswith("101 s elapsed,    8 s left")
