"""Progress on a terminal redraws one line; in a log it writes a few plain lines."""

import io

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
