"""Reusable, atomic stages of a run: a stage is redone only when its inputs change.

A stage writes one folder. It is built under a temporary name beside its destination,
``stage.json`` (the SHA-256 key of its inputs, which include the keys of the stages it
reads) and what the build took (wall and CPU seconds, :mod:`validation.workflow.clock`)
are written into it, and it is renamed into place when complete. A later run with
the same key reuses the folder; a different key, or a folder without a readable
``stage.json`` (not made by this module), rebuilds it. An interrupted build leaves only
a hidden temporary folder. A resumable stage's temporary folder is named after its key
(:func:`staging_folder`) and kept: the next run with the same key finds what the builder
had finished there (its chunks) and goes on; any other temporary folder of the stage is
removed. So one output folder serves one run at a time.
"""

import hashlib
import json
import shutil
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from validation.workflow.clock import StageTime, Stopwatch

STAGE_FILE = "stage.json"


def stage_key(inputs: dict) -> str:
    """SHA-256 of the canonical JSON of ``inputs`` (sorted keys), hex."""
    text = json.dumps(inputs, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(text.encode()).hexdigest()


@dataclass(frozen=True)
class StageOutcome:
    """A stage's folder, its key, whether it was reused, and what its build took (None:
    a stage built before its times were kept)."""

    folder: Path
    key: str
    reused: bool
    time: StageTime | None = None


def staging_folder(folder: Path, key: str) -> Path:
    """Where a resumable stage of key ``key`` is built: ``staging_folder(...) / folder.name``."""
    folder = Path(folder)
    return folder.parent / f".{folder.name}.partial-{key[:16]}"


def is_built(folder: Path, key: str) -> bool:
    """Whether ``folder`` holds the complete stage of key ``key``."""
    return Path(folder).is_dir() and _recorded_key(Path(folder)) == key


def _recorded_key(folder: Path) -> str | None:
    try:
        return json.loads((folder / STAGE_FILE).read_text())["key"]
    except (OSError, ValueError, KeyError):
        return None


def _recorded_time(folder: Path) -> StageTime | None:
    """What the build of the stage in ``folder`` took, as its ``stage.json`` says."""
    try:
        built = json.loads((folder / STAGE_FILE).read_text())["built"]
        return StageTime(float(built["wall_s"]), float(built["cpu_s"]), reused=True)
    except (OSError, ValueError, KeyError, TypeError):
        return None


def run_stage(
    folder: Path,
    inputs: dict,
    build: Callable[[Path], None],
    *,
    name: str,
    resume: bool = False,
) -> StageOutcome:
    """Reuse ``folder`` if it was built from the same inputs, else build it atomically.

    Parameters
    ----------
    folder : Path
        The stage's output folder.
    inputs : dict
        JSON-able description of everything the output depends on.
    build : callable(Path)
        Writes the stage's files under the path it is given, which does not exist yet
        (the builder creates it: a folder); with ``resume``, it may exist, holding what
        an interrupted build of the same inputs left.
    name : str
        The stage's name, recorded beside the key.
    resume : bool
        Build in :func:`staging_folder`, kept when the build is interrupted.

    Returns
    -------
    StageOutcome
    """
    folder = Path(folder)
    key = stage_key(inputs)
    if is_built(folder, key):
        return StageOutcome(folder, key, reused=True, time=_recorded_time(folder))
    folder.parent.mkdir(parents=True, exist_ok=True)
    keep = staging_folder(folder, key) if resume else None
    for stale in folder.parent.glob(f".{folder.name}.partial-*"):
        if stale != keep:
            shutil.rmtree(stale, ignore_errors=True)
    if keep is not None:
        keep.mkdir(exist_ok=True)
        staging = keep
    else:
        staging = Path(tempfile.mkdtemp(prefix=f".{folder.name}.partial-", dir=folder.parent))
    try:
        target = staging / folder.name
        with Stopwatch() as watch:
            build(target)
        built = watch.time.as_dict()
        del built["reused"]
        record = {"stage": name, "key": key, "inputs": inputs, "built": built}
        (target / STAGE_FILE).write_text(json.dumps(record, indent=2))
        if folder.exists():
            shutil.rmtree(folder)
        target.rename(folder)
        shutil.rmtree(staging, ignore_errors=True)
    finally:
        if keep is None:
            shutil.rmtree(staging, ignore_errors=True)
    return StageOutcome(folder, key, reused=False, time=watch.time)
