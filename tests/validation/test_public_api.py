"""The public API of ``validation``: every name in ``validation.__all__`` resolves, is
documented with examples that run, and ``import validation`` stays cheap."""

import doctest
import inspect
import subprocess
import sys

import pytest

import validation

OPTIONS = doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE


def _run_doctests(name: str) -> tuple[int, list[str]]:
    """The examples of ``validation.<name>`` run in a fresh namespace: (examples, failure
    reports)."""
    finder = doctest.DocTestFinder(exclude_empty=True)
    runner = doctest.DocTestRunner(optionflags=OPTIONS, verbose=False)
    reports: list[str] = []
    examples = 0
    for test in finder.find(getattr(validation, name), f"validation.{name}", globs={}):
        examples += len(test.examples)
        result = runner.run(test, out=reports.append, clear_globs=True)
        assert result.attempted == len(test.examples)
    return examples, reports


@pytest.mark.parametrize("name", validation.__all__)
def test_examples_run(name):
    examples, failures = _run_doctests(name)
    assert examples > 0, f"validation.{name} has no examples"
    assert not failures, f"validation.{name}: failing examples:\n" + "".join(failures)


@pytest.mark.parametrize("name", validation.__all__)
def test_name_resolves_with_a_docstring(name):
    obj = getattr(validation, name)
    assert not inspect.ismodule(obj), f"validation.{name} is a module, not an object of the API"
    doc = inspect.getdoc(obj)
    assert doc and doc.splitlines()[0].strip(), f"validation.{name} has no one-line summary"
    assert "Examples\n--------" in doc, f"validation.{name} has no numpydoc Examples section"


def test_package_docstring_lists_every_name_once():
    listed = [
        line.split()[0] for line in validation.__doc__.splitlines() if line.startswith(" " * 4)
    ]
    public = [name for name in listed if name in validation.__all__]
    assert sorted(public) == sorted(validation.__all__)
    assert sorted(set(validation.__all__)) == sorted(validation.__all__)


def test_dir_lists_the_public_names():
    assert set(validation.__all__) <= set(dir(validation))
    with pytest.raises(AttributeError, match="no attribute 'not_a_name'"):
        _ = validation.not_a_name


def _modules_after(script: str) -> list[str]:
    """Top-level packages of the modules imported by ``script`` in a fresh interpreter."""
    report = "import sys; print(' '.join(sorted({n.split('.')[0] for n in sys.modules})))"
    result = subprocess.run(
        [sys.executable, "-c", f"{script}\n{report}"], capture_output=True, text=True, check=True
    )
    return result.stdout.split()


def test_import_is_cheap():
    loaded = _modules_after("import validation")
    assert not {"ptv", "simulator"} & set(loaded), "import validation loads the stack"
    assert not {"numba", "h5py", "cv2", "scipy", "matplotlib", "dask"} & set(loaded)
