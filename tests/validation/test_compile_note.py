"""A command says once that it compiles the numerical kernels, and never when they are
cached (validation/workflow/compile_note.py)."""

import importlib
import os
import sys

from numba import njit

from validation.workflow import compile_note

LINE = "synptv: compiling the numerical kernels once"

KERNEL_MODULE = """
from numba import njit


@njit(cache=True)
def twice(x):
    return 2 * x
"""


def test_the_first_compile_says_it_once(capsys):
    with compile_note.watch():
        njit(lambda x: x + 1)(1)
        njit(lambda x: x - 1)(1.0)
    err = capsys.readouterr().err
    assert err.count(LINE) == 1 and err.startswith(LINE)


def test_quiet_says_nothing(capsys):
    with compile_note.watch(quiet=True):
        njit(lambda x: x + 2)(1)
    assert capsys.readouterr().err == ""


def test_nothing_is_said_once_another_process_said_it(capsys):
    with compile_note.watch():
        marker = os.environ[compile_note.MARKER]
        open(marker, "x").close()  # what a local worker leaves when it compiled first
        njit(lambda x: x + 3)(1)
    assert capsys.readouterr().err == ""
    assert compile_note.MARKER not in os.environ


def test_kernels_loaded_from_the_cache_say_nothing(tmp_path, monkeypatch, capsys):
    (tmp_path / "note_kernel.py").write_text(KERNEL_MODULE)
    monkeypatch.syspath_prepend(str(tmp_path))
    with compile_note.watch():  # a first run: compiled and cached
        assert importlib.import_module("note_kernel").twice(3) == 6
    assert LINE in capsys.readouterr().err
    del sys.modules["note_kernel"]
    with compile_note.watch():  # a later run: a new process would load it the same way
        assert importlib.import_module("note_kernel").twice(4) == 8
    assert capsys.readouterr().err == ""
    del sys.modules["note_kernel"]


def test_a_local_worker_watches_when_its_command_does(monkeypatch, tmp_path):
    registered = []
    monkeypatch.setattr(compile_note.event, "register", lambda *a: registered.append(a))
    monkeypatch.delenv(compile_note.MARKER, raising=False)
    compile_note.dask_setup(None)
    assert registered == []
    monkeypatch.setenv(compile_note.MARKER, str(tmp_path / "said"))
    compile_note.dask_setup(None)
    assert [kind for kind, _ in registered] == ["numba:compile"]
