"""``tracks.csv``: the tracks of a time-resolved recording as text (:mod:`ptv.pipeline.results`
writes the same rows to ``/tracks`` of results.h5); ``tracks_fitted.csv`` and
``tracks_fit.json``: their fit; and the temporary names every result file is written
under before it is renamed into place."""

import json
import logging
import math
import os
import uuid
from pathlib import Path

import numpy as np

__all__ = ["save_fitted_tracks_csv", "save_tracks_csv", "temporary_path"]

log = logging.getLogger(__name__)


def temporary_path(folder: Path, name: str) -> Path:
    """A fresh temporary name beside the target (created with the usual permissions)."""
    return folder / f".{name}.{os.getpid()}.{uuid.uuid4().hex[:12]}.partial"


def _write_rows(path: Path, columns: list, header: str) -> None:
    """A CSV of ``columns`` under ``header`` (track and frame as integers, the rest to
    nine digits), written under a temporary name and renamed."""
    tmp = temporary_path(path.parent, path.name)
    try:
        np.savetxt(
            tmp,
            np.column_stack(columns),
            fmt=["%d", "%d"] + ["%.9g"] * (len(columns) - 2),
            delimiter=",",
            header=header,
            comments="",
        )
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


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
    _write_rows(path, columns, "track,frame,time_s,x,y,z")
    log.info("tracks written to %s", path)
    return path


def _json_ready(value):
    """``value`` with every non-finite float as None (JSON has no NaN)."""
    if isinstance(value, dict):
        return {k: _json_ready(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json_ready(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def save_fitted_tracks_csv(result, track_fit, folder: str | os.PathLike) -> Path:
    """Write ``tracks_fitted.csv`` and ``tracks_fit.json`` into ``folder``: the fit of the
    tracks of the recording of ``result``
    (:func:`ptv.pipeline.track_fit.fit_recording`, ``track_fit``).

    One row per fitted point (the points of tracks too short to fit and the outliers are
    left out), sorted by track then frame, under the header
    ``track,frame,time_s,x,y,z,vx,vy,vz,ax,ay,az,sigma_x,sigma_v,sigma_a``: the fitted
    position (m, calibration's frame), velocity (m/s), acceleration (m/s²) and their
    standard errors per component from the noise. The JSON holds
    :meth:`ptv.pipeline.track_fit.FittedRecording.as_dict`.

    Returns
    -------
    Path
        The CSV file.
    """
    fit = track_fit.fitted
    order = np.lexsort((fit.frame, fit.track))
    columns = [
        fit.track[order],
        fit.frame[order],
        fit.frame[order] / result.recording.frame_rate,
        *fit.position[order].T,
        *fit.velocity[order].T,
        *fit.acceleration[order].T,
        fit.position_error[order],
        fit.velocity_error[order],
        fit.acceleration_error[order],
    ]
    path = Path(folder) / "tracks_fitted.csv"
    header = "track,frame,time_s,x,y,z,vx,vy,vz,ax,ay,az,sigma_x,sigma_v,sigma_a"
    _write_rows(path, columns, header)
    text = json.dumps(_json_ready(track_fit.as_dict()), indent=2, allow_nan=False)
    (Path(folder) / "tracks_fit.json").write_text(text)
    log.info("fitted tracks written to %s", path)
    return path
