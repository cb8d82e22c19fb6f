"""OpenPTV's 3-D particles and links: its ``res/rt_is.<number>`` and ``ptv_is.<number>``
files (liboptv's ``write_path_frame``; pyptv and optv write the same).

``rt_is.<number>``: the first line the particle count, then one particle per line,
``id x y z c1 c2 c3 c4``: the 1-based row number, the position in mm in the frame of
the calibration (the dataset's world frame for an export, docs/export.md) and the target
index of the particle in each camera's image (−1 for none; four columns whatever the
number of cameras). ``ptv_is.<number>``: the same count, then per particle, in the same
order, ``prev next x y z``: its row (from 0) in the previous and the next frame's files,
−1 (prev) or −2 (next) for none, and the position again. ``<number>`` is OpenPTV's frame
number, as ``synptv export --format openptv`` numbered the images (``frames.csv``:
10001 + 2m for frame a of snapshot m and one more for frame b, per Δt; 10001 + n − first
for frame n of a recording).

Links are read from ``next``: a point's next row in the file of the next number. Every
point linked to carries the id of the chain it belongs to (:mod:`validation.convert.points`
keeps the a → b steps of frame pairs, the whole chains of a recording).
"""

import re
from pathlib import Path

import numpy as np

from validation.convert.points import MM_PER_M, CodePoints, Numbering
from validation.export.openptv import FIRST_NUMBER
from validation.score.positions import parse_coordinate, parse_integer

__all__ = ["NUMBERING", "read_openptv", "read_ptv_is", "read_rt_is"]

#: OpenPTV's frame numbers of an export.
NUMBERING = Numbering("OpenPTV frame number", FIRST_NUMBER)
#: File names: rt_is.<number>, ptv_is.<number>.
RT_IS = re.compile(r"rt_is\.(\d+)")
PTV_IS = re.compile(r"ptv_is\.(\d+)")
#: ptv_is: no previous (−1) and no next (−2) particle.
PREV_NONE, NEXT_NONE = -1, -2


def _rows(path: Path) -> tuple[int, list[tuple[int, list[str]]]]:
    """The count of line 1 and the (line number, fields) of every other non-blank line."""
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as err:
        raise ValueError(f"{path}: unreadable ({err})") from None
    lines = text.split("\n")
    head = lines[0].split()
    if len(head) != 1:
        raise ValueError(f"{path} line 1: expected the particle count, got {lines[0]!r}")
    count = parse_integer(head[0], f"{path} line 1, the particle count")
    rows = [(n, line.split()) for n, line in enumerate(lines[1:], start=2) if line.strip()]
    if count != len(rows):
        raise ValueError(f"{path} line 1: says {count} particles, holds {len(rows)}")
    return count, rows


def read_rt_is(path: str | Path) -> tuple[np.ndarray, list[int]]:
    """The particles of one ``rt_is.<number>`` file (module docstring).

    Parameters
    ----------
    path : path-like
        The file.

    Returns
    -------
    (ndarray, list of int)
        Positions (N, 3) in m, in the file's order, and the line of each.

    Raises
    ------
    ValueError
        A first line that is not the count, a count that is not the number of rows, a
        row without ``id x y z``, an id that is not an integer, a coordinate that is not
        a finite number: one line naming the file, the line and the column.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> tmp = tempfile.TemporaryDirectory()
    >>> path = pathlib.Path(tmp.name) / "rt_is.10001"
    >>> _ = path.write_text("2\\n   1    22.159    41.050     9.228  128  131   -1   -1\\n"
    ...                     "   2   -21.890    35.455    11.032  187  181   -1   -1\\n")
    >>> xyz, lines = read_rt_is(path)
    >>> xyz[0], lines  # m
    (array([0.022159, 0.04105 , 0.009228]), [2, 3])
    >>> tmp.cleanup()
    """
    path = Path(path)
    _, rows = _rows(path)
    xyz = np.empty((len(rows), 3))
    for i, (line, fields) in enumerate(rows):
        if len(fields) < 4:
            raise ValueError(
                f"{path} line {line}: expected id x y z and a target index per camera, got "
                f"{' '.join(fields)!r}"
            )
        parse_integer(fields[0], f"{path} line {line}, column id")
        for j, axis in enumerate("xyz"):
            xyz[i, j] = parse_coordinate(fields[1 + j], f"{path} line {line}, column {axis}")
    return xyz / MM_PER_M, [line for line, _ in rows]


def read_ptv_is(path: str | Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[int]]:
    """The links of one ``ptv_is.<number>`` file (module docstring).

    Returns
    -------
    (ndarray, ndarray, ndarray, list of int)
        ``prev`` and ``next`` rows (N,), the positions (N, 3) in m, the line of each.

    Raises
    ------
    ValueError
        As :func:`read_rt_is`, for rows ``prev next x y z``.
    """
    path = Path(path)
    _, rows = _rows(path)
    links = np.empty((len(rows), 2), dtype=np.int64)
    xyz = np.empty((len(rows), 3))
    for i, (line, fields) in enumerate(rows):
        if len(fields) < 5:
            raise ValueError(
                f"{path} line {line}: expected prev next x y z, got {' '.join(fields)!r}"
            )
        for j, name in enumerate(("prev", "next")):
            links[i, j] = parse_integer(fields[j], f"{path} line {line}, column {name}")
        for j, axis in enumerate("xyz"):
            xyz[i, j] = parse_coordinate(fields[2 + j], f"{path} line {line}, column {axis}")
    return links[:, 0], links[:, 1], xyz / MM_PER_M, [line for line, _ in rows]


