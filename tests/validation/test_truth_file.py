"""truth.h5 written part by part: the parts recorded survive an interruption, an
unreadable file starts again, and what is read back is what was written."""

import h5py
import numpy as np

from validation.truth.truth_file import TruthRun, TruthWriter

CAMERAS = ("cam1",)


def _writer(path, shared=True):
    return TruthWriter(
        path,
        header=lambda f: f.attrs.__setitem__("rig", "{}"),
        cameras=CAMERAS,
        planes=2,
        chunks=[(0, 2), (2, 4)],
        frames=4,
        shared_first_frame=shared,
    )


def _runs(rng, first, n, particles=5, n_dt=2):
    a = rng.normal(size=(n, particles, 3))
    out = []
    for k in range(n_dt):
        positions = np.stack([a, a + rng.normal(size=a.shape) * 1e-4], axis=1)
        out.append(
            TruthRun(
                dt=1e-4 * (k + 1),
                positions=positions,
                velocity=a * 0.1,
                xy={"cam1": rng.uniform(0, 2048, (n, 2, particles, 2))},
                visible={"cam1": rng.random((n, 2, particles)) > 0.3},
                first=first,
            )
        )
    return out


def test_parts_written_before_an_interruption_are_found_again(tmp_path):
    path = tmp_path / "truth.h5"
    rng = np.random.default_rng(0)
    _writer(path).write_chunk(1, _runs(rng, 2, 2))
    plates, chunks = _writer(path).done()  # a new writer continues the same file
    assert chunks.tolist() == [False, True] and not plates.any()


def test_an_unreadable_file_starts_again(tmp_path):
    path = tmp_path / "truth.h5"
    path.write_bytes(b"not an HDF5 file")
    plates, chunks = _writer(path).done()
    assert not chunks.any() and not plates.any()


def test_frame_a_is_stored_once_and_read_back_for_every_dt(tmp_path):
    path = tmp_path / "truth.h5"
    rng = np.random.default_rng(1)
    written = _runs(rng, 0, 2)
    writer = _writer(path)
    writer.write_chunk(0, written)
    with h5py.File(path) as f:
        assert f["particles/dt1/positions_a"] == f["particles/dt0/positions_a"]
        stored = f["particles/dt1/positions_b"][:2]
        xy = f["particles/dt0/cam1/xy_b"][:2]
    assert np.array_equal(stored, written[1].positions[:, 1])
    assert xy.dtype == np.float32
    assert np.allclose(xy, written[0].xy["cam1"][:, 1], rtol=2**-24, atol=0)
