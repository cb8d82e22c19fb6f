"""Another code's 3-D positions, read for ``synptv score`` and checked row by row.

A CSV file has the header ``dt,snapshot,frame,x,y,z`` (any order; an optional ``track``
column; other columns are ignored), one position per line::

    dt        the Δt index k of the dataset (0 … K − 1)
    snapshot  the frame-pair index m (0 … M − 1)
    frame     a (t) or b (t + Δt_k)
    x, y, z   the position, m, in the dataset's world frame
    track     an integer track id (positions with the same id in frames a and b of one
              snapshot at one Δt are one link)

An HDF5 file holds the same columns as 1-D datasets of equal length, at its root or in
a group ``positions`` (``frame`` as strings ``a``/``b``); a ``results.h5`` of ``synptv
ptv`` holds its matched points there. Every error names the file and the line (CSV,
counting the header as line 1) or the row (HDF5, from 0) and the column, in one line.
"""

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from simulator.particles import Box

#: The columns every positions file needs.
COLUMNS = ("dt", "snapshot", "frame", "x", "y", "z")
#: A position this many half-sizes of the sheet from its centre is in other units.
UNIT_SLIP = 100.0
#: The HDF5 group that holds the columns, when not the root.
HDF5_GROUP = "positions"


@dataclass(frozen=True, eq=False)
class Positions:
    """The rows of a positions file.

    Attributes
    ----------
    path : Path
        The file.
    k : ndarray of int, shape (N,)
        Δt index.
    snapshot : ndarray of int, shape (N,)
        Snapshot index m.
    frame : ndarray of int, shape (N,)
        0 for frame a, 1 for frame b.
    xyz : ndarray, shape (N, 3)
        Positions, m.
    track : ndarray of int, shape (N,), or None
        Track ids (None when not read).
    lines : ndarray of int, shape (N,), or None
        The CSV line of each row (None for HDF5, whose rows are named by index).
    """

    path: Path
    k: np.ndarray
    snapshot: np.ndarray
    frame: np.ndarray
    xyz: np.ndarray
    track: np.ndarray | None
    lines: np.ndarray | None

    def where(self, row: int, column: str) -> str:
        """``<file> line L, column C`` (CSV) or ``<file> row R, column C`` (HDF5)."""
        at = f"line {self.lines[row]}" if self.lines is not None else f"row {row}"
        return f"{self.path} {at}, column {column}"


