"""A scenario's ``[ipr]``: iterative particle reconstruction rungs beside the
detect-and-match stack.

With ``[ipr]`` a run keeps its particle images and adds two kinds of rungs to its error
budget: IPR through the true cameras (``ipr-true-cameras``: what the reconstruction
alone costs) and IPR through each calibration of ``methods`` (``ipr-<method>``: what a
laboratory gets), so that reconstruction and calibration errors separate. The first
IPR rung of ``methods`` is then the method under test; the detect-and-match rungs of
``[ptv] methods`` become baselines.

Fields: ``methods`` (calibrations IPR runs through; each must be fitted, i.e. in
``[calibration] methods``), ``otf_regions`` (rows, columns of image regions the OTF is
measured in, on the images) and ``otf_depth_slabs`` (depth slabs it is then measured in,
from the particles reconstructed there), ``mapping_grid`` (the step, in voxels, of the grid that
interpolates a calibration's world → pixel mapping; 0 calls the calibration directly)
and ``outer_iterations`` (at most; the default is :class:`ptv.reconstruct.IPRSettings`'). The
scenario's ``mapping_grid`` (32 voxels) differs from ``IPRSettings``' (0) on purpose: a run
interpolates every calibration alike, where a caller of :func:`ptv.reconstruct.reconstruct`
may give the cameras themselves.
"""

import os
from dataclasses import dataclass

from ptv.reconstruct import IPRSettings
from validation.run.recording_section import MEMORY_SHARE, machine_memory
from validation.run.scenario_fields import ScenarioError

#: Fewest cameras IPR needs: a candidate triangulated from two is checked in a third.
MIN_CAMERAS = 3
#: Memory one exposure's reconstruction adds per particle in the volume and per sensor
#: pixel of all the cameras, bytes (its particles, their images, candidates and shaking
#: buffers; the images, residuals and projections in float64). benchmarks/
#: bench_peer_openlpt measured the peak grow by 17 MiB at 1865 particles and 37 MiB at
#: 9326 on four 512 × 512 cameras: 2.8 kB per particle and 12 B per pixel, rounded up.
IPR_BYTES_PER_PARTICLE = 4000
IPR_BYTES_PER_PIXEL = 16
#: Resident memory of a worker before it reconstructs (Python with NumPy, SciPy and the
#: compiled kernels: 330-430 MiB measured), bytes.
WORKER_BYTES = 512 * 2**20


@dataclass(frozen=True)
class IprSection:
    """Iterative particle reconstruction rungs (module docstring)."""

    methods: tuple[str, ...] = ("model-free",)
    otf_regions: tuple[int, ...] = (1, 1)
    otf_depth_slabs: int = 3
    mapping_grid: float = 32.0
    outer_iterations: int = IPRSettings().outer_iterations

    def settings(self) -> IPRSettings:
        """The reconstruction's options."""
        return IPRSettings(mapping_grid=self.mapping_grid, outer_iterations=self.outer_iterations)

    def variants(self) -> tuple[str, ...]:
        """The rungs' names: IPR through the true cameras, then through each method."""
        return ("ipr-true-cameras", *(f"ipr-{m}" for m in self.methods))


def check_ipr(scenario, source: str, cameras: int) -> None:
    """Refuse an ``[ipr]`` that cannot run, naming the file and the field.

    Parameters
    ----------
    scenario : Scenario
        With ``ipr``.
    source : str
        The scenario file, for the message.
    cameras : int
        The rig's cameras.

    Raises
    ------
    ScenarioError
    """
    ipr = scenario.ipr

    def fail(message: str):
        raise ScenarioError(f"{source}: ipr.{message}")

    if cameras < MIN_CAMERAS:
        fail(
            f"methods: IPR needs at least {MIN_CAMERAS} cameras (a candidate from two is "
            f"checked in a third), the rig {scenario.rig.name!r} has {cameras}"
        )
    if scenario.recording is not None:
        raise ScenarioError(f"{source}: [ipr] runs on frame pairs, not with [recording]")
    if not ipr.methods:
        fail("methods must name at least one calibration method")
    missing = [m for m in ipr.methods if m not in scenario.calibration.methods]
    if missing:
        fail(f"methods {missing} are not in calibration.methods")
    if len(ipr.otf_regions) != 2 or min(ipr.otf_regions) < 1:
        fail(f"otf_regions must be [rows, columns], each >= 1, got {list(ipr.otf_regions)}")
    if ipr.otf_depth_slabs < 1:
        fail(f"otf_depth_slabs must be >= 1, got {ipr.otf_depth_slabs}")
    try:
        ipr.settings()
    except ValueError as err:
        fail(str(err))


def sensor_pixels(cameras) -> int:
    """Pixels of all the cameras' sensors together (each camera's ``lens.sensor_size``)."""
    return sum(int(c.lens.sensor_size[0]) * int(c.lens.sensor_size[1]) for c in cameras)


def ipr_memory(particles: int, pixels: int, workers: int) -> float:
    """Bytes the reconstructions of a run plan to take at their peak: every worker
    reconstructing one exposure of ``particles`` tracers on cameras of ``pixels`` pixels
    in all (the constants above)."""
    exposure = particles * IPR_BYTES_PER_PARTICLE + pixels * IPR_BYTES_PER_PIXEL
    return workers * (WORKER_BYTES + exposure)


def check_ipr_memory(
    scenario,
    source: str,
    pixels: int,
    *,
    workers: int | None = None,
    memory: float | None = None,
) -> None:
    """Refuse a density whose reconstructions would not fit in memory, before any work.

    Parameters
    ----------
    scenario : Scenario
        With ``ipr``.
    source : str
        The scenario file (or study point), for the message.
    pixels : int
        Pixels of all the rig's sensors together (:func:`sensor_pixels`).
    workers : int, optional
        Worker processes reconstructing at once (default: one per CPU).
    memory : float, optional
        The machine's memory, bytes (default :func:`machine_memory`).

    Raises
    ------
    ScenarioError
    """
    workers = (os.cpu_count() or 1) if workers is None else workers
    memory = machine_memory() if memory is None else memory
    need = ipr_memory(scenario.particles.count, pixels, workers)
    if need > MEMORY_SHARE * memory:
        raise ScenarioError(
            f"{source}: particles.count: reconstructing {scenario.particles.count} tracers "
            f"on {workers} workers takes about {need / 2**30:.3g} GiB, more than half this "
            f"machine's {memory / 2**30:.3g} GiB: seed fewer tracers or use fewer workers"
        )