def _numbered(folder: Path, pattern: re.Pattern) -> dict[int, Path]:
    """Files of ``folder`` whose whole name matches ``pattern``, by their number."""
    found = {}
    for path in folder.iterdir():
        match = pattern.fullmatch(path.name)
        if match and path.is_file():
            found[int(match.group(1))] = path
    return found


#: Positions of rt_is and ptv_is rows that are one particle agree to this, m (both
#: files print mm to three decimals).
SAME_POSITION = 1e-6


def read_openptv(path: str | Path) -> CodePoints:
    """OpenPTV's particles of one sequence (one Δt, or one recording), with its links.

    Parameters
    ----------
    path : path-like
        The folder of the ``rt_is.<number>`` files (OpenPTV's ``res``, or the working
        folder that holds it); ``ptv_is.<number>`` files beside them carry the links.

    Returns
    -------
    CodePoints
        Every particle of every rt_is file, numbers in increasing order.

    Raises
    ------
    ValueError
        No such folder, no rt_is file, a bad row (:func:`read_rt_is`,
        :func:`read_ptv_is`), a ptv_is file whose count or positions differ from its
        rt_is file's, a ``next`` row beyond the next file's particles, a file of the
        next number missing, or a particle that two particles link to: one line
        naming the file, the line and the column.

    Examples
    --------
    Frame a and frame b of snapshot 0, one particle linked from a to b:

    >>> import pathlib, tempfile
    >>> tmp = tempfile.TemporaryDirectory()
    >>> res = pathlib.Path(tmp.name)
    >>> _ = (res / "rt_is.10001").write_text("1\\n 1 1.0 2.0 0.5 3 4 -1 -1\\n")
    >>> _ = (res / "rt_is.10002").write_text("1\\n 1 1.1 2.0 0.5 2 5 -1 -1\\n")
    >>> _ = (res / "ptv_is.10001").write_text("1\\n -1 0 1.0 2.0 0.5\\n")
    >>> _ = (res / "ptv_is.10002").write_text("1\\n 0 -2 1.1 2.0 0.5\\n")
    >>> points = read_openptv(res)
    >>> points.number, points.track, points.xyz[:, 0]  # m
    (array([10001, 10002]), array([0, 0]), array([0.001 , 0.0011]))
    >>> tmp.cleanup()
    """
    folder = Path(path)
    if not folder.is_dir():
        raise ValueError(f"--input {folder}: no such folder (OpenPTV's res folder)")
    rt_is = _numbered(folder, RT_IS)
    if not rt_is and (folder / "res").is_dir():
        folder = folder / "res"
        rt_is = _numbered(folder, RT_IS)
    if not rt_is:
        raise ValueError(f"--input {folder}: no rt_is.<number> files (OpenPTV's res folder)")
    ptv_is = _numbered(folder, PTV_IS)
    numbers = sorted(rt_is)
    frames = {n: read_rt_is(rt_is[n]) for n in numbers}
    nexts = {n: _links(ptv_is[n], rt_is[n], *frames[n]) for n in numbers if n in ptv_is}
    track = {n: np.full(len(frames[n][0]), -1, dtype=np.int64) for n in numbers}
    claimed: dict[int, dict[int, int]] = {}
    count = 0
    for n in numbers:
        if n not in nexts:
            continue
        ahead, lines = nexts[n]
        for i in np.flatnonzero(ahead >= 0):
            where = f"{ptv_is[n]} line {lines[i]}, column next"
            if n + 1 not in frames:
                raise ValueError(
                    f"{where}: links to row {ahead[i]} of rt_is.{n + 1}, which is missing"
                )
            if ahead[i] >= len(frames[n + 1][0]):
                raise ValueError(
                    f"{where}: links to row {ahead[i]} of rt_is.{n + 1}, which holds "
                    f"{len(frames[n + 1][0])} particles (rows from 0)"
                )
            earlier = claimed.setdefault(n + 1, {}).get(int(ahead[i]))
            if earlier is not None:
                raise ValueError(
                    f"{where}: row {ahead[i]} of rt_is.{n + 1} is linked from line {earlier} "
                    "already (a particle has one predecessor)"
                )
            claimed[n + 1][int(ahead[i])] = lines[i]
            if track[n][i] < 0:
                track[n][i] = count
                count += 1
            track[n + 1][ahead[i]] = track[n][i]
    where = tuple(f"{rt_is[n]} line {line}" for n in numbers for line in frames[n][1])
    return CodePoints(
        source=Path(path),
        number=np.concatenate([np.full(len(frames[n][0]), n, dtype=np.int64) for n in numbers]),
        xyz=np.concatenate([frames[n][0] for n in numbers]),
        track=np.concatenate([track[n] for n in numbers]),
        where=where,
        linked=bool(nexts),
    )


def _links(path: Path, rt_path: Path, xyz: np.ndarray, _lines) -> tuple[np.ndarray, list[int]]:
    """The ``next`` rows of a ptv_is file, checked against its rt_is file."""
    _, ahead, positions, lines = read_ptv_is(path)
    if len(ahead) != len(xyz):
        raise ValueError(
            f"{path} line 1: {len(ahead)} particles, but {rt_path.name} holds {len(xyz)}"
        )
    off = np.flatnonzero(np.abs(positions - xyz).max(axis=1, initial=0.0) > SAME_POSITION)
    if off.size:
        i = off[0]
        raise ValueError(
            f"{path} line {lines[i]}: x y z differ from row {i} of {rt_path.name} (the rows "
            "of ptv_is and rt_is are the same particles, in the same order)"
        )
    bad = np.flatnonzero((ahead < 0) & (ahead != NEXT_NONE) & (ahead != PREV_NONE))
    if bad.size:
        i = bad[0]
        raise ValueError(
            f"{path} line {lines[i]}, column next: {ahead[i]} (a row from 0, or −2 for none)"
        )
    return ahead, lines
