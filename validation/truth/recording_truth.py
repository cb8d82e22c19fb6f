"""``truth.h5`` of a rendered recording: every particle at every frame (ptv never reads it).

A recording's folder (``dataset/sequence<s>/``, :mod:`validation.run.render_recording`)
holds its truth beside its images. Layout (lengths in m, times in s, pixels as OpenCV)::

    /                       attrs: format_version, rig (the rig's JSON)
    /flow, /cameras         as in :mod:`validation.truth.truth_file`
    /recording              attrs: frame_rate, frames (F), sequence, seeds
        times (F,)                      frame times from 0
        frame_start (F + 1,)            rows of frame f: frame_start[f] … frame_start[f+1]
        particle, frame (N,)            particle id and frame index of each row, rows
                                        sorted by frame, then particle
        position, velocity, acceleration (N, 3)   exact X, u and Lagrangian a, float64
        <camera>/xy (N, 2)              exact image of the particle centre, px, float32,
                                        NaN where not imaged
        <camera>/visible (N,)           lit and on the sensor

The particle arrays are written when the file is created; the image positions chunk of
frames by chunk of frames as they are rendered, each chunk recorded as done once
written (``/progress/chunks``, deleted when complete), so an interrupted render resumes.
"""

import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from simulator.recording import RecordedParticles
from simulator.rigs import Rig, rig_from_dict
from validation.truth.truth_file import FORMAT_VERSION

_PROGRESS = "progress"


@dataclass(frozen=True, eq=False)
class RecordingTruth:
    """The truth of one recording, one row per particle and frame in the sheet.

    Attributes
    ----------
    rig : Rig
        The cameras and sheet the recording was rendered with.
    frame_rate : float
        Hz.
    times : ndarray, shape (F,)
        s.
    particle, frame : ndarray of int, shape (N,)
        Rows sorted by frame, then particle.
    position, velocity, acceleration : ndarray, shape (N, 3)
        m, m/s, m/s².
    xy : dict of str to ndarray, shape (N, 2)
        Exact image of each particle per camera, px.
    visible : dict of str to ndarray of bool, shape (N,)
        Lit and on the camera's sensor.
    """

    rig: Rig
    frame_rate: float
    times: np.ndarray
    particle: np.ndarray
    frame: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    xy: dict
    visible: dict

    def imaged_by(self, cameras: int) -> np.ndarray:
        """Rows that at least ``cameras`` cameras image, shape (N,) of bool."""
        return np.sum(list(self.visible.values()), axis=0) >= cameras


def frame_chunks(frames: int, size: int) -> list[tuple[int, int]]:
    """Frame ranges (f0, f1) of at most ``size`` frames covering 0 … frames − 1."""
    return [(f0, min(f0 + size, frames)) for f0 in range(0, frames, size)]


