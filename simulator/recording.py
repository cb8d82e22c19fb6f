"""Time-resolved recordings: tracers carried through the sheet over many frames.

A recording is one realization of the flow seen at the frame times t_f = f/frame_rate,
f = 0 … F − 1. As for snapshots (:mod:`simulator.particles`), tracers are seeded
uniformly in the region padded by the most a particle travels over the recording
(:data:`simulator.particles.MARGIN_IN_U_RMS` u′ T); the flow being incompressible,
the density inside the region stays uniform, so particles enter and leave it as the
flow carries them and none is re-injected by hand. Over a long recording the padding
holds many more tracers than the region ever sees: they are followed in batches, and
only the particle-frames inside ``keep`` (the region, or the region padded by what a
renderer needs) are kept, so that memory grows with the particles seen, not with the
seeds.

The flow is kinematic simulation (:class:`simulator.particles.KSFlow`), one realization
per recording, each trajectory by the same classical RK4 as the snapshots' with steps
no longer than min(τ/2, 0.05 τ_η, 0.2/ω_N), τ the frame interval.

A Navier–Stokes DNS (:func:`follow_periodic_recording`) lives in a periodic box of side
L that tiles space. Padding the region by the distance its tracers travel would seed
thousands of times the region's volume over a recording of a few eddy times, so the
tracers are seeded once in one period cell, at the density the region asks, followed
with the flow, and every periodic image X + Lk of each that enters the region is kept
as a tracer of its own: the same field, exactly, wherever the region lies, with
particles entering and leaving it as they are carried.
"""

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from simulator.ks_field import draw_ks_field
from simulator.particles import (
    MARGIN_IN_U_RMS,
    SHEET,
    Box,
    KSFlow,
    TracerFlow,
    integrate,
    max_step,
)

#: Seeds followed at once: bounds the memory of a batch to about 72 bytes × batch × F.
BATCH = 20_000


@dataclass(frozen=True, eq=False)
class RecordedParticles:
    """The truth of a recording, one row per particle and frame inside ``keep``.

    Attributes
    ----------
    times : ndarray, shape (F,)
        Frame times, s, from 0.
    particle, frame : ndarray of int, shape (N,)
        Particle id (its seed's index) and frame index f; rows sorted by particle, then
        frame.
    position, velocity, acceleration : ndarray, shape (N, 3)
        Exact X(t_f), u(X, t_f) and Lagrangian acceleration, m, m/s, m/s².
    seeds : int
        Tracers seeded in the padded region.
    """

    times: np.ndarray
    particle: np.ndarray
    frame: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    seeds: int


def follow_recording(
    flow: KSFlow,
    frame_rate: float,
    frames: int,
    *,
    particles: int,
    region: Box = SHEET,
    keep: Box | None = None,
    rng: np.random.Generator | int | None = None,
    batch: int = BATCH,
    progress: Callable[[int, int], None] | None = None,
) -> RecordedParticles:
    """Seed one recording's tracers and follow them over every frame.

    Parameters
    ----------
    flow : KSFlow
        The flow: one realization is drawn for the recording.
    frame_rate : float
        Frames per second, Hz, > 0.
    frames : int
        Frames F ≥ 2.
    particles : int
        Mean number of tracers inside ``region`` at any frame.
    region : Box
        The illuminated volume.
    keep : Box, optional
        The particle-frames kept (default ``region``).
    rng : numpy.random.Generator, int or None
        Randomness: the realization, then each batch's seeds from a child of its own
        (another batch size draws other seeds: the same statistics, not the same
        particles).
    batch : int
        Seeds followed at once.
    progress : callable(done, total), optional
        Called after each batch.

    Returns
    -------
    RecordedParticles

    Examples
    --------
    Five frames at 2 kHz of about 50 tracers in a 20 × 20 × 2 mm slab: one row per
    particle and frame inside it, with its exact velocity and acceleration.

    >>> import numpy as np
    >>> import simulator
    >>> preset = simulator.flow_preset("lem-10hz")
    >>> flow = simulator.KSFlow(simulator.PopeSpectrum(preset.parameters), n_modes=50)
    >>> slab = simulator.Box((0.02, 0.02, 0.002))  # m
    >>> recorded = simulator.follow_recording(flow, 2000.0, 5, particles=50, region=slab,
    ...                                       rng=0)
    >>> recorded.times * 1e3  # ms
    array([0. , 0.5, 1. , 1.5, 2. ])
    >>> recorded.position.shape, recorded.seeds  # (N, 3), m; tracers followed
    ((239, 3), 247)
    >>> np.bincount(recorded.frame)  # tracers in the slab at each frame
    array([51, 49, 47, 44, 48])
    """
    _check_counts(frame_rate, frames, particles)
    keep = region if keep is None else keep
    times = np.arange(frames) / frame_rate
    margin = MARGIN_IN_U_RMS * flow.u_rms * times[-1]
    seed_box = region.padded(margin)
    seeds = round(particles * seed_box.volume / region.volume)
    generator = np.random.default_rng(rng)
    field = draw_ks_field(
        flow.spectrum, n_modes=flow.n_modes, unsteadiness=flow.unsteadiness, rng=generator
    )
    h_max = max_step(field, 1.0 / frame_rate)
    starts = range(0, seeds, batch)
    children = generator.spawn(len(starts))
    parts = []
    for b, (start, child) in enumerate(zip(starts, children, strict=True)):
        x0 = seed_box.sample(min(batch, seeds - start), child)
        positions = integrate(field, x0, times, h_max=h_max)  # (F, n, 3)
        frame, which = np.nonzero(keep.contains(positions))
        x = positions[frame, which]
        velocity, acceleration = np.empty_like(x), np.empty_like(x)
        for f in np.unique(frame):
            rows = frame == f
            u, _, _, a = field.derivatives(x[rows], times[f])
            velocity[rows], acceleration[rows] = u, a
        parts.append((start + which, frame, x, velocity, acceleration))
        if progress is not None:
            progress(b + 1, len(starts))
    return _recorded(times, parts, seeds)


