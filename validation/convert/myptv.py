"""MyPTV's 3-D particles and trajectories (MyPTV's user manual, its ``save_results``).

Every file is a whitespace- (tab-) separated table, one point per line, lengths in mm
in the frame of the calibration (the dataset's world frame for an export,
docs/export.md), the frame index in the last column (MyPTV's index of the image in
the sorted image folder, from 0; ``synptv export --format myptv`` names the images so
that frame a of snapshot m is 2m and frame b 2m + 1, per Δt: ``frames.csv``):

- the particles file of the matching step: ``x y z``, the blob index in each camera
  (−1 for none), the triangulation error, the frame index;
- the trajectory file of the tracking step: the trajectory id (−1: a particle the
  tracker did not link), ``x y z``, the blob indices, the error, the frame index
  (older versions: ``id x y z frame``);
- the smoothed (or stitched) trajectory file: ``id x y z vx vy vz ax ay az frame``.

The kind is told by the first column: MyPTV writes a trajectory id as an integer
(``%d``) and a coordinate with decimals (``%.3f``), so a file whose every first field is
an integer is a trajectory file. Of every kind only the id, ``x y z`` and the frame
index are read (a smoothed file's velocities and accelerations are per frame, in MyPTV's
units, and are left out).
"""

import re
from pathlib import Path

import numpy as np

from validation.convert.points import MM_PER_M, CodePoints, Numbering
from validation.score.positions import parse_coordinate, parse_integer

__all__ = ["NUMBERING", "read_myptv"]

#: MyPTV's frame indices of an export.
NUMBERING = Numbering("MyPTV frame index", 0)
#: An integer as MyPTV writes a trajectory id.
INTEGER = re.compile(r"[+-]?\d+")
#: MyPTV's id of a point no trajectory holds.
UNLINKED = -1


def _frame_index(text: str, where: str) -> int:
    """The frame index of the last column (written ``%.3f`` by the matching step)."""
    value = parse_coordinate(text, where)
    if value != int(value) or value < 0:
        raise ValueError(f"{where}: {text!r} is not a frame index (an integer ≥ 0)")
    return int(value)


def read_myptv(path: str | Path) -> CodePoints:
    """MyPTV's points of one run (one Δt): a particles or a trajectory file.

    Parameters
    ----------
    path : path-like
        The file (module docstring; the kind is told by its first column).

    Returns
    -------
    CodePoints
        Every point of the file, in its order; ``linked`` for a trajectory file.

    Raises
    ------
    ValueError
        No such file, no row, a row too short for its kind, a value that is not a
        number, a coordinate that is not finite, a frame index that is not an integer ≥ 0,
        a trajectory id below −1: one line naming the file, the line and the column.

    Examples
    --------
    A trajectory of two points (frames a and b of snapshot 0) and an unlinked point:

    >>> import pathlib, tempfile
    >>> tmp = tempfile.TemporaryDirectory()
    >>> path = pathlib.Path(tmp.name) / "trajectories_dt0"
    >>> _ = path.write_text("0\\t1.000\\t2.000\\t0.500\\t3\\t4\\t0.010\\t0.000\\n"
    ...                     "0\\t1.100\\t2.000\\t0.500\\t2\\t5\\t0.012\\t1.000\\n"
    ...                     "-1\\t9.000\\t2.000\\t0.500\\t7\\t1\\t0.020\\t1.000\\n")
    >>> points = read_myptv(path)
    >>> points.number, points.track, points.linked
    (array([0, 1, 1]), array([ 0,  0, -1]), True)
    >>> tmp.cleanup()
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"--input {path}: no such file (MyPTV's particles or trajectory file)")
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as err:
        raise ValueError(f"{path}: unreadable ({err})") from None
    rows = [
        (n, line.split())
        for n, line in enumerate(text.split("\n"), start=1)
        if line.strip() and not line.lstrip().startswith("#")
    ]
    if not rows:
        raise ValueError(f"{path}: no particles (an empty file)")
    trajectories = all(INTEGER.fullmatch(fields[0]) for _, fields in rows)
    least, columns = (5, "id x y z … frame") if trajectories else (4, "x y z … frame")
    first = 1 if trajectories else 0
    xyz = np.empty((len(rows), 3))
    number = np.empty(len(rows), dtype=np.int64)
    track = np.full(len(rows), UNLINKED, dtype=np.int64)
    for i, (line, fields) in enumerate(rows):
        at = f"{path} line {line}"
        if len(fields) < least:
            raise ValueError(
                f"{at}: expected {columns} ({'a trajectory' if trajectories else 'a particles'} "
                f"file), got {' '.join(fields)!r}"
            )
        for j, axis in enumerate("xyz"):
            xyz[i, j] = parse_coordinate(fields[first + j], f"{at}, column {axis}")
        number[i] = _frame_index(fields[-1], f"{at}, column frame (the last)")
        if trajectories:
            track[i] = parse_integer(fields[0], f"{at}, column id")
            if track[i] < UNLINKED:
                raise ValueError(
                    f"{at}, column id: {track[i]} (a trajectory id ≥ 0, or −1 for none)"
                )
    return CodePoints(
        source=path,
        number=number,
        xyz=xyz / MM_PER_M,
        track=track,
        where=tuple(f"{path} line {line}" for line, _ in rows),
        linked=trajectories,
    )