class RecordingTruthWriter:
    """Creates or continues a recording's truth.h5; every call opens and closes it.

    Parameters
    ----------
    path : Path
        The file.
    cameras : sequence of str
        Camera names.
    chunks : sequence of (int, int)
        The frame ranges rendered one at a time.
    """

    def __init__(self, path: Path, cameras: Sequence[str], chunks: Sequence[tuple[int, int]]):
        self.path = Path(path)
        self.cameras = list(cameras)
        self.chunks = list(chunks)

    def started(self) -> bool:
        """Whether the file holds the particles (else it is removed, to be created)."""
        if not self.path.exists():
            return False
        try:
            with h5py.File(self.path, "r") as f:
                if f.attrs.get("format_version") == FORMAT_VERSION and _PROGRESS in f:
                    return True
        except OSError:
            pass
        self.path.unlink()  # unreadable (killed while writing): start again
        return False

    def create(
        self,
        recorded: RecordedParticles,
        frame_rate: float,
        sequence: int,
        header: Callable[[h5py.File], None],
    ) -> None:
        """Write the header and every particle-frame of ``recorded``."""
        order = np.lexsort((recorded.particle, recorded.frame))
        frames = len(recorded.times)
        frame = recorded.frame[order]
        start = np.searchsorted(frame, np.arange(frames + 1))
        with h5py.File(self.path, "w") as f:
            f.attrs["format_version"] = FORMAT_VERSION
            header(f)
            g = f.create_group("recording")
            g.attrs.update(
                frame_rate=frame_rate, frames=frames, sequence=sequence, seeds=recorded.seeds
            )
            g["times"] = recorded.times
            g["frame_start"] = start
            for key, value in (
                ("particle", recorded.particle[order]),
                ("frame", frame),
                ("position", recorded.position[order]),
                ("velocity", recorded.velocity[order]),
                ("acceleration", recorded.acceleration[order]),
            ):
                g.create_dataset(key, data=value, compression="gzip", compression_opts=1)
            rows = len(frame)
            for camera in self.cameras:
                g.create_dataset(
                    f"{camera}/xy", shape=(rows, 2), dtype=np.float32, fillvalue=np.nan
                )
                g.create_dataset(f"{camera}/visible", shape=(rows,), dtype=bool)
            f.create_group(_PROGRESS)["chunks"] = np.zeros(len(self.chunks), bool)

    def todo(self) -> list[int]:
        """Indices of the chunks not written yet."""
        with h5py.File(self.path, "r") as f:
            return [int(i) for i in np.flatnonzero(~f[_PROGRESS]["chunks"][:])]

    def positions(self, i: int) -> list[np.ndarray]:
        """The particle positions of each frame of chunk i, (P_f, 3) each."""
        f0, f1 = self.chunks[i]
        with h5py.File(self.path, "r") as f:
            start = f["recording/frame_start"][f0 : f1 + 1]
            x = f["recording/position"][start[0] : start[-1]]
        return np.split(x, start[1:-1] - start[0])

    def write_chunk(self, i: int, xy: dict, visible: dict) -> None:
        """Chunk i's image positions (rows, 2) and flags (rows,) per camera."""
        f0, f1 = self.chunks[i]
        with h5py.File(self.path, "a") as f:
            g = f["recording"]
            start = g["frame_start"]
            rows = slice(int(start[f0]), int(start[f1]))
            for camera in self.cameras:
                g[f"{camera}/xy"][rows] = xy[camera]
                g[f"{camera}/visible"][rows] = visible[camera]
            f[_PROGRESS]["chunks"][i] = True

    def finish(self) -> None:
        """Check every chunk is written and drop the record of parts."""
        missing = self.todo()
        if missing:
            raise RuntimeError(f"{self.path}: {len(missing)} chunks of frames missing")
        with h5py.File(self.path, "a") as f:
            del f[_PROGRESS]


def read_recording_truth(path: str | Path) -> RecordingTruth:
    """A recording's truth from its truth.h5 (or the folder holding it).

    Raises
    ------
    ValueError
        No truth.h5, another format version, or not a recording's.
    """
    path = Path(path)
    if path.is_dir():
        path = path / "truth.h5"
    if not path.is_file():
        raise ValueError(
            f"{path.parent} has no truth.h5: scoring tracks needs a rendered recording"
        )
    with h5py.File(path, "r") as f:
        version = f.attrs.get("format_version")
        if version != FORMAT_VERSION:
            raise ValueError(
                f"{path}: truth format version {version}, this synptv reads {FORMAT_VERSION}"
            )
        if "recording" not in f:
            raise ValueError(f"{path}: the truth of frame pairs, not of a recording")
        g = f["recording"]
        rig = rig_from_dict(json.loads(f.attrs["rig"]), source=str(path))
        cameras = rig.camera_names
        return RecordingTruth(
            rig=rig,
            frame_rate=float(g.attrs["frame_rate"]),
            times=g["times"][:],
            particle=g["particle"][:],
            frame=g["frame"][:],
            position=g["position"][:],
            velocity=g["velocity"][:],
            acceleration=g["acceleration"][:],
            xy={c: g[f"{c}/xy"][:] for c in cameras},
            visible={c: g[f"{c}/visible"][:] for c in cameras},
        )
