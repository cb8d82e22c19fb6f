"""Frames located by iterative particle reconstruction instead of detection and matching.

Where particle images overlap (from about 0.03 particles per pixel), detecting them in
each image and matching the detections loses particles and makes ghosts; iterative
particle reconstruction (:mod:`ptv.reconstruct`) finds them from all the cameras' images
at once. :func:`reconstruct_chunk` reconstructs every exposure of a range of snapshots
of a dataset, and the :class:`ReconstructedChunk` it gives locates each frame's points
for the double-frame stack (:func:`ptv.pipeline.double_frame.measure_snapshots`, its
``locate``), which then links, tests and averages them as it does matched points.

The OTF is measured on the images themselves (:func:`measure_run_otf`; ``synptv run``
measures it on frame a of the first snapshot, and on as many further exposures as a
dense recording needs): from the isolated particle images, then per depth slab from the
particles reconstructed there, as a laboratory calibrates it.
"""

import logging
import time
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from ptv.box import Box
from ptv.camera_model import CameraModel
from ptv.detect.frames import exposures
from ptv.io.dataset import Dataset
from ptv.reconstruct import (
    IPRSettings,
    OpticalTransferFunction,
    TooFewIsolatedImages,
    grid_mappings,
    measure_otf,
    reconstruct,
    refine_otf_pooled,
)

logger = logging.getLogger(__name__)

#: Outer iterations of the reconstruction with the OTF measured without depth, whose
#: particles measure the OTF per depth slab: with that OTF the residuals of the oblique
#: cameras keep peaks and IPR runs to its cap without converging; after 10 iterations
#: the particles give the same OTF as after 60 (dense-ci's first snapshot, 7 s against
#: 39 s).
FLAT_OTF_ITERATIONS = 10

#: Exposures :func:`measure_run_otf` pools at most: at 0.08 particles per pixel a ±30°
#: camera of dense-ci holds 3 isolated particle images per exposure in the middle of
#: three depth slabs (70 and 64 in the outer ones), 10 needed.
OTF_MAX_EXPOSURES = 16


@dataclass(frozen=True, eq=False)
class ReconstructedChunk:
    """Every exposure of snapshots m0 … m1 − 1, reconstructed.

    Attributes
    ----------
    folder : Path
        The dataset.
    detector : dict
        How the particles were located: ``method`` and the reconstruction's settings,
        ``threshold_sigmas`` its peak threshold in background noise units (as a
        detector's).
    cameras : tuple of str
        Camera names, in the calibrations' order.
    dt : ndarray, shape (K,)
        Frame separations, s.
    frames : tuple of int
        Frame pairs per Δt.
    shared_first_frame : bool
        Frame a of snapshot m shared by every Δt.
    snapshots : (int, int)
        m0, m1.
    points : dict of (int, int, str) to ndarray, shape (N, 3)
        Per exposure (k, m, frame), k = −1 for a shared frame a: the particles, m.
    seen : dict of (int, int, str) to list of int
        Per exposure, the particles each camera images.
    seconds : dict of (int, int, str) to float
        Per exposure, the reconstruction's wall time, s.
    iterations : dict of (int, int, str) to int
        Per exposure, the outer iterations run.
    """

    folder: Path
    detector: dict
    cameras: tuple[str, ...]
    dt: np.ndarray
    frames: tuple[int, ...]
    shared_first_frame: bool
    snapshots: tuple[int, int]
    points: dict
    seen: dict
    seconds: dict
    iterations: dict

    @classmethod
    def join(cls, chunks: Sequence["ReconstructedChunk"]) -> "ReconstructedChunk":
        """Consecutive chunks of one run as one (snapshots from the first's m0 to the
        last's m1)."""
        first = chunks[0]
        merged = {name: {} for name in ("points", "seen", "seconds", "iterations")}
        for chunk in chunks:
            for name, values in merged.items():
                values.update(getattr(chunk, name))
        snapshots = (first.snapshots[0], chunks[-1].snapshots[1])
        return replace(first, snapshots=snapshots, **merged)

    def key(self, k: int, m: int, frame: str) -> tuple[int, int, str]:
        """The exposure of frame ``frame`` of snapshot m at Δt_k."""
        return (-1 if frame == "a" and self.shared_first_frame else k, m, frame)

    def locate(self, k: int, m: int, frame: str) -> tuple[list[int], np.ndarray]:
        """Particles imaged per camera and points (N, 3), m, of one frame: the
        ``locate`` of :func:`ptv.pipeline.double_frame.measure_snapshots`."""
        key = self.key(k, m, frame)
        try:
            return self.seen[key], self.points[key]
        except KeyError:
            raise KeyError(f"no reconstruction of Δt_{k}, snapshot {m}, frame {frame}") from None


