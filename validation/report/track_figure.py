"""The picture of the tracks of a time-resolved recording (``synptv ptv --tracks``).

Left, the tracks seen along the sheet normal (x–y, mm), each a line coloured by its mean
z; right, how many tracks have each length. Only tracks of two points or more are
drawn, at most :data:`MAX_DRAWN` of them (the longest), so that a long recording stays
readable.
"""

import os
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure

from ptv.tracking.linking import RecordingTracks
from validation.report.png import save_figure

__all__ = ["MAX_DRAWN", "TRACKS_FIGURE", "save_tracks_figure", "tracks_figure"]

#: File name written by :func:`save_tracks_figure`.
TRACKS_FIGURE = "tracks.png"
#: Most tracks drawn in the x–y panel.
MAX_DRAWN = 3000


def _drawn_tracks(recording: RecordingTracks) -> list[np.ndarray]:
    """The points (L, 3), m, of the longest tracks of two points or more."""
    tracks = recording.tracks
    lengths = tracks.lengths
    order = np.argsort(-lengths, kind="stable")
    chosen = order[lengths[order] >= 2][:MAX_DRAWN]
    starts = np.concatenate([[0], np.cumsum(lengths)])
    return [tracks.positions[starts[t] : starts[t + 1]] for t in np.sort(chosen)]


def tracks_figure(recording: RecordingTracks) -> Figure:
    """Tracks in x–y coloured by mean z, and the histogram of track lengths."""
    figure, (left, right) = plt.subplots(1, 2, figsize=(11, 4.8), width_ratios=(1.2, 1))
    lines = _drawn_tracks(recording)
    tracks = recording.tracks
    first, last = recording.numbers[0], recording.numbers[-1]
    if lines:
        depth = np.array([line[:, 2].mean() * 1e3 for line in lines])
        collection = LineCollection(
            [line[:, :2] * 1e3 for line in lines], array=depth, cmap="viridis", linewidths=0.8
        )
        left.add_collection(collection)
        left.autoscale()
        figure.colorbar(collection, ax=left, label="mean z (mm)")
    else:
        left.text(0.5, 0.5, "no track of two points or more", ha="center", transform=left.transAxes)
    left.set_aspect("equal", adjustable="datalim")
    left.set_xlabel("x (mm)")
    left.set_ylabel("y (mm)")
    longer = int(np.count_nonzero(tracks.lengths >= 2))
    left.set_title(
        f"{len(lines)} of {longer} tracks of ≥ 2 points, frames {first} … {last}", fontsize=10
    )
    lengths = tracks.lengths
    if lengths.size:
        counts = np.bincount(lengths)[1:]
        right.bar(np.arange(1, counts.size + 1), counts, width=1.0, color="tab:blue")
        right.set_yscale("log")
    right.set_xlabel("track length (points)")
    right.set_ylabel("tracks")
    mean = f"{len(tracks) / tracks.n_tracks:.1f}" if tracks.n_tracks else "–"
    right.set_title(f"{tracks.n_tracks} tracks, mean length {mean} points", fontsize=10)
    figure.tight_layout()
    return figure


def save_tracks_figure(recording: RecordingTracks, folder: str | os.PathLike) -> Path:
    """Write :data:`TRACKS_FIGURE` into ``folder``; returns its path."""
    return save_figure(tracks_figure(recording), Path(folder) / TRACKS_FIGURE)
