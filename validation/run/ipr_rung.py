"""The PTV stack with iterative particle reconstruction (IPR) in place of detection and
matching: a rung of a dense run's error budget.

Each chunk of snapshots is reconstructed on its own (every exposure of every camera,
:func:`ptv.pipeline.reconstructed.reconstruct_chunk`); the chunks are joined in
snapshot order, and the rest is the double-frame stack on the reconstructed points: the
largest speed and the predicted links' radii measured on the first snapshots, the links,
the median test and the statistics (:func:`validation.run.ptv_rung.rung_result`). The
OTF is measured once, on the images, before the chunks.
"""

import logging
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ptv.box import Box
from ptv.camera_model import CameraModel
from ptv.detect.frames import exposures
from ptv.io.dataset import Dataset, open_dataset
from ptv.pipeline.double_frame import PtvResult, measure_snapshots
from ptv.pipeline.reconstructed import ReconstructedChunk, measure_run_otf, reconstruct_chunk
from ptv.pipeline.resolve import resolve_settings
from ptv.reconstruct import IPRSettings, OpticalTransferFunction
from ptv.settings import PipelineSettings
from validation.run.ptv_rung import SCORED_SNAPSHOTS, rung_result
from validation.workflow.chunk_map import map_chunks
from validation.workflow.parallel import Executor

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class IprRung:
    """What an IPR rung reconstructs with.

    Attributes
    ----------
    settings : IPRSettings
        The reconstruction's options.
    box : Box
        The volume searched (the lit volume), (lower, upper), m.
    otf_regions : (int, int)
        Image regions the OTF is measured in.
    otf_depth_slabs : int
        Depth slabs of the OTF.
    """

    settings: IPRSettings
    box: Box
    otf_regions: tuple[int, int] = (1, 1)
    otf_depth_slabs: int = 3


def ipr_chunk(
    snapshots: tuple[int, int],
    *,
    folder: Path,
    cameras: Sequence[CameraModel],
    otfs: Sequence[OpticalTransferFunction],
    rung: IprRung,
) -> ReconstructedChunk:
    """Reconstruct one chunk of the dataset in ``folder`` (a worker's task)."""
    return reconstruct_chunk(
        open_dataset(folder),
        snapshots,
        cameras=cameras,
        otfs=otfs,
        box=rung.box,
        settings=rung.settings,
    )


def ipr_rung(
    folder: Path,
    cameras: Sequence[CameraModel],
    settings: PipelineSettings,
    rung: IprRung,
    chunks: Sequence[tuple[int, int]],
    *,
    executor: Executor,
    cache: Path | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> tuple[PtvResult, list[np.ndarray], ReconstructedChunk, list[OpticalTransferFunction]]:
    """IPR on every chunk of a dataset's images, then the double-frame stack.

    Parameters
    ----------
    folder : Path
        The dataset, with its particle images.
    cameras : sequence of CameraModel
        Calibrations in the dataset's camera order (world → pixel and pixel → ray).
    settings : PipelineSettings
        Linking and statistics; max_speed and predicted_radii None to measure them on
        the reconstructed points of the first snapshots.
    rung : IprRung
        The reconstruction's options, volume and OTF regions.
    chunks : sequence of (int, int)
        Snapshot ranges covering the run, in order.
    executor : Executor
        Where the chunks are reconstructed.
    cache : Path, optional
        Where finished chunks are kept.
    progress : callable(done, total), optional
        Called after each chunk.

    Returns
    -------
    (PtvResult, list of ndarray (N, 3), ReconstructedChunk, list of OpticalTransferFunction)
        The result; the points of frame a of the first :data:`SCORED_SNAPSHOTS`
        snapshots of Δt_0, m, in the calibration's frame; every exposure's
        reconstruction; the OTFs measured.

    Raises
    ------
    ValueError
        The OTF cannot be measured (too few isolated particle images), fewer than three
        cameras, or too few points to measure the speed.
    """
    dataset = open_dataset(folder)
    if len(cameras) < 3:
        raise ValueError(f"IPR needs at least three cameras, the dataset has {len(cameras)}")
    otfs = measure_run_otf(
        _exposures_for_otf(dataset),
        cameras,
        rung.box,
        rung.settings,
        regions=rung.otf_regions,
        depth_slabs=rung.otf_depth_slabs,
        saturation=dataset.saturation,
    )
    found = map_chunks(
        executor,
        ipr_chunk,
        chunks,
        lambda chunk: chunk,
        shared={"folder": Path(folder), "cameras": list(cameras), "otfs": otfs, "rung": rung},
        cache=cache,
        name="ipr",
        progress=progress,
    )
    joined = ReconstructedChunk.join(found)
    settings, measured = resolve_settings(joined, cameras, settings, locate=joined.locate)
    box = settings.statistics.analysis_volume
    per_chunk = [
        [
            [s.within(box) for s in run]
            for run in measure_snapshots(
                joined, range(*chunk.snapshots), cameras, settings, locate=joined.locate
            )
        ]
        for chunk in found
    ]
    m_scored = min(SCORED_SNAPSHOTS, joined.snapshots[1])
    frame_a = [joined.locate(0, m, "a")[1] for m in range(m_scored)]
    result = rung_result(joined, cameras, settings, per_chunk, frame_a, measured)
    seconds = np.fromiter(joined.seconds.values(), dtype=float)
    log.info(
        "IPR: %d exposures, %.1f s each (median), %.0f points each",
        len(seconds),
        float(np.median(seconds)),
        float(np.mean([len(p) for p in joined.points.values()])),
    )
    return result, frame_a, joined, otfs


def _exposures_for_otf(dataset: Dataset) -> Iterator[list[np.ndarray]]:
    """The dataset's exposures in the order the OTF pools them: frame a of each
    snapshot first (the particles of frame b have barely moved), then the frames b."""
    order = exposures(
        dataset.frames, range(max(dataset.frames)), shared_first_frame=dataset.shared_first_frame
    )
    order.sort(key=lambda exposure: exposure[2] == "b")
    for k, m, frame in order:
        yield [dataset.read_frame(max(k, 0), c, m, frame) for c in dataset.cameras]
