"""The public API of each package: every name in its ``__all__`` resolves, is documented
with examples that run, and the package's import stays cheap and keeps the layering
(``ptv`` never imports ``simulator``; ``simulator`` neither ``ptv`` nor ``validation``)."""

import doctest
import importlib
import inspect
import subprocess
import sys

import pytest

OPTIONS = doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE
#: Package → (packages its whole API must not import, heavy libraries ``import`` must not).
PACKAGES = {
    "ptv": ({"simulator", "validation"}, {"numba", "h5py", "cv2", "scipy"}),
    "simulator": ({"ptv", "validation"}, {"numba", "h5py", "scipy", "trimesh"}),
    # validation drives both, but loads neither until a name is used
    "validation": (
        set(),
        {"ptv", "simulator", "numba", "h5py", "cv2", "scipy", "matplotlib", "dask"},
    ),
}
NAMES = [
    (package, name) for package in PACKAGES for name in importlib.import_module(package).__all__
]


def _run_doctests(package: str, name: str) -> tuple[int, list[str]]:
    """The examples of ``package.<name>`` run in a fresh namespace: (examples, failure
    reports)."""
    finder = doctest.DocTestFinder(exclude_empty=True)
    runner = doctest.DocTestRunner(optionflags=OPTIONS, verbose=False)
    reports: list[str] = []
    examples = 0
    obj = getattr(importlib.import_module(package), name)
    for test in finder.find(obj, f"{package}.{name}", globs={}):
        examples += len(test.examples)
        result = runner.run(test, out=reports.append, clear_globs=True)
        assert result.attempted == len(test.examples)
    return examples, reports


@pytest.mark.parametrize(("package", "name"), NAMES)
def test_examples_run(package, name):
    examples, failures = _run_doctests(package, name)
    assert examples > 0, f"{package}.{name} has no examples"
    assert not failures, f"{package}.{name}: failing examples:\n" + "".join(failures)


@pytest.mark.parametrize(("package", "name"), NAMES)
def test_name_resolves_with_a_docstring(package, name):
    obj = getattr(importlib.import_module(package), name)
    assert not inspect.ismodule(obj), f"{package}.{name} is a module, not an object of the API"
    doc = inspect.getdoc(obj)
    assert doc and doc.splitlines()[0].strip(), f"{package}.{name} has no one-line summary"
    assert "Examples\n--------" in doc, f"{package}.{name} has no numpydoc Examples section"


@pytest.mark.parametrize("package", PACKAGES)
def test_package_docstring_lists_every_name_once(package):
    module = importlib.import_module(package)
    listed = [line.split()[0] for line in module.__doc__.splitlines() if line.startswith(" " * 4)]
    public = [name for name in listed if name in module.__all__]
    assert sorted(public) == sorted(module.__all__)
    assert sorted(set(module.__all__)) == sorted(module.__all__)


@pytest.mark.parametrize("package", PACKAGES)
def test_dir_lists_the_public_names(package):
    module = importlib.import_module(package)
    assert set(module.__all__) <= set(dir(module))
    with pytest.raises(AttributeError, match="no attribute 'not_a_name'"):
        _ = module.not_a_name


def _modules_after(script: str) -> set[str]:
    """Top-level packages of the modules imported by ``script`` in a fresh interpreter."""
    report = "import sys; print(' '.join(sorted({n.split('.')[0] for n in sys.modules})))"
    result = subprocess.run(
        [sys.executable, "-c", f"{script}\n{report}"], capture_output=True, text=True, check=True
    )
    return set(result.stdout.split())


@pytest.mark.parametrize("package", PACKAGES)
def test_import_is_cheap_and_keeps_the_layering(package):
    forbidden, heavy = PACKAGES[package]
    loaded = _modules_after(f"import {package}")
    assert not forbidden & loaded
    assert not heavy & loaded, f"import {package} loads {sorted(heavy & loaded)}"
    everything = _modules_after(
        f"import {package}\nfor name in {package}.__all__:\n    getattr({package}, name)"
    )
    assert not forbidden & everything
