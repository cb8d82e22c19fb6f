"""The whole PTV stack on a run's stored detections, one chunk of snapshots per task.

Each chunk is matched, linked and tested
(:func:`ptv.pipeline.double_frame.measure_snapshots`) on its own; only the links whose
X(t) lies in the analysis volume are kept (the only ones the statistics use: a
paper-size run would otherwise carry 10⁷ links per rung), with the counts of every
detection, match and link. The matched points of frame a of the first snapshots come
back too, for the matching score (:mod:`validation.truth.matching`). The chunks are
joined in snapshot order, so the result does not depend on which worker measured which
chunk.
"""

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ptv.camera_model import CameraModel
from ptv.detect.frames import ChunkDetections
from ptv.detect.store import DetectionStore
from ptv.pipeline.double_frame import (
    MatchedPoints,
    PtvResult,
    SnapshotMeasurement,
    measure_snapshots,
    run_particles,
)
from ptv.pipeline.resolve import MeasuredSettings, match_frame, resolve_settings
from ptv.settings import PipelineSettings
from ptv.stats.run_statistics import compute_statistics
from validation.workflow.chunk_map import map_chunks
from validation.workflow.parallel import Executor

#: Snapshots whose frame-a matches are scored against the truth.
SCORED_SNAPSHOTS = 10


@dataclass(frozen=True, eq=False)
class PtvChunk:
    """What :func:`ptv_chunk` gives back.

    Attributes
    ----------
    measured : list of K lists of SnapshotMeasurement
        Per Δt, the chunk's snapshots, links restricted to the analysis volume.
    frame_a : dict of int to ndarray, shape (N, 3)
        Matched points of frame a of Δt_0, m, for the chunk's snapshots below
        :data:`SCORED_SNAPSHOTS`.
    """

    measured: list[list[SnapshotMeasurement]]
    frame_a: dict[int, np.ndarray]


def ptv_chunk(
    frames: ChunkDetections, *, cameras: Sequence[CameraModel], settings: PipelineSettings
) -> PtvChunk:
    """Match, link and test the snapshots of one chunk (see the module docstring)."""
    m0, m1 = frames.snapshots
    box = settings.statistics.analysis_volume
    measured = measure_snapshots(frames, range(m0, m1), cameras, settings)
    frame_a = {
        m: match_frame(frames.detections(0, m, "a"), cameras, settings)
        for m in range(m0, min(m1, SCORED_SNAPSHOTS))
    }
    return PtvChunk([[s.within(box) for s in run] for run in measured], frame_a)


def ptv_rung(
    store: DetectionStore,
    cameras: Sequence[CameraModel],
    settings: PipelineSettings,
    chunks: Sequence[tuple[int, int]],
    *,
    executor: Executor,
    cache: Path | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> tuple[PtvResult, list[np.ndarray]]:
    """The PTV stack on every chunk of a detection store, then the statistics.

    Parameters
    ----------
    store : DetectionStore
        The run's detections.
    cameras : sequence of CameraModel
        Calibrations in the store's camera order.
    settings : PipelineSettings
        Matching, linking, statistics; max_speed None to measure it on the first
        snapshots (:func:`ptv.pipeline.resolve.resolve_settings`).
    chunks : sequence of (int, int)
        Snapshot ranges covering the run, in order.
    executor : Executor
        Where the chunks are measured.
    cache : Path, optional
        Where finished chunks are kept (:func:`validation.workflow.chunk_map.map_chunks`).
    progress : callable(done, total), optional
        Called after each chunk.

    Returns
    -------
    (PtvResult, list of ndarray (N, 3))
        The result, and the matched points of frame a of the first
        :data:`SCORED_SNAPSHOTS` snapshots of Δt_0 (in the calibration's frame; the
        result holds them too, as its ``matched`` points, which ``results.h5`` keeps
        for ``synptv score``).
    """
    settings, measured = resolve_settings(store, cameras, settings)
    results = map_chunks(
        executor,
        ptv_chunk,
        chunks,
        lambda chunk: store.chunk(chunk[0]),
        shared={"cameras": list(cameras), "settings": settings},
        cache=cache,
        name="ptv",
        progress=progress,
    )
    measured_chunks = [r.measured for r in results]
    frame_a = [points for r in results for _, points in sorted(r.frame_a.items())]
    result = rung_result(store, cameras, settings, measured_chunks, frame_a, measured)
    return result, frame_a


def rung_result(
    source,
    cameras: Sequence[CameraModel],
    settings: PipelineSettings,
    measured_chunks: Sequence[list[list[SnapshotMeasurement]]],
    frame_a: Sequence[np.ndarray],
    measured: MeasuredSettings,
) -> PtvResult:
    """A rung's links per Δt and their statistics, from its chunks' measurements.

    Parameters
    ----------
    source : FrameDetections-like
        What was measured (``folder``, ``cameras``, ``dt``, ``detector``,
        ``shared_first_frame``).
    cameras : sequence of CameraModel
        Calibrations in the source's camera order.
    settings : PipelineSettings
        The resolved settings.
    measured_chunks : sequence of list of K lists of SnapshotMeasurement
        Per chunk, in snapshot order, its snapshots per Δt.
    frame_a : sequence of ndarray, shape (N_m, 3)
        The points of frame a of the first snapshots of Δt_0, m.
    measured : MeasuredSettings
        What was measured on the data to resolve the settings.

    Returns
    -------
    PtvResult
    """
    runs = [
        run_particles(
            k,
            float(source.dt[k]),
            [s for chunk in measured_chunks for s in chunk[k]],
            len(cameras),
            settings,
            speed_measured=measured.link_speed is not None,
        )
        for k in range(len(source.dt))
    ]
    statistics = compute_statistics(
        runs, settings.statistics, shared_first_frame=source.shared_first_frame
    )
    matched = MatchedPoints.from_frames((0, m, 0, points) for m, points in enumerate(frame_a))
    return PtvResult(source, source.cameras, settings, runs, statistics, matched, measured=measured)
