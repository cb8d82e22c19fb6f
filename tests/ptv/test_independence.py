"""The PTV stack runs on real images: no module of ``ptv`` imports ``simulator`` or
``validation``, directly or through another module."""

import pkgutil
import subprocess
import sys

import ptv


def test_ptv_imports_neither_simulator_nor_validation():
    modules = sorted(
        m.name for m in pkgutil.walk_packages(ptv.__path__, prefix="ptv.") if not m.ispkg
    )
    script = (
        "import importlib, sys\n"
        f"for name in {modules!r}:\n"
        "    importlib.import_module(name)\n"
        "bad = sorted(n for n in sys.modules if n.split('.')[0] in ('simulator', 'validation'))\n"
        "print(' '.join(bad))\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, check=True
    )
    assert len(modules) > 20
    assert result.stdout.strip() == "", f"ptv pulls in: {result.stdout.strip()}"
