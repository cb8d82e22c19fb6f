"""Results written as a user can trust them: whole or not at all, JSON without NaN.

A file is written under a temporary name in its folder and renamed into place, so a
reader (or a run interrupted half-way) never sees a partial file.
"""

import json
import os
import shutil
import socket
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
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


#: The file that marks an output folder as held by a running command.
LOCK_NAME = ".synptv.lock"


@contextmanager
def hold_lock(lock: Path | str, command: str, held: Path) -> Iterator[str | None]:
    """Hold the lock file ``lock`` of the folder ``held`` while ``command`` runs.

    The lock holds the holder's pid, host and command; it is created exclusively and
    removed on exit. A lock whose process no longer runs on this host is stale: it is
    taken over, and the context yields a line that says so (else None).

    Raises
    ------
    ValueError
        Another running process holds the lock (or one on another host, which cannot be
        checked): the message names it and the lock file.
    """
    lock = Path(lock)
    note = None
    while True:
        try:
            handle = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        except FileExistsError:
            holder = _lock_holder(lock)
            who = f"{holder.get('command', 'a synptv command')} (pid {holder.get('pid')})"
            if _running(holder):
                raise ValueError(
                    f"{held} is in use by {who} on {holder.get('host')}: wait for it "
                    f"to finish or choose another folder (if it is gone, remove {lock})"
                ) from None
            note = f"{held}: took over the lock of {who}, which no longer runs"
            lock.unlink(missing_ok=True)
            continue
        with os.fdopen(handle, "w") as stream:
            json.dump(
                {"pid": os.getpid(), "host": socket.gethostname(), "command": command}, stream
            )
        break
    try:
        yield note
    finally:
        lock.unlink(missing_ok=True)


@contextmanager
def hold_output_folder(folder: Path | str, command: str) -> Iterator[str | None]:
    """Hold ``folder`` (created if needed) with :func:`hold_lock` on its
    :data:`LOCK_NAME` file while ``command`` writes in it; on exit the folders this call
    created are removed again where nothing was written in them."""
    folder = Path(folder)
    created = [p for p in (folder, *folder.parents) if not p.exists()]
    folder.mkdir(parents=True, exist_ok=True)
    try:
        with hold_lock(folder / LOCK_NAME, command, folder) as note:
            yield note
    finally:
        for path in created:  # failed before writing: leave no trace
            if any(path.iterdir()):
                break
            path.rmdir()


@contextmanager
def hold_new_folder(folder: Path | str, command: str) -> Iterator[str | None]:
    """Hold the name of a folder that must not exist yet (``command`` builds it elsewhere
    and renames it into place): the lock sits beside it, ``.<name>.synptv.lock``.

    Raises
    ------
    ValueError
        ``folder`` exists, or another running command holds its name.
    """
    folder = Path(folder)
    if folder.exists():
        raise ValueError(f"output folder {str(folder)!r} already exists; choose a new one")
    folder.parent.mkdir(parents=True, exist_ok=True)
    with hold_lock(folder.parent / f".{folder.name}{LOCK_NAME}", command, folder) as note:
        yield note


@contextmanager
def staged_output(folder: Path | str) -> Iterator[Path]:
    """A private folder inside ``folder`` for a command to write its files into.

    When the block ends without error, each file is renamed into ``folder`` (replacing
    an earlier one of the same name); when it raises, all are discarded. Either way
    ``folder`` then holds the earlier output or the whole new one, never a mixture
    left by a failure half-way.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=".staging-", dir=folder))
    try:
        yield staging
        for path in sorted(staging.iterdir()):
            os.replace(path, folder / path.name)
    finally:
        shutil.rmtree(staging, ignore_errors=True)


def _lock_holder(lock: Path) -> dict:
    """The lock's holder, {} when the file is unreadable (a holder that died writing it)."""
    try:
        holder = json.loads(lock.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return {}
    return holder if isinstance(holder, dict) else {}


def _running(holder: dict) -> bool:
    """Whether the holder may still run: on another host, assume so."""
    pid = holder.get("pid")
    if not isinstance(pid, int) or isinstance(pid, bool) or pid <= 0:
        return False
    if holder.get("host") != socket.gethostname():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # alive, owned by another user
        return True
    return True
