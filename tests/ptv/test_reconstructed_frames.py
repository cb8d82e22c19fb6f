"""The double-frame stack on frames located by something other than matching (a
reconstruction): points given per exposure are linked, measured and tested as matches."""

import numpy as np
import pytest

from ptv.pipeline.double_frame import measure_snapshots
from ptv.pipeline.reconstructed import ReconstructedChunk
from ptv.pipeline.resolve import resolve_settings
from ptv.settings import PipelineSettings

DT = np.array([1e-3, 2e-3, 4e-3])
VELOCITY = np.array([0.05, -0.02, 0.01])  # m/s, one uniform flow: links known exactly


def chunk(snapshots: int, *, first: int = 0, n: int = 400, seed: int = 0) -> ReconstructedChunk:
    """Points of a uniform translation seen in every frame: frame a shared, frame b at
    each Δt."""
    rng = np.random.default_rng(seed)
    points, seen = {}, {}
    for m in range(first, first + snapshots):
        start = rng.uniform(-0.02, 0.02, (n, 3))
        points[(-1, m, "a")] = start
        for k, dt in enumerate(DT):
            points[(k, m, "b")] = start + VELOCITY * dt
        for key in points:
            seen[key] = [n, n, n]
    zeros = dict.fromkeys(points, 0.0)
    return ReconstructedChunk(
        folder=None,
        detector={"method": "given", "threshold_sigmas": 0.0},
        cameras=("c1", "c2", "c3"),
        dt=DT,
        frames=(first + snapshots,) * len(DT),
        shared_first_frame=True,
        snapshots=(first, first + snapshots),
        points=points,
        seen=seen,
        seconds=zeros,
        iterations=dict.fromkeys(points, 0),
    )


def test_located_points_are_linked_to_their_exact_displacements():
    frames = chunk(3)
    settings, measured = resolve_settings(
        frames, [None] * 3, PipelineSettings(), locate=frames.locate
    )
    assert measured.tolerance is None  # nothing was matched
    assert settings.max_speed == pytest.approx(np.linalg.norm(VELOCITY), rel=0.5)
    runs = measure_snapshots(frames, range(3), [None] * 3, settings, locate=frames.locate)
    for k, run in enumerate(runs):
        for snapshot in run:
            assert snapshot.links == 400
            assert np.allclose(snapshot.displacements, VELOCITY * DT[k], atol=1e-12)
            assert snapshot.detections.tolist() == [[400] * 3, [400] * 3]


def test_joined_chunks_locate_every_exposure_and_refuse_a_missing_one():
    a, b = chunk(2, seed=1), chunk(2, first=2, seed=2)
    joined = ReconstructedChunk.join([a, b])
    assert joined.snapshots == (0, 4)
    assert np.array_equal(joined.locate(1, 3, "b")[1], b.points[(1, 3, "b")])
    assert np.array_equal(joined.locate(2, 0, "a")[1], a.points[(-1, 0, "a")])
    with pytest.raises(KeyError, match="snapshot 7"):
        joined.locate(0, 7, "a")


def test_a_chunk_whose_reconstructions_did_not_converge_says_how_many(monkeypatch, caplog):
    """Two of a chunk's three exposures stopped at outer_iterations: one warning names
    the count and the setting to raise."""
    from types import SimpleNamespace

    from ptv.pipeline import reconstructed
    from ptv.reconstruct import IPRSettings

    flags = iter([False, True, False])

    def fake(images, cameras, otfs, box, settings):
        diagnostics = SimpleNamespace(iterations=3, converged=next(flags))
        return SimpleNamespace(
            positions=np.zeros((1, 3)), xy=np.zeros((3, 1, 2)), diagnostics=diagnostics
        )

    monkeypatch.setattr(reconstructed, "reconstruct", fake)
    dataset = SimpleNamespace(
        frames=(1, 1),
        shared_first_frame=True,
        cameras=("c0", "c1", "c2"),
        dt=(1e-3, 2e-3),
        folder="d",
        read_frame=lambda k, c, m, frame: np.zeros((4, 4)),
    )
    with caplog.at_level("WARNING", logger="ptv.pipeline.reconstructed"):
        reconstructed.reconstruct_chunk(
            dataset, (0, 1), cameras=[], otfs=[], box=None, settings=IPRSettings()
        )
    assert "in 2 of the 3 exposures" in caplog.text
    assert "raise [ipr] outer_iterations" in caplog.text