def read_positions(path: str | Path, *, tracks: bool = False) -> Positions:
    """Read a positions file (module docstring): CSV, or HDF5 by its signature.

    Parameters
    ----------
    path : str or Path
        The file.
    tracks : bool
        Read the ``track`` column (then required).

    Returns
    -------
    Positions

    Raises
    ------
    ValueError
        No such file, a missing column, a value that is not a number, an integer, ``a``
        or ``b``, a NaN or infinite coordinate, or no row at all: one line naming the
        file, the line or row and the column.

    Examples
    --------
    Two positions of one particle, frames a and b of snapshot 0 at Δt_0, then a file
    whose coordinate is not a number:

    >>> import pathlib, tempfile
    >>> import validation
    >>> tmp = tempfile.TemporaryDirectory()
    >>> path = pathlib.Path(tmp.name) / "positions.csv"
    >>> _ = path.write_text('''dt,snapshot,frame,x,y,z,track
    ... 0,0,a,0.001,0.002,0.0,7
    ... 0,0,b,0.0011,0.002,0.0,7
    ... ''')
    >>> positions = validation.read_positions(path, tracks=True)
    >>> positions.frame, positions.xyz, positions.track  # 0: a, 1: b; m
    (array([0, 1]), array([[0.001 , 0.002 , 0.    ],
           [0.0011, 0.002 , 0.    ]]), array([7, 7]))
    >>> _ = path.write_text('''dt,snapshot,frame,x,y,z
    ... 0,0,a,1 mm,0,0
    ... ''')
    >>> validation.read_positions(path)
    Traceback (most recent call last):
    ...
    ValueError: .../positions.csv line 2, column x: '1 mm' is not a number
    >>> tmp.cleanup()
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"--positions {path}: no such file")
    columns = (*COLUMNS, "track") if tracks else COLUMNS
    try:
        positions = _read_hdf5(path, columns) if h5py.is_hdf5(path) else _read_csv(path, columns)
    except (OSError, csv.Error) as err:  # a damaged HDF5 file, a NUL byte in a CSV one
        raise ValueError(f"{path}: unreadable ({err})") from None
    if not len(positions.k):
        raise ValueError(f"{path}: no positions (a header and no row)")
    return positions


def parse_integer(text: str, where: str) -> int:
    """``text`` as an integer; a ValueError naming ``where`` if it is not one."""
    try:
        return int(text)
    except ValueError:
        raise ValueError(f"{where}: {text!r} is not an integer") from None


def parse_track_id(text: str, where: str) -> int:
    """A track id read from a file.

    Parameters
    ----------
    text : str
        The field as written.
    where : str
        File and line, for the message.

    Returns
    -------
    int
        The id, ≥ 0 (the scorer keeps −1 for "no track"); a Python int, so that ids
        beyond 2⁵³ stay apart.

    Raises
    ------
    ValueError
        Not an integer, or negative; the message names ``where``.
    """
    value = parse_integer(text, where)
    if value < 0:
        raise ValueError(
            f"{where}: track id {value} is negative (track ids must be integers ≥ 0)"
        )
    return value


def parse_coordinate(text: str, where: str) -> float:
    """``text`` as a finite number; a ValueError naming ``where`` if it is not one."""
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"{where}: {text!r} is not a number") from None
    if not math.isfinite(value):
        raise ValueError(f"{where}: {text.strip()} (every coordinate must be a finite number)")
    return value


def _frame(text: str, where: str) -> int:
    if text.strip() not in ("a", "b"):
        raise ValueError(f"{where}: frame {text!r}, expected a or b")
    return "ab".index(text.strip())


def read_csv_rows(
    path: Path,
    columns: tuple[str, ...],
    parse: dict,
    optional: tuple[tuple[str, ...], ...] = (),
) -> tuple[list[str], list[list], list[int]]:
    """The parsed rows of a CSV file whose header names its columns (any order).

    Parameters
    ----------
    path : Path
        The file.
    columns : tuple of str
        Columns every row needs; a missing one is an error naming line 1.
    parse : dict of str to callable(text, where)
        Parser of a column (default :func:`parse_coordinate`), raising a one-line
        ValueError that names ``where``.
    optional : tuple of tuples of str
        Groups of columns read when the header has every column of the group.

    Returns
    -------
    names : list of str
        The columns read, in the order of each row's values.
    rows : list of lists
        The parsed values of every non-blank line.
    lines : list of int
        The line of each row (the header is line 1).
    """
    with open(path, newline="", encoding="utf-8-sig", errors="replace") as stream:
        reader = csv.reader(stream)
        header = [name.strip() for name in next(reader, [])]
        for name in columns:
            if name not in header:
                raise ValueError(
                    f"{path} line 1: no column {name!r} (the header has "
                    f"{', '.join(header) or 'nothing'}; needs {', '.join(columns)})"
                )
        names = [*columns, *(n for group in optional if set(group) <= set(header) for n in group)]
        index = [header.index(name) for name in names]
        rows, lines = [], []
        for row in reader:
            if not row or all(not cell.strip() for cell in row):
                continue
            line = reader.line_num
            if len(row) != len(header):
                raise ValueError(
                    f"{path} line {line}: {len(row)} values for the {len(header)} columns "
                    "of the header"
                )
            rows.append(
                [
                    parse.get(name, parse_coordinate)(row[i], f"{path} line {line}, column {name}")
                    for name, i in zip(names, index, strict=True)
                ]
            )
            lines.append(line)
    return names, rows, lines


def _read_csv(path: Path, columns: tuple[str, ...]) -> Positions:
    """The rows of a CSV positions file (module docstring)."""
    parse = {
        "dt": parse_integer,
        "snapshot": parse_integer,
        "frame": _frame,
        "track": parse_track_id,
    }
    _, rows, lines = read_csv_rows(path, columns, parse)
    table = np.array(rows, dtype=object).reshape(-1, len(columns))
    return Positions(
        path=path,
        k=table[:, 0].astype(np.int64),
        snapshot=table[:, 1].astype(np.int64),
        frame=table[:, 2].astype(np.int64),
        xyz=table[:, 3:6].astype(np.float64),
        track=table[:, 6].astype(np.int64) if "track" in columns else None,
        lines=np.asarray(lines, dtype=np.int64),
    )


def _hdf5_column(group: h5py.Group, name: str, path: Path) -> np.ndarray:
    """One column of an HDF5 positions file, checked for its kind of values."""
    where = f"{path}: {group.name.rstrip('/')}/{name}"
    if name not in group or not isinstance(group[name], h5py.Dataset):
        raise ValueError(f"{path}: no column {name!r} (a 1-D dataset in {group.name})")
    values = group[name][()]
    if values.ndim != 1:
        raise ValueError(f"{where}: a column must be 1-D, this one has shape {values.shape}")
    kind = values.dtype.kind
    if name == "frame":
        if kind not in "SUO":
            raise ValueError(f"{where}: frames must be the strings a or b, got {values.dtype}")
        text = np.array([v.decode() if isinstance(v, bytes) else str(v) for v in values])
        bad = np.flatnonzero(~np.isin(text, ["a", "b"]))
        if bad.size:
            raise ValueError(
                f"{path} row {bad[0]}, column frame: {text[bad[0]]!r}, expected a or b"
            )
        return (text == "b").astype(np.int64)
    if name in ("dt", "snapshot", "track"):
        if kind not in "iu":
            raise ValueError(f"{where}: must hold integers, holds {values.dtype}")
        if name == "track" and values.size and values.min() < 0:
            bad = int(np.argmin(values))
            raise ValueError(
                f"{path} row {bad}, column track: track id {values[bad]} is negative (track "
                "ids must be integers ≥ 0)"
            )
        return values.astype(np.int64)
    if kind not in "iuf":
        raise ValueError(f"{where}: must hold numbers, holds {values.dtype}")
    values = values.astype(np.float64)
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        raise ValueError(
            f"{path} row {bad[0]}, column {name}: {values[bad[0]]} "
            "(every coordinate must be a finite number)"
        )
    return values


def _read_hdf5(path: Path, columns: tuple[str, ...]) -> Positions:
    """The rows of an HDF5 positions file (module docstring)."""
    with h5py.File(path, "r") as f:
        group = f[HDF5_GROUP] if isinstance(f.get(HDF5_GROUP), h5py.Group) else f
        if group is f and f.attrs.get("format") == "synptv-ptv-results":
            raise ValueError(
                f"{path}: a results.h5 without its matched points (written before synptv "
                "ptv kept them): run synptv ptv again"
            )
        data = {name: _hdf5_column(group, name, path) for name in columns}
    lengths = {name: len(v) for name, v in data.items()}
    if len(set(lengths.values())) > 1:
        raise ValueError(
            f"{path}: columns of different lengths ("
            + ", ".join(f"{name} {n}" for name, n in lengths.items())
            + ")"
        )
    return Positions(
        path=path,
        k=data["dt"],
        snapshot=data["snapshot"],
        frame=data["frame"],
        xyz=np.stack([data["x"], data["y"], data["z"]], axis=1),
        track=data.get("track"),
        lines=None,
    )


def check_positions(positions: Positions, *, n_dt: int, snapshots: int, sheet: Box) -> None:
    """Check the rows against the dataset: Δt and snapshot indices, units, track ids.

    Parameters
    ----------
    positions : Positions
        The rows.
    n_dt : int
        Δt of the dataset, K.
    snapshots : int
        Snapshots per Δt, M.
    sheet : Box
        The dataset's laser sheet, m (its rig's ``[sheet]``).

    Raises
    ------
    ValueError
        The first row with an unknown Δt or snapshot index, positions that are not in
        metres (none lies in the laser sheet and their median distance from its centre
        is over :data:`UNIT_SLIP` times its half-size), or a track id given twice in one
        frame; one line naming the file, the row and the column.

    Examples
    --------
    Positions in mm where m are asked for lie nowhere near the sheet:

    >>> import pathlib, tempfile
    >>> import simulator, validation
    >>> tmp = tempfile.TemporaryDirectory()
    >>> path = pathlib.Path(tmp.name) / "positions.csv"
    >>> _ = path.write_text('''dt,snapshot,frame,x,y,z
    ... 0,0,a,10.0,20.0,1.0
    ... 0,0,b,11.0,20.0,1.0
    ... ''')
    >>> positions = validation.read_positions(path)
    >>> sheet = simulator.Box((0.1, 0.1, 0.01))  # the dataset's laser sheet, m
    >>> validation.check_positions(positions, n_dt=5, snapshots=40, sheet=sheet)
    Traceback (most recent call last):
    ...
    ValueError: .../positions.csv line 2, column x, y, z: no position lies in the 100 × 100
    × 10 mm laser sheet ... positions must be in metres (are these in mm?)
    >>> tmp.cleanup()
    """
    for column, values, count, what in (
        ("dt", positions.k, n_dt, "Δt"),
        ("snapshot", positions.snapshot, snapshots, "snapshots per Δt"),
    ):
        bad = np.flatnonzero((values < 0) | (values >= count))
        if bad.size:
            raise ValueError(
                f"{positions.where(bad[0], column)}: {values[bad[0]]} is not an index of the "
                f"dataset, which has {count} {what} (0 … {count - 1})"
            )
    _check_units(positions, sheet)
    if positions.track is not None:
        key = np.stack([positions.k, positions.snapshot, positions.frame, positions.track], axis=1)
        _, first, count = np.unique(key, axis=0, return_index=True, return_counts=True)
        if (count > 1).any():
            seen = {tuple(row) for row in key[first[count > 1]]}
            row = next(i for i in range(len(key)) if tuple(key[i]) in seen and i not in first)
            raise ValueError(
                f"{positions.where(row, 'track')}: track {positions.track[row]} appears twice "
                f"in frame {'ab'[positions.frame[row]]} of snapshot {positions.snapshot[row]} "
                f"at Δt index {positions.k[row]} (a track is one position per frame)"
            )


def _check_units(positions: Positions, sheet: Box) -> None:
    """Refuse positions that are not in metres (see :func:`check_positions`)."""
    half = np.asarray(sheet.size) / 2
    reach = np.max(np.abs(positions.xyz - np.asarray(sheet.centre)) / half, axis=1)
    median = float(np.median(reach))
    if np.all(reach > 1) and median > UNIT_SLIP:
        size = " × ".join(f"{v * 1e3:g}" for v in sheet.size)
        raise ValueError(
            f"{positions.where(0, 'x, y, z')}: no position lies in the {size} mm laser "
            f"sheet and half of them lie over {median:.3g} times its half-size from its "
            "centre: positions must be in metres (are these in mm?)"
        )
