"""docs/python.md runs as written: its ```python blocks, in order, in one fresh namespace
inside an empty working folder, each printing the ```text block that follows it."""

import contextlib
import io
import re
import traceback
from pathlib import Path

DOC = Path(__file__).resolve().parents[2] / "docs" / "python.md"

#: A python block, and the text block right after it (blank lines between), if any.
BLOCK = re.compile(r"```python\n(.*?)```[ \t]*\n(?:\s*```text\n(.*?)```)?", re.S)


def _blocks() -> list[tuple[str, str | None]]:
    """(code, expected output or None) of every python block of the page, in order."""
    return [(code, expected) for code, expected in BLOCK.findall(DOC.read_text("utf-8"))]


def test_the_page_has_three_tasks_of_blocks():
    text = DOC.read_text("utf-8")
    assert len(re.findall(r"^## \d\. ", text, re.M)) == 3
    assert len(_blocks()) >= 3
    assert text.count("```python") == len(_blocks())


def test_every_block_runs_and_prints_what_the_page_shows(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    namespace: dict = {"__name__": "__python_doc__"}
    for number, (code, expected) in enumerate(_blocks(), start=1):
        out = io.StringIO()
        try:
            with contextlib.redirect_stdout(out):
                exec(compile(code, f"docs/python.md block {number}", "exec"), namespace)
        except Exception:
            raise AssertionError(
                f"docs/python.md, python block {number} failed:\n{traceback.format_exc()}"
            ) from None
        if expected is not None:
            printed = [line.rstrip() for line in out.getvalue().rstrip().splitlines()]
            shown = [line.rstrip() for line in expected.rstrip().splitlines()]
            assert printed == shown, (
                f"docs/python.md, python block {number} printed\n"
                + "\n".join(printed)
                + "\nwhere the page shows\n"
                + "\n".join(shown)
            )
