"""``tracks.csv``: the tracks of a time-resolved recording as text (:mod:`ptv.pipeline.results`
writes the same rows to ``/tracks`` of results.h5), and the temporary names every result
file is written under before it is renamed into place."""

import logging
import os
import uuid
from pathlib import Path

import numpy as np

__all__ = ["save_tracks_csv", "temporary_path"]

log = logging.getLogger(__name__)


def temporary_path(folder: Path, name: str) -> Path:
    """A fresh temporary name beside the target (created with the usual permissions)."""
    return folder / f".{name}.{os.getpid()}.{uuid.uuid4().hex[:12]}.partial"


def save_tracks_csv(result, folder: str | os.PathLike) -> Path:
    """Write ``tracks.csv`` into ``folder``: the tracks of the recording of ``result`` (a
    :class:`ptv.pipeline.double_frame.PtvResult`).

    One row per matched point of every frame tracked, sorted by track then frame, under
    the header ``track,frame,time_s,x,y,z`` (frame number, n / frame_rate in s, the
    point in m in the calibration's frame).

    Raises
    ------
    ValueError
        The result has no recording.
    """
    recording = result.recording
    if recording is None:
        raise ValueError("the result holds no tracks (not a time-resolved recording)")
    path = Path(folder) / "tracks.csv"
    tracks = recording.tracks
    columns = [tracks.track, recording.frame_number, recording.time, *tracks.positions.T]
    tmp = temporary_path(path.parent, path.name)
    try:
        np.savetxt(
            tmp,
            np.column_stack(columns),
            fmt=["%d", "%d", "%.9g", "%.9g", "%.9g", "%.9g"],
            delimiter=",",
            header="track,frame,time_s,x,y,z",
            comments="",
        )
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    log.info("tracks written to %s", path)
    return path
