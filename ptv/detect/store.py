"""Detections of a whole dataset on disk, so that every analysis of its images detects once.

A detection store is a folder::

    detections.json          cameras, Δt, snapshots per Δt, shared first frame, the
                             detector settings, the chunk files (written last: a folder
                             without it is incomplete)
    chunk-<m0>-<m1>.h5       the exposures of snapshots m0 … m1 − 1 (HDF5)

Each chunk file holds ``exposures`` (E, 3) int32 rows (k, m, frame) in the order of
:func:`ptv.detect.frames.exposures` (k = −1 for a frame a shared by every Δt; frame 0 = a,
1 = b) and, per camera, ``<camera>/offsets`` (E + 1,) int64, ``<camera>/xy`` (N, 2)
float64 centres in px (OpenCV convention) and ``<camera>/flags`` (N,) uint8
(:class:`ptv.detect.DetectionFlag`): exposure e's detections are rows
offsets[e]:offsets[e + 1] (``xy`` and ``flags`` compressed without loss: gzip, byte
shuffle). Chunk files are written whole under a temporary name and renamed, so a chunk
that exists is complete.
"""

import json
import os
import uuid
from bisect import bisect_right
from collections.abc import Sequence
from itertools import pairwise
from pathlib import Path

import h5py
import numpy as np

from ptv.detect.frames import ChunkDetections, DetectedCentres, exposures

__all__ = [
    "FORMAT_NAME",
    "DetectionStore",
    "StoreError",
    "chunk_name",
    "write_chunk",
    "write_index",
]

FORMAT_NAME = "synptv-detections"
FORMAT_VERSION = 1
INDEX = "detections.json"


def _compressed(group: h5py.Group, name: str, data: np.ndarray) -> None:
    """A dataset compressed losslessly (byte shuffle and gzip level 1: the centres take
    a fifth less room for ~70 MB/s of writing)."""
    options = {"compression": "gzip", "compression_opts": 1, "shuffle": True} if data.size else {}
    group.create_dataset(name, data=data, **options)


class StoreError(ValueError):
    """A detection store that cannot be read (the message names the file)."""


def chunk_name(m0: int, m1: int) -> str:
    """File name of the chunk of snapshots m0 … m1 − 1."""
    return f"chunk-{m0:06d}-{m1:06d}.h5"


def write_chunk(path: Path, chunk: ChunkDetections, *, frames: Sequence[int]) -> Path:
    """Write one chunk file atomically (temporary name, then rename).

    Parameters
    ----------
    path : Path
        The chunk file (:func:`chunk_name` inside the store folder).
    chunk : ChunkDetections
        Its detections; every exposure of :func:`ptv.detect.frames.exposures` must be there.
    frames : sequence of int
        Frame pairs of the run at each Δt.

    Returns
    -------
    Path
    """
    m0, m1 = chunk.snapshots
    order = exposures(frames, range(m0, m1), shared_first_frame=chunk.shared_first_frame)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{uuid.uuid4().hex[:8]}.partial")
    try:
        with h5py.File(tmp, "w") as f:
            f.attrs["format"] = FORMAT_NAME
            f.attrs["format_version"] = FORMAT_VERSION
            f.attrs["snapshots"] = np.array([m0, m1])
            f.create_dataset(
                "exposures",
                data=np.array([(k, m, "ab".index(fr)) for k, m, fr in order], dtype=np.int32),
            )
            for c, camera in enumerate(chunk.cameras):
                found = [chunk.found[key][c] for key in order]
                sizes = [len(d.xy) for d in found]
                group = f.create_group(camera)
                group.create_dataset("offsets", data=np.concatenate([[0], np.cumsum(sizes)]))
                xy = _stack([d.xy for d in found], (0, 2), np.float64)
                flags = _stack([d.flags for d in found], (0,), np.uint8)
                _compressed(group, "xy", xy)
                _compressed(group, "flags", flags)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    return path


def _stack(arrays: Sequence[np.ndarray], empty: tuple, dtype) -> np.ndarray:
    return np.concatenate(arrays).astype(dtype, copy=False) if arrays else np.empty(empty, dtype)