def measure_run_otf(
    exposures: Iterable[Sequence[np.ndarray]],
    cameras: Sequence[CameraModel],
    box: Box,
    settings: IPRSettings,
    *,
    regions: tuple[int, int] = (1, 1),
    depth_slabs: int = 3,
    min_per_cell: int = 10,
    saturation: float | None = None,
    max_exposures: int = OTF_MAX_EXPOSURES,
) -> list[OpticalTransferFunction]:
    """Each camera's OTF, measured on a recording's images, per depth slab.

    As a laboratory calibrates it on its own particle images (Schanz et al. 2013): the
    isolated particle images of each camera are fitted (:func:`ptv.reconstruct.measure_otf`),
    the exposures are reconstructed with that OTF, and the isolated images of the
    reconstructed particles are fitted again per depth slab
    (:func:`ptv.reconstruct.refine_otf_pooled`): defocus widens the images away from the
    focal plane, most in the cameras that look through the window most obliquely, and an
    OTF without depth leaves their residual images full of peaks.

    Each stage starts from the first exposure and pools the next ones only while some
    cell holds too few isolated images: a dense image holds few (at 0.05 particles per
    pixel about 2 % are 5 px from any other; at 0.12, a few per mille). An inner depth
    slab that ``max_exposures`` exposures would still leave short, at the rate of those
    pooled so far, takes σ from the defocus law instead
    (:func:`ptv.reconstruct.refine_otf_pooled`, ``fill_inner``).

    Parameters
    ----------
    exposures : iterable of (sequence of C ndarray, shape (H_c, W_c))
        Exposures, one image per camera each, in the order they are pooled; read only as
        far as needed (``synptv run``: frame a of each snapshot first).
    cameras : sequence of C CameraModel
        Calibrations in the images' order.
    box : Box
        The volume searched, (lower, upper) corners, m.
    settings : IPRSettings
        The reconstruction's options.
    regions : (rows, columns)
        Image regions the OTF is measured in; one region is the default.
    depth_slabs : int
        Depth slabs of the refined OTF, >= 1.
    min_per_cell : int
        Fitted reconstructed particle images needed in every region and slab, >= 1.
    saturation : float, optional
        The images' saturation level (default: their dtype's maximum).
    max_exposures : int
        Exposures pooled at most, >= 1.

    Returns
    -------
    list of C OpticalTransferFunction

    Raises
    ------
    TooFewIsolatedImages
        Too few isolated particle images in some region or slab even pooled over
        ``max_exposures`` exposures, or all there are (the message says how many were
        found and how many are needed).
    """
    if not (isinstance(max_exposures, int) and max_exposures >= 1):
        raise ValueError(f"max_exposures must be an integer >= 1, got {max_exposures!r}")
    source = iter(exposures)
    taken: list[list[np.ndarray]] = []

    def pool_another(error: TooFewIsolatedImages | None) -> None:
        nxt = next(source, None) if len(taken) < max_exposures else None
        if nxt is None:
            if error is None:
                raise ValueError("measuring the OTF needs at least one exposure")
            raise TooFewIsolatedImages(f"{error} [pooled over {len(taken)} exposures]")
        taken.append([np.asarray(image) for image in nxt])

    pool_another(None)
    while True:
        try:
            stacks = [np.stack(images) for images in zip(*taken, strict=True)]
            flat = measure_otf(stacks, regions=regions, saturation=saturation)
            break
        except TooFewIsolatedImages as error:
            pool_another(error)
    first_settings = replace(
        settings, outer_iterations=min(settings.outer_iterations, FLAT_OTF_ITERATIONS)
    )
    reconstructed = []
    fill_inner = False
    while True:
        for images in taken[len(reconstructed) :]:
            first = reconstruct(images, cameras, flat, box, settings=first_settings)
            reconstructed.append((images, first.positions, first.xy))
        try:
            otfs = refine_otf_pooled(
                reconstructed,
                flat,
                depth_slabs=depth_slabs,
                min_per_cell=min_per_cell,
                fill_inner=fill_inner,
            )
        except TooFewIsolatedImages as error:
            # an inner slab that even max_exposures would leave short: the defocus law
            fill_inner = error.inner_only and (
                error.poorest * max_exposures < min_per_cell * len(taken)
            )
            if not fill_inner:
                pool_another(error)
            continue
        logger.info("OTF measured on %d exposures", len(taken))
        return otfs


