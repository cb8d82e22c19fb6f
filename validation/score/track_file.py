"""Another code's time-resolved tracks, read and checked row by row.

A CSV file has the header ``track,frame,x,y,z`` (any order; other columns are ignored,
except ``vx,vy,vz`` and ``ax,ay,az``, the velocity and acceleration of a track fit,
which are read when all three are there), one point per line::

    track     an integer track id
    frame     the recording's frame number
    x, y, z   the position, m, in the dataset's world frame
    vx …      m/s;  ax … m/s²

Each track's rows come in increasing frame order, one row per (track, frame), every
value finite. Every error names the file and the line (the header is line 1), in one
line.
"""

import csv
from pathlib import Path

import numpy as np

from validation.score.positions import parse_integer, parse_track_id, read_csv_rows
from validation.score.trajectories import TrackPoints

#: The columns every tracks file needs.
COLUMNS = ("track", "frame", "x", "y", "z")
#: Optional column triples: a fitted velocity and acceleration.
OPTIONAL = (("vx", "vy", "vz"), ("ax", "ay", "az"))


def read_tracks(path: str | Path) -> TrackPoints:
    """Read a tracks CSV file (module docstring).

    Parameters
    ----------
    path : str or Path
        The file.

    Returns
    -------
    TrackPoints

    Raises
    ------
    ValueError
        No such file, a missing column, a value that is not an integer or a finite
        number, a (track, frame) given twice, a track whose frames do not increase, or no
        row: one line naming the file and the line.

    Examples
    --------
    Two tracks, the first with the velocity of a track fit, then a file whose track
    goes back in time:

    >>> import pathlib, tempfile
    >>> import validation
    >>> tmp = tempfile.TemporaryDirectory()
    >>> path = pathlib.Path(tmp.name) / "tracks.csv"
    >>> _ = path.write_text('''track,frame,x,y,z,vx,vy,vz
    ... 0,0,0.0010,0.0,0.0,0.2,0.0,0.0
    ... 0,1,0.0011,0.0,0.0,0.2,0.0,0.0
    ... 3,1,0.0050,0.0,0.0,0.0,-0.1,0.0
    ... ''')
    >>> tracks = validation.read_tracks(path)
    >>> tracks.track, tracks.frame, tracks.velocity[:, 0]  # ids, frames, m/s
    (array([0, 0, 3]), array([0, 1, 1]), array([0.2, 0.2, 0. ]))
    >>> _ = path.write_text('''track,frame,x,y,z
    ... 0,1,0.0010,0.0,0.0
    ... 0,0,0.0011,0.0,0.0
    ... ''')
    >>> validation.read_tracks(path)
    Traceback (most recent call last):
    ...
    ValueError: .../tracks.csv line 3: track 0 frame 0 after frame 1 (each track's frames must
    increase, one row per track and frame)
    >>> tmp.cleanup()
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"--tracks {path}: no such file")
    try:
        names, rows, lines = read_csv_rows(
            path, COLUMNS, {"track": parse_track_id, "frame": parse_integer}, OPTIONAL
        )
    except csv.Error as err:
        raise ValueError(f"{path}: unreadable ({err})") from None
    if not rows:
        raise ValueError(f"{path}: no tracks (a header and no row)")
    # Ids and frames as the integers they were read as: through float64, ids above 2⁵³
    # would merge.
    track = np.array([row[0] for row in rows], dtype=np.int64)
    frame = np.array([row[1] for row in rows], dtype=np.int64)
    table = np.array([row[2:] for row in rows], dtype=np.float64)
    _check_order(track, frame, np.asarray(lines), path)
    extra = [group for group in OPTIONAL if group[0] in names]
    columns = {group: table[:, 3 + 3 * i : 6 + 3 * i] for i, group in enumerate(extra)}
    return TrackPoints(
        track=track,
        frame=frame,
        position=table[:, 0:3],
        velocity=columns.get(OPTIONAL[0]),
        acceleration=columns.get(OPTIONAL[1]),
    )


def _check_order(track: np.ndarray, frame: np.ndarray, lines: np.ndarray, path: Path) -> None:
    """Each track's frames increase in file order (which also makes them unique)."""
    order = np.argsort(track, kind="stable")
    same = track[order][1:] == track[order][:-1]
    step = frame[order][1:] - frame[order][:-1]
    bad = np.flatnonzero(same & (step <= 0))
    if bad.size:
        i = order[bad[0] + 1]
        what = "given twice" if step[bad[0]] == 0 else f"after frame {frame[order][bad[0]]}"
        raise ValueError(
            f"{path} line {lines[i]}: track {track[i]} frame {frame[i]} {what} (each "
            "track's frames must increase, one row per track and frame)"
        )
