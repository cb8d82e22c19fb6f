"""A code's 3-D points in its own frame numbers, mapped onto a dataset's frames.

The export numbers each exposure for the code (docs/export.md): OpenPTV's frame
numbers run from 10001, MyPTV's frame indices from 0, and in both the frame pairs of one
Δt follow each other, frame a of snapshot m at offset 2m and frame b at 2m + 1
(:func:`validation.export.openptv.frame_number`, :func:`validation.export.myptv.frame_index`);
frame n of a recording is at offset n − first (:func:`validation.export.openptv.recorded_number`).
So one integer, the number of offset 0, inverts either layout: offset = number − origin.

Track ids: where the code linked its points (OpenPTV's ``ptv_is`` files, a MyPTV
trajectory file), the points it linked carry one code track id. For frame pairs only the
a → b step of a snapshot is a displacement, so a track of the positions file is one
snapshot's part of a code track (the positions of one (Δt, snapshot) with the same code
id); every point the code left unlinked gets a track of its own. For a recording the
code's tracks are kept whole.
"""

from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = [
    "CodePoints",
    "Frames",
    "Numbering",
    "positions_csv",
    "read_frames",
    "tracks_csv",
]

#: Millimetres per metre: OpenPTV and MyPTV write mm.
MM_PER_M = 1000.0


@dataclass(frozen=True, eq=False)
class CodePoints:
    """The 3-D points of one input: one Δt's run of the code, or one recording's.

    Attributes
    ----------
    source : Path
        The input (a folder or a file).
    number : ndarray of int, shape (N,)
        The code's frame number of each point.
    xyz : ndarray, shape (N, 3)
        Positions, m.
    track : ndarray of int, shape (N,)
        The code's track id of each point, −1 where it linked none.
    where : tuple of str
        ``<file> line <L>`` of each point, for messages.
    linked : bool
        Whether the input holds the code's links at all.
    """

    source: Path
    number: np.ndarray
    xyz: np.ndarray
    track: np.ndarray
    where: tuple[str, ...]
    linked: bool


@dataclass(frozen=True)
class Numbering:
    """How a code numbers the exported frames.

    Attributes
    ----------
    name : str
        What the code calls the number, for messages.
    origin : int
        The number of offset 0: frame a of snapshot 0, or the first recorded frame.
    """

    name: str
    origin: int


@dataclass(frozen=True)
class Frames:
    """The frames of a dataset that a code's numbers map to.

    Attributes
    ----------
    folder : Path
        The dataset.
    snapshots : tuple of int
        Frame pairs per Δt (frame pairs).
    first, last : int or None
        The recorded frames of a time-resolved recording; None for frame pairs.
    """

    folder: Path
    snapshots: tuple[int, ...]
    first: int | None = None
    last: int | None = None

    @property
    def recording(self) -> bool:
        """Whether the dataset is a time-resolved recording."""
        return self.first is not None


def read_frames(folder: str | Path) -> Frames:
    """The frames of the dataset ``folder`` (its experiment.json; images not needed).

    Raises
    ------
    ValueError
        No such folder, the top of a recorded dataset (name one recording,
        ``sequence<s>``), a missing or malformed experiment.json: one line naming it.
    """
    from ptv.io.dataset import open_dataset

    folder = Path(folder)
    if not folder.is_dir():
        raise ValueError(f"--dataset {folder}: no such folder")
    if (folder / "sequence0").is_dir():
        raise ValueError(
            f"--dataset {folder}: a recorded dataset; name the recording the code tracked, "
            f"e.g. {folder / 'sequence0'}"
        )
    try:
        dataset = open_dataset(folder, check_files=False)
    except FileNotFoundError as err:
        raise ValueError(f"--dataset {folder}: {err}") from None
    if dataset.sequence is not None:
        return Frames(folder, tuple(dataset.frames), dataset.sequence.first, dataset.sequence.last)
    return Frames(folder, tuple(dataset.frames))


def _table(points: list[CodePoints]) -> tuple[np.ndarray, ...]:
    """Every input's points stacked: input index, number, xyz, code track, where."""
    index = np.concatenate([np.full(len(p.number), i) for i, p in enumerate(points)])
    number = np.concatenate([p.number for p in points])
    xyz = np.concatenate([p.xyz for p in points])
    track = np.concatenate([p.track for p in points])
    where = [w for p in points for w in p.where]
    return index, number, xyz, track, where


def _fresh_ids(groups: np.ndarray, linked: np.ndarray) -> np.ndarray:
    """Track ids from 0: one per distinct row of ``groups`` where ``linked``, one per
    point elsewhere."""
    out = np.empty(len(linked), dtype=np.int64)
    if linked.any():
        _, inverse = np.unique(groups[linked], axis=0, return_inverse=True)
        out[linked] = inverse.reshape(-1)
        start = int(inverse.max()) + 1
    else:
        start = 0
    out[~linked] = start + np.arange(np.count_nonzero(~linked))
    return out


def _check_once_per_frame(keys: np.ndarray, linked: np.ndarray, where: list, what: str) -> None:
    """No code track holds two points of one frame (``keys``: track key and frame)."""
    rows = np.flatnonzero(linked)
    if not rows.size:
        return
    _, first, counts = np.unique(keys[rows], axis=0, return_index=True, return_counts=True)
    if (counts > 1).any():
        key = keys[rows][first[np.argmax(counts > 1)]]
        twice = rows[np.flatnonzero((keys[rows] == key).all(axis=1))]
        raise ValueError(
            f"{where[twice[1]]}: {what} {key[-2]} holds a second point in this frame "
            f"(the first at {where[twice[0]]}); a track has one point per frame"
        )