def reconstruct_chunk(
    dataset: Dataset,
    snapshots: tuple[int, int],
    *,
    cameras: Sequence[CameraModel],
    otfs: Sequence[OpticalTransferFunction],
    box: Box,
    settings: IPRSettings,
) -> ReconstructedChunk:
    """Reconstruct every exposure of snapshots m0 … m1 − 1 of a dataset.

    Parameters
    ----------
    dataset : Dataset
        The images (C >= 3 cameras).
    snapshots : (int, int)
        m0, m1.
    cameras : sequence of C CameraModel
        Calibrations in the dataset's camera order.
    otfs : sequence of C OpticalTransferFunction
        Each camera's OTF (:func:`measure_run_otf`).
    box : Box
        The volume searched, (lower, upper) corners, m.
    settings : IPRSettings
        The reconstruction's options.

    Returns
    -------
    ReconstructedChunk
    """
    m0, m1 = snapshots
    if settings.mapping_grid > 0:
        cameras = grid_mappings(cameras, box, settings)
    points, seen, seconds, iterations, unconverged = {}, {}, {}, {}, 0
    for k, m, frame in exposures(
        dataset.frames, range(m0, m1), shared_first_frame=dataset.shared_first_frame
    ):
        images = [dataset.read_frame(max(k, 0), c, m, frame) for c in dataset.cameras]
        t0 = time.perf_counter()
        found = reconstruct(images, cameras, otfs, box, settings=settings)
        key = (k, m, frame)
        seconds[key] = time.perf_counter() - t0
        points[key] = found.positions
        seen[key] = np.isfinite(found.xy).all(axis=2).sum(axis=1).tolist()
        iterations[key] = found.diagnostics.iterations
        unconverged += not found.diagnostics.converged
        logger.debug(
            "reconstructed Δt_%d snapshot %d frame %s: %d particles in %.1f s",
            k,
            m,
            frame,
            len(found.positions),
            seconds[key],
        )
    if unconverged:
        logger.warning(
            "IPR stopped at its %d outer iterations still adding particles in %d of the %d "
            "exposures of snapshots %d-%d: they are incomplete; raise [ipr] outer_iterations "
            "(docs/study.md §3: at 0.16 particles per pixel 150 found 0.997 of the particles "
            "where 60 found 0.87)",
            settings.outer_iterations,
            unconverged,
            len(iterations),
            m0,
            m1 - 1,
        )
    return ReconstructedChunk(
        dataset.folder,
        {
            "method": "iterative particle reconstruction",
            "threshold_sigmas": settings.noise_threshold,
            **asdict(settings),
        },
        tuple(dataset.cameras),
        np.asarray(dataset.dt),
        tuple(dataset.frames),
        dataset.shared_first_frame,
        (m0, m1),
        points,
        seen,
        seconds,
        iterations,
    )