def follow_periodic_recording(
    flow: TracerFlow,
    box_side: float,
    frame_rate: float,
    frames: int,
    *,
    particles: int,
    region: Box = SHEET,
    keep: Box | None = None,
    rng: np.random.Generator | int | None = None,
    snapshot: int = 0,
) -> RecordedParticles:
    """Follow one period cell's tracers of a periodic flow over a recording, and keep
    each of their periodic images inside ``keep`` (module docstring).

    Parameters
    ----------
    flow : TracerFlow
        A flow periodic in x, y and z with period ``box_side`` (a DNS); its positions
        may come folded into one period.
    box_side : float
        The period L, m.
    frame_rate : float
        Frames per second, Hz, > 0.
    frames : int
        Frames F ≥ 2.
    particles : int
        Mean number of tracers inside ``region`` at any frame.
    region : Box
        The illuminated volume.
    keep : Box, optional
        The particle-frames kept (default ``region``).
    rng : numpy.random.Generator, int or None
        The seeds' randomness.
    snapshot : int
        The flow's snapshot the recording starts from.

    Returns
    -------
    RecordedParticles
        Particle id i + n·c for image c (a fixed numbering of the shifts k) of seed i of
        n; ``seeds`` = n.
    """
    _check_counts(frame_rate, frames, particles)
    if not (np.isfinite(box_side) and box_side > 0):
        raise ValueError(f"box_side must be finite and > 0 m, got {box_side!r}")
    keep = region if keep is None else keep
    times = np.arange(frames) / frame_rate
    seeds = max(1, round(particles * box_side**3 / region.volume))
    cell = Box((box_side,) * 3, centre=region.centre)
    x, u, a = flow.follow_snapshot(snapshot, np.random.default_rng(rng), cell, seeds, times)
    # A periodic flow may hand its positions back folded into one period: unfold them
    # along time (a tracer moves far less than L/2 in a frame).
    x = np.unwrap(x, period=box_side, axis=0)
    centre, half = np.asarray(keep.centre), np.asarray(keep.size) / 2
    lowest = np.floor((centre - half - x.max(axis=(0, 1))) / box_side).astype(int)
    highest = np.ceil((centre + half - x.min(axis=(0, 1))) / box_side).astype(int)
    parts = []
    for c, shift in enumerate(np.ndindex(*(highest - lowest + 1))):
        image = x + box_side * (lowest + np.asarray(shift))
        frame, which = np.nonzero(keep.contains(image))
        parts.append(
            (which + seeds * c, frame, image[frame, which], u[frame, which], a[frame, which])
        )
    return _recorded(times, parts, seeds)


def _recorded(times: np.ndarray, parts: list, seeds: int) -> RecordedParticles:
    """The recording of parts (particle, frame, position, velocity, acceleration), its
    rows sorted by particle, then frame."""
    particle, frame, position, velocity, acceleration = (
        np.concatenate(p) for p in zip(*parts, strict=True)
    )
    order = np.lexsort((frame, particle))
    return RecordedParticles(
        times=times,
        particle=particle[order],
        frame=frame[order],
        position=position[order],
        velocity=velocity[order],
        acceleration=acceleration[order],
        seeds=seeds,
    )


def _check_counts(frame_rate: float, frames: int, particles: int) -> None:
    """ValueError unless the frame rate is > 0 and the frames (≥ 2) and particles (≥ 1)
    are integers."""
    if not (np.isfinite(frame_rate) and frame_rate > 0):
        raise ValueError(f"frame_rate must be finite and > 0 Hz, got {frame_rate!r}")
    if not isinstance(frames, int) or frames < 2:
        raise ValueError(f"frames must be an integer >= 2, got {frames!r}")
    if not isinstance(particles, int) or particles < 1:
        raise ValueError(f"particles must be an integer >= 1, got {particles!r}")
