"""The public API of ``ptv``: every name in ``ptv.__all__`` resolves, is documented with
examples that run, and ``import ptv`` stays cheap and free of ``simulator``."""

import doctest
import inspect
import subprocess
import sys

import pytest

import ptv

OPTIONS = doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE


def _run_doctests(name: str) -> tuple[int, list[str]]:
    """The examples of ``ptv.<name>`` run in a fresh namespace: (examples, failure reports)."""
    finder = doctest.DocTestFinder(exclude_empty=True)
    runner = doctest.DocTestRunner(optionflags=OPTIONS, verbose=False)
    reports: list[str] = []
    examples = 0
    for test in finder.find(getattr(ptv, name), f"ptv.{name}", globs={}):
        examples += len(test.examples)
        result = runner.run(test, out=reports.append, clear_globs=True)
        assert result.attempted == len(test.examples)
    return examples, reports


@pytest.mark.parametrize("name", ptv.__all__)
def test_examples_run(name):
    examples, failures = _run_doctests(name)
    assert examples > 0, f"ptv.{name} has no examples"
    assert not failures, f"ptv.{name}: failing examples:\n" + "".join(failures)


@pytest.mark.parametrize("name", ptv.__all__)
def test_name_resolves_with_a_docstring(name):
    obj = getattr(ptv, name)
    assert not inspect.ismodule(obj), f"ptv.{name} is a module, not an object of the API"
    doc = inspect.getdoc(obj)
    assert doc and doc.splitlines()[0].strip(), f"ptv.{name} has no one-line summary"
    assert "Examples\n--------" in doc, f"ptv.{name} has no numpydoc Examples section"


def test_package_docstring_lists_every_name_once():
    listed = [line.split()[0] for line in ptv.__doc__.splitlines() if line.startswith(" " * 4)]
    public = [name for name in listed if name in ptv.__all__]
    assert sorted(public) == sorted(ptv.__all__)
    assert sorted(set(ptv.__all__)) == sorted(ptv.__all__)


def test_dir_lists_the_public_names():
    assert set(ptv.__all__) <= set(dir(ptv))
    with pytest.raises(AttributeError, match="no attribute 'not_a_name'"):
        _ = ptv.not_a_name


def _modules_after(script: str) -> list[str]:
    """Top-level packages of the modules imported by ``script`` in a fresh interpreter."""
    report = "import sys; print(' '.join(sorted({n.split('.')[0] for n in sys.modules})))"
    result = subprocess.run(
        [sys.executable, "-c", f"{script}\n{report}"], capture_output=True, text=True, check=True
    )
    return result.stdout.split()


def test_import_is_cheap_and_free_of_simulator():
    loaded = _modules_after("import ptv")
    assert not {"simulator", "validation"} & set(loaded)
    assert not {"numba", "h5py", "cv2", "scipy"} & set(loaded), "import ptv loads the stack"


def test_the_whole_api_is_free_of_simulator():
    loaded = _modules_after("import ptv\nfor name in ptv.__all__:\n    getattr(ptv, name)")
    assert not {"simulator", "validation"} & set(loaded)
