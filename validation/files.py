"""Results written as a user can trust them: whole or not at all, JSON without NaN.

A file is written under a temporary name in its folder and renamed into place, so a
reader (or a run interrupted half-way) never sees a partial file.
"""

import json
import os
import tempfile
from pathlib import Path

import numpy as np


def as_json(value: object) -> object:
    """A JSON round trip: tuples become lists, NumPy numbers floats, NaN and inf None."""

    def convert(v):
        if isinstance(v, dict):
            return {str(k): convert(x) for k, x in v.items()}
        if isinstance(v, list | tuple | np.ndarray):
            return [convert(x) for x in v]
        if isinstance(v, np.generic):
            v = v.item()
        if isinstance(v, float) and not np.isfinite(v):
            return None
        return v

    return json.loads(json.dumps(convert(value), allow_nan=False))


def write_text_atomic(path: Path, text: str) -> Path:
    """Write ``text`` to ``path`` under a temporary name, then rename it into place."""
    path = Path(path)
    handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
    try:
        with os.fdopen(handle, "w") as stream:
            stream.write(text)
        os.chmod(temporary, 0o644)  # mkstemp makes it private; results are for sharing
        os.replace(temporary, path)
    finally:
        if os.path.exists(temporary):
            os.remove(temporary)
    return path


def write_json_atomic(path: Path, value: object) -> Path:
    """:func:`write_text_atomic` of ``value`` as indented JSON (NaN written as null)."""
    return write_text_atomic(path, json.dumps(as_json(value), indent=2) + "\n")


def check_output_folder(path: Path | str, option: str = "--out") -> Path:
    """``path`` as a folder that can be created or written, checked before any work.

    Raises
    ------
    ValueError
        Naming ``option`` and the path: it is a file, lies under a file, or its nearest
        existing folder cannot be written.
    """
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise ValueError(f"{option} {path} is a file, not a folder")
    existing = path
    while not existing.exists():
        if existing.parent == existing:
            break
        existing = existing.parent
    if not existing.is_dir():
        raise ValueError(f"{option} {path} lies under {existing}, which is a file")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise ValueError(f"{option} {path}: {existing} is not writable")
    return path
