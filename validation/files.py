"""Results written as a user can trust them: whole or not at all, JSON without NaN.

A file is written under a temporary name in its folder and renamed into place, so a
reader (or a run interrupted half-way) never sees a partial file.
"""

import json
import os
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
def hold_output_folder(folder: Path | str, command: str) -> Iterator[str | None]:
    """Hold ``folder`` (created if needed) for this process while ``command`` writes in it.

    The lock is a file with the holder's pid, host and command, created exclusively and
    removed on exit, with the folder if this call created it and nothing was written. A
    lock whose process no longer runs on this host is stale: it is taken over, and the
    context yields a line that says so (else None).

    Raises
    ------
    ValueError
        Another running process holds the folder (or one on another host, which cannot
        be checked): the message names it and the lock file.
    """
    folder = Path(folder)
    created = not folder.exists()
    folder.mkdir(parents=True, exist_ok=True)
    lock = folder / LOCK_NAME
    note = None
    while True:
        try:
            handle = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        except FileExistsError:
            holder = _lock_holder(lock)
            who = f"{holder.get('command', 'a synptv command')} (pid {holder.get('pid')})"
            if _running(holder):
                raise ValueError(
                    f"{folder} is in use by {who} on {holder.get('host')}: wait for it to "
                    f"finish or choose another folder (if it is gone, remove {lock})"
                ) from None
            note = f"{folder}: took over the lock of {who}, which no longer runs"
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
        if created and not any(folder.iterdir()):  # failed before writing: leave no trace
            folder.rmdir()


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