def _pair_rows(points: list[CodePoints], frames: Frames, numbering: Numbering):
    """(k, m, frame b?, xyz, track or None, where) of frame-pair inputs."""
    if len(points) > len(frames.snapshots):
        raise ValueError(
            f"--input: {len(points)} inputs, but {frames.folder} has "
            f"{len(frames.snapshots)} Δt (one input per Δt, in the order of Δt_0, Δt_1, …)"
        )
    k, number, xyz, track, where = _table(points)
    offset = number - numbering.origin
    m, b = offset // 2, offset % 2
    count = np.asarray(frames.snapshots)[k]
    bad = np.flatnonzero((offset < 0) | (m >= count))
    if bad.size:
        i = bad[0]
        last = numbering.origin + 2 * count[i] - 1
        raise ValueError(
            f"{where[i]}: {numbering.name} {number[i]} is no exposure of Δt_{k[i]} of "
            f"{frames.folder} ({numbering.origin} … {last}: {count[i]} frame pairs, a then b; "
            "docs/export.md)"
        )
    if not any(p.linked for p in points):
        return k, m, b, xyz, None, where
    linked = track >= 0
    _check_once_per_frame(np.column_stack([k, m, track, b]), linked, where, "code track")
    ids = _fresh_ids(np.column_stack([k, m, track]), linked)
    return k, m, b, xyz, ids, where


def _number(value: float) -> str:
    """A coordinate as the shortest text that reads back to the same float."""
    return repr(float(value))


def positions_csv(
    points: list[CodePoints], frames: Frames, numbering: Numbering
) -> tuple[str, dict]:
    """The positions file of docs/score.md §1 from the inputs of a frame-pair dataset.

    Parameters
    ----------
    points : list of CodePoints
        One per Δt, in order (Δt_0 first); fewer than the dataset's Δt leave the rest out.
    frames : Frames
        The dataset's frames (frame pairs).
    numbering : Numbering
        The code's frame numbers.

    Returns
    -------
    (str, dict)
        The CSV text (``dt,snapshot,frame,x,y,z`` and ``track`` where an input holds
        links; rows by Δt, snapshot, frame) and a summary: ``positions``, ``frames``,
        ``dt`` (the Δt indices given), ``links`` (a → b links; None without a track
        column).

    Raises
    ------
    ValueError
        More inputs than Δt, a number that is no exposure of its Δt, a code track with
        two points in one frame: one line naming the file and the line.
    """
    k, m, b, xyz, ids, _ = _pair_rows(points, frames, numbering)
    order = np.lexsort((b, m, k))
    header = "dt,snapshot,frame,x,y,z" + (",track" if ids is not None else "")
    lines = [header]
    for i in order:
        coordinates = ",".join(_number(v) for v in xyz[i])
        row = f"{k[i]},{m[i]},{'ab'[b[i]]},{coordinates}"
        lines.append(row + (f",{ids[i]}" if ids is not None else ""))
    links = None
    if ids is not None:
        keys = np.column_stack([k, m, ids])
        _, counts = np.unique(keys, axis=0, return_counts=True)
        links = int(np.count_nonzero(counts == 2))
    summary = {
        "positions": len(k),
        "frames": len(np.unique(np.column_stack([k, m, b]), axis=0)),
        "dt": sorted({int(v) for v in k}),
        "links": links,
    }
    return "\n".join(lines) + "\n", summary


def tracks_csv(points: list[CodePoints], frames: Frames, numbering: Numbering) -> tuple[str, dict]:
    """The tracks file of docs/score.md §11 from the input of a recording.

    Parameters
    ----------
    points : list of CodePoints
        One input: the code's points of the recording, with their links.
    frames : Frames
        The recording's frames.
    numbering : Numbering
        The code's frame numbers.

    Returns
    -------
    (str, dict)
        The CSV text (``track,frame,x,y,z``, rows by track then frame; ``frame`` the
        recording's frame number n; a point the code left unlinked is a track of one
        point, as in synptv's own tracks.csv) and a summary: ``points``, ``tracks``,
        ``linked_tracks`` (of two points or more), ``frames``.

    Raises
    ------
    ValueError
        Not one input, an input without links, a number outside the recording, a code
        track with two points in one frame: one line naming the file and the line.
    """
    if len(points) != 1:
        raise ValueError(
            f"--input: {len(points)} inputs, but a recording ({frames.folder}) takes one"
        )
    (p,) = points
    if not p.linked:
        raise ValueError(
            f"--input {p.source}: no links (OpenPTV: no ptv_is.<number> files; MyPTV: a "
            "particles file, not a trajectory file), and a recording is scored by its tracks"
        )
    _, number, xyz, track, where = _table(points)
    n = frames.first + (number - numbering.origin)
    bad = np.flatnonzero((n < frames.first) | (n > frames.last))
    if bad.size:
        i = bad[0]
        raise ValueError(
            f"{where[i]}: {numbering.name} {number[i]} is recorded frame {n[i]}, outside "
            f"{frames.folder}'s frames {frames.first} … {frames.last} ({numbering.name}s "
            f"{numbering.origin} … {numbering.origin + frames.last - frames.first}; "
            "docs/export.md)"
        )
    linked = track >= 0
    _check_once_per_frame(np.column_stack([track, n]), linked, where, "code track")
    ids = _fresh_ids(track[:, None], linked)
    order = np.lexsort((n, ids))
    lines = ["track,frame,x,y,z"] + [
        f"{ids[i]},{n[i]}," + ",".join(_number(v) for v in xyz[i]) for i in order
    ]
    _, lengths = np.unique(ids, return_counts=True)
    summary = {
        "points": len(n),
        "tracks": len(lengths),
        "linked_tracks": int(np.count_nonzero(lengths >= 2)),
        "frames": len(np.unique(n)),
    }
    return "\n".join(lines) + "\n", summary
