"""Detection stores: what is written is read back bit for bit, and an incomplete store is
refused by name."""

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ptv.detect.frames import ChunkDetections, exposures
from ptv.detect.store import (
    DetectionStore,
    StoreError,
    chunk_name,
    write_chunk,
    write_index,
)

CAMERAS = ("cam1", "cam2")


class Found:
    """Detections as the store keeps them: centres and flags."""

    def __init__(self, xy, flags):
        self.xy, self.flags = xy, flags


def _chunk(rng, frames, snapshots, shared):
    found = {}
    for key in exposures(frames, range(*snapshots), shared_first_frame=shared):
        found[key] = []
        for _ in CAMERAS:
            n = int(rng.integers(0, 6))
            found[key].append(
                Found(rng.uniform(-0.5, 2047.5, (n, 2)), rng.integers(0, 32, n).astype(np.uint8))
            )
    dt = np.array([1e-4, 2e-4, 3e-4])[: len(frames)]
    detector = {"threshold_sigmas": 6.0}
    return ChunkDetections(None, CAMERAS, dt, tuple(frames), shared, detector, snapshots, found)


def _write_store(folder, chunks, frames, shared):
    folder.mkdir()
    for chunk in chunks:
        write_chunk(folder / chunk_name(*chunk.snapshots), chunk, frames=frames)
    write_index(
        folder,
        cameras=CAMERAS,
        dt=chunks[0].dt,
        frames=frames,
        shared_first_frame=shared,
        detector={"threshold_sigmas": 6.0, "saturation": 4095.0},
        chunks=[c.snapshots for c in chunks],
        source="here",
    )
    return DetectionStore(folder)


@settings(max_examples=25, deadline=None)
@given(
    seed=st.integers(0, 2**31),
    shared=st.booleans(),
    frames=st.lists(st.integers(1, 7), min_size=2, max_size=3),
    size=st.integers(1, 4),
)
def test_detections_read_back_bit_for_bit(tmp_path_factory, seed, shared, frames, size):
    if shared:
        frames = [frames[0]] * len(frames)
    rng = np.random.default_rng(seed)
    bounds = [(m, min(m + size, max(frames))) for m in range(0, max(frames), size)]
    chunks = [_chunk(rng, frames, b, shared) for b in bounds]
    store = _write_store(tmp_path_factory.mktemp("store") / "s", chunks, frames, shared)
    assert store.frames == tuple(frames) and store.shared_first_frame == shared
    for chunk in chunks:
        for (k, m, frame), found in chunk.found.items():
            for kk in range(len(frames)) if k < 0 else [k]:
                read = store.detections(kk, m, frame)
                assert all(np.array_equal(r, f.xy) for r, f in zip(read, found, strict=True))
        back = store.chunk(chunk.snapshots[0])
        for key, found in chunk.found.items():
            flags = [f.flags for f in back.found[key]]
            assert all(np.array_equal(a, f.flags) for a, f in zip(flags, found, strict=True))


def test_a_store_without_its_index_is_incomplete(tmp_path):
    folder = tmp_path / "s"
    folder.mkdir()
    with pytest.raises(StoreError, match="not a complete detection store"):
        DetectionStore(folder)
    (folder / "detections.json").write_text(json.dumps({"format": "other"}))
    with pytest.raises(StoreError, match="not the index of a detection store"):
        DetectionStore(folder)


def test_a_snapshot_beyond_the_store_is_refused(tmp_path):
    rng = np.random.default_rng(0)
    store = _write_store(tmp_path / "s", [_chunk(rng, [2, 2], (0, 2), True)], [2, 2], True)
    with pytest.raises(IndexError, match="snapshot 2 out of range"):
        store.detections(0, 2, "a")
