"""The public API of ``simulator``: every name in ``simulator.__all__`` resolves, is
documented with examples that run, and ``import simulator`` stays cheap and free of
``ptv`` and ``validation``."""

import doctest
import inspect
import subprocess
import sys

import pytest

import simulator

OPTIONS = doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE


def _run_doctests(name: str) -> tuple[int, list[str]]:
    """The examples of ``simulator.<name>`` run in a fresh namespace: (examples, failure
    reports)."""
    finder = doctest.DocTestFinder(exclude_empty=True)
    runner = doctest.DocTestRunner(optionflags=OPTIONS, verbose=False)
    reports: list[str] = []
    examples = 0
    for test in finder.find(getattr(simulator, name), f"simulator.{name}", globs={}):
        examples += len(test.examples)
        result = runner.run(test, out=reports.append, clear_globs=True)
        assert result.attempted == len(test.examples)
    return examples, reports


@pytest.mark.parametrize("name", simulator.__all__)
def test_examples_run(name):
    examples, failures = _run_doctests(name)
    assert examples > 0, f"simulator.{name} has no examples"
    assert not failures, f"simulator.{name}: failing examples:\n" + "".join(failures)


@pytest.mark.parametrize("name", simulator.__all__)
def test_name_resolves_with_a_docstring(name):
    obj = getattr(simulator, name)
    assert not inspect.ismodule(obj), f"simulator.{name} is a module, not an object of the API"
    doc = inspect.getdoc(obj)
    assert doc and doc.splitlines()[0].strip(), f"simulator.{name} has no one-line summary"
    assert "Examples\n--------" in doc, f"simulator.{name} has no numpydoc Examples section"


def test_package_docstring_lists_every_name_once():
    listed = [
        line.split()[0] for line in simulator.__doc__.splitlines() if line.startswith(" " * 4)
    ]
    public = [name for name in listed if name in simulator.__all__]
    assert sorted(public) == sorted(simulator.__all__)
    assert sorted(set(simulator.__all__)) == sorted(simulator.__all__)


def test_dir_lists_the_public_names():
    assert set(simulator.__all__) <= set(dir(simulator))
    with pytest.raises(AttributeError, match="no attribute 'not_a_name'"):
        _ = simulator.not_a_name


def _modules_after(script: str) -> list[str]:
    """Top-level packages of the modules imported by ``script`` in a fresh interpreter."""
    report = "import sys; print(' '.join(sorted({n.split('.')[0] for n in sys.modules})))"
    result = subprocess.run(
        [sys.executable, "-c", f"{script}\n{report}"], capture_output=True, text=True, check=True
    )
    return result.stdout.split()


def test_import_is_cheap_and_free_of_ptv():
    loaded = _modules_after("import simulator")
    assert not {"ptv", "validation"} & set(loaded)
    assert not {"numba", "h5py", "scipy", "trimesh"} & set(loaded), "import simulator loads the lab"


def test_the_whole_api_is_free_of_ptv():
    loaded = _modules_after(
        "import simulator\nfor name in simulator.__all__:\n    getattr(simulator, name)"
    )
    assert not {"ptv", "validation"} & set(loaded)