def _read_chunk(path: Path, cameras: Sequence[str]) -> tuple[tuple[int, int], dict]:
    """The snapshot range (m0, m1) and the detections per exposure of one chunk file.

    Raises
    ------
    StoreError
        Not a chunk file of a detection store, or without one of ``cameras``.
    """
    try:
        with h5py.File(path, "r") as f:
            if f.attrs.get("format") != FORMAT_NAME:
                raise StoreError(f"{path}: not a chunk of a detection store")
            m0, m1 = (int(v) for v in f.attrs["snapshots"])
            rows = f["exposures"][:]
            per_camera = []
            for camera in cameras:
                if camera not in f:
                    raise StoreError(f"{path}: no detections of camera {camera!r}")
                g = f[camera]
                offsets, xy, flags = g["offsets"][:], g["xy"][:], g["flags"][:]
                per_camera.append(
                    [DetectedCentres(xy[a:b], flags[a:b]) for a, b in pairwise(offsets)]
                )
    except OSError as err:
        raise StoreError(f"{path}: not readable as a detection chunk ({err})") from None
    found = {
        (int(k), int(m), "ab"[int(fr)]): [per[e] for per in per_camera]
        for e, (k, m, fr) in enumerate(rows)
    }
    return (m0, m1), found


def write_index(
    folder: Path,
    *,
    cameras: Sequence[str],
    dt: np.ndarray,
    frames: Sequence[int],
    shared_first_frame: bool,
    detector: dict,
    chunks: Sequence[tuple[int, int]],
    source: str,
) -> Path:
    """Write ``detections.json``, which makes the store complete.

    Parameters
    ----------
    folder : Path
        The store.
    cameras, dt, frames, shared_first_frame :
        As :class:`ptv.detect.frames.FrameDetections`.
    detector : dict
        The detector settings (:meth:`ptv.settings.DetectorSettings.as_dict`).
    chunks : sequence of (int, int)
        Snapshot ranges of the chunk files, covering 0 … max(frames) − 1 in order.
    source : str
        The dataset the images came from.
    """
    index = {
        "format": FORMAT_NAME,
        "format_version": FORMAT_VERSION,
        "source": source,
        "cameras": list(cameras),
        "dt": [float(v) for v in dt],
        "frames": [int(v) for v in frames],
        "shared_first_frame": bool(shared_first_frame),
        "detector": detector,
        "chunks": [chunk_name(m0, m1) for m0, m1 in chunks],
    }
    path = Path(folder) / INDEX
    tmp = path.with_name(f".{INDEX}.{os.getpid()}.partial")
    tmp.write_text(json.dumps(index, indent=2) + "\n")
    os.replace(tmp, path)
    return path


class DetectionStore:
    """:class:`ptv.detect.frames.FrameDetections` read from a detection store folder.

    The chunk holding the snapshot asked for is read whole and kept until another
    chunk is asked for, so reading snapshot after snapshot reads each file once.

    Parameters
    ----------
    folder : path-like
        The store (module docstring).

    Raises
    ------
    StoreError
        No ``detections.json`` (an incomplete store), or a malformed one.
    """

    def __init__(self, folder: str | os.PathLike) -> None:
        self.folder = Path(folder)
        path = self.folder / INDEX
        try:
            index = json.loads(path.read_text())
        except FileNotFoundError:
            raise StoreError(
                f"{self.folder} is not a complete detection store: no {INDEX}"
            ) from None
        except (OSError, ValueError) as err:
            raise StoreError(f"{path}: not readable as JSON ({err})") from None
        if not isinstance(index, dict) or index.get("format") != FORMAT_NAME:
            raise StoreError(f"{path}: not the index of a detection store")
        self.cameras = tuple(index["cameras"])
        self.dt = np.asarray(index["dt"], dtype=np.float64)
        self.frames = tuple(int(v) for v in index["frames"])
        self.shared_first_frame = bool(index["shared_first_frame"])
        self.detector = index["detector"]
        self.source = index["source"]
        self._files = [self.folder / name for name in index["chunks"]]
        self._starts = [int(name.split("-")[1]) for name in index["chunks"]]
        self._chunk: ChunkDetections | None = None

    def chunk(self, m: int) -> ChunkDetections:
        """The chunk holding snapshot m."""
        if self._chunk is not None and self._chunk.snapshots[0] <= m < self._chunk.snapshots[1]:
            return self._chunk
        i = bisect_right(self._starts, m) - 1
        if i < 0 or m >= max(self.frames):
            raise IndexError(f"snapshot {m} out of range 0 … {max(self.frames) - 1}")
        snapshots, found = _read_chunk(self._files[i], self.cameras)
        self._chunk = ChunkDetections.of(self, snapshots, found)
        return self._chunk

    def detections(self, k: int, m: int, frame: str) -> list[np.ndarray]:
        """Centres (N_c, 2), px, per camera, of frame ``frame`` of snapshot m at Δt_k."""
        return self.chunk(m).detections(k, m, frame)
