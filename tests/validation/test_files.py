"""Output folders are checked before any work."""

import json
import os
import socket
import subprocess
import sys

import pytest

from validation.cli import main
from validation.workflow.files import (
    LOCK_NAME,
    check_output_folder,
    hold_new_folder,
    hold_output_folder,
    staged_output,
)


def test_output_folders_that_cannot_be_written_are_refused_by_name(tmp_path):
    a_file = tmp_path / "results.txt"
    a_file.write_text("not a folder")
    with pytest.raises(ValueError, match=r"--out .*results.txt is a file"):
        check_output_folder(a_file)
    with pytest.raises(ValueError, match=r"lies under .*results.txt, which is a file"):
        check_output_folder(a_file / "run" / "deeper")
    assert check_output_folder(tmp_path / "new" / "run") == tmp_path / "new" / "run"
    assert not (tmp_path / "new").exists()  # checked, not created


def _dead_pid() -> int:
    """The pid of a process that has exited (and been reaped)."""
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    return child.pid


def test_a_folder_held_by_a_running_command_is_refused(tmp_path):
    with hold_output_folder(tmp_path / "out", "synptv run") as took_over:
        assert took_over is None
        with pytest.raises(ValueError) as error:
            with hold_output_folder(tmp_path / "out", "synptv study planes"):
                pass
        message = str(error.value)
        assert f"in use by synptv run (pid {os.getpid()})" in message and LOCK_NAME in message
    assert not (tmp_path / "out" / LOCK_NAME).exists()  # released on exit


@pytest.mark.parametrize("content", ["dead", "{not json", ""])
def test_a_stale_lock_is_taken_over_and_said(tmp_path, content):
    lock = tmp_path / LOCK_NAME
    if content == "dead":
        content = json.dumps({"pid": _dead_pid(), "host": socket.gethostname(), "command": "x"})
    lock.write_text(content)
    with hold_output_folder(tmp_path, "synptv run") as took_over:
        assert "took over the lock" in took_over and "no longer runs" in took_over
        assert json.loads(lock.read_text())["pid"] == os.getpid()
    assert not lock.exists()


def test_a_lock_from_another_host_is_respected(tmp_path):
    holder = {"pid": os.getpid(), "host": socket.gethostname() + "-elsewhere", "command": "x"}
    (tmp_path / LOCK_NAME).write_text(json.dumps(holder))
    with pytest.raises(ValueError, match="-elsewhere"):
        with hold_output_folder(tmp_path, "synptv run"):
            pass


def test_a_second_run_into_a_held_folder_exits_2_and_touches_nothing(tmp_path, capsys):
    out = tmp_path / "run"
    with hold_output_folder(out, "synptv run"):
        before = sorted(p.name for p in out.iterdir())
        assert main(["run", "--out", str(out), "--quiet"]) == 2
        assert sorted(p.name for p in out.iterdir()) == before
    err = capsys.readouterr().err
    assert "is in use by synptv run" in err and err.count("\n") == 1


def test_a_folder_created_for_nothing_is_removed(tmp_path):
    with pytest.raises(RuntimeError):
        with hold_output_folder(tmp_path / "new" / "out", "synptv run"):
            raise RuntimeError("failed before writing")
    assert sorted(tmp_path.iterdir()) == []  # "new" was created for it too


def test_a_new_folder_is_held_by_its_name_and_must_not_exist(tmp_path):
    (tmp_path / "taken").mkdir()
    with pytest.raises(ValueError, match="already exists"):
        with hold_new_folder(tmp_path / "taken", "synptv render"):
            pass
    with hold_new_folder(tmp_path / "ds", "synptv render"):
        assert not (tmp_path / "ds").exists()  # built elsewhere, renamed into place
        with pytest.raises(ValueError, match="in use by synptv render"):
            with hold_new_folder(tmp_path / "ds", "synptv render"):
                pass
    assert sorted(p.name for p in tmp_path.iterdir()) == ["taken"]


def test_staged_output_replaces_the_old_files_together_or_not_at_all(tmp_path):
    (tmp_path / "results.h5").write_text("old results")
    (tmp_path / "figure.png").write_text("old figure")
    with pytest.raises(RuntimeError):
        with staged_output(tmp_path) as staging:
            (staging / "results.h5").write_text("new results")
            raise RuntimeError("drawing the figure failed")
    assert {p.name: p.read_text() for p in tmp_path.iterdir()} == {
        "results.h5": "old results",
        "figure.png": "old figure",
    }
    with staged_output(tmp_path) as staging:
        (staging / "results.h5").write_text("new results")
        (staging / "figure.png").write_text("new figure")
    assert {p.name: p.read_text() for p in tmp_path.iterdir()} == {
        "results.h5": "new results",
        "figure.png": "new figure",
    }
