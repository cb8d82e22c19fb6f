"""Tracer particles in a flow: seeding, trajectories and the sample truth.

Every snapshot is an independent realization of the flow seeded afresh (docs/flow.md
§6), so snapshots are independent samples. Particles are seeded uniformly in the
illuminated slab padded by a margin larger than any particle travels during the
snapshot; since the flow is incompressible the particle density inside the slab stays
uniform at every time, so particles leaving the slab are replaced by particles entering
it without biasing the sample (no particle is re-injected by hand). Whether a particle is
in the slab or the analysis volume at a given time is a mask computed by the consumer.

A flow is anything that follows one snapshot's tracers (:class:`TracerFlow`): the
kinematic simulation (:class:`KSFlow`, one KS realization per snapshot, trajectories by
classical RK4 in float64 with steps no longer than min(Δt_min/2, 0.05 τ_η, 0.2/ω_N),
docs/flow.md §6) or a Navier–Stokes simulation (:mod:`simulator.dns.tracers`).
"""

import logging
from collections.abc import Callable
from dataclasses import dataclass
from itertools import pairwise
from typing import Protocol

import numpy as np

from simulator import ks_kernels
from simulator.ks_field import DEFAULT_UNSTEADINESS, KSField, draw_ks_field
from simulator.spectra import Spectrum

log = logging.getLogger(__name__)

#: Margin of the seeding box, in units of u' times the longest time a snapshot spans.
MARGIN_IN_U_RMS = 6.0

Progress = Callable[[int, int], None]


@dataclass(frozen=True)
class Box:
    """An axis-aligned box.

    Parameters
    ----------
    size : tuple of 3 floats
        Edge lengths along X, Y, Z, m.
    centre : tuple of 3 floats
        Centre, m.

    Examples
    --------
    A 20 × 20 × 2 mm slab centred on the origin:

    >>> import numpy as np
    >>> import simulator
    >>> slab = simulator.Box((0.02, 0.02, 0.002))  # m
    >>> round(slab.volume * 1e9)  # mm³
    800
    >>> slab.contains(np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.002]]))
    array([ True, False])
    >>> slab.padded(1e-3).size  # 1 mm more on every side, m
    (0.022, 0.022, 0.004)
    >>> slab.sample(5, np.random.default_rng(0)).shape  # uniform points, m
    (5, 3)
    """

    size: tuple[float, float, float]
    centre: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        size = np.asarray(self.size, dtype=float)
        centre = np.asarray(self.centre, dtype=float)
        if size.shape != (3,) or np.any(~np.isfinite(size)) or np.any(size <= 0):
            raise ValueError(f"box size must be 3 finite lengths > 0, got {self.size!r}")
        if centre.shape != (3,) or np.any(~np.isfinite(centre)):
            raise ValueError(f"box centre must be 3 finite coordinates, got {self.centre!r}")

    @property
    def volume(self) -> float:
        """Volume, m³."""
        return float(np.prod(self.size))

    def padded(self, margin: float) -> "Box":
        """The box grown by ``margin`` (m) on every side."""
        return Box(tuple(float(s) + 2 * margin for s in self.size), self.centre)

    def contains(self, x: np.ndarray) -> np.ndarray:
        """Mask of points inside the box; x of shape (..., 3), mask of shape (...)."""
        half = 0.5 * np.asarray(self.size)
        return np.all(np.abs(np.asarray(x) - np.asarray(self.centre)) <= half, axis=-1)

    def sample(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """n points uniform in the box, shape (n, 3), m."""
        half = 0.5 * np.asarray(self.size)
        return np.asarray(self.centre) + rng.uniform(-half, half, size=(n, 3))


#: The paper's illuminated volume: 100 × 100 mm, a 10 mm thick laser sheet normal to Z.
SHEET = Box((0.100, 0.100, 0.010))
#: The paper's analysis volume, 70 × 70 × 2 mm, centred in the sheet.
ANALYSIS_VOLUME = Box((0.070, 0.070, 0.002))


@dataclass(frozen=True)
class ParticleSnapshots:
    """Independent snapshots of particles followed over a set of times.

    Attributes
    ----------
    times : ndarray, shape (T,)
        Times after the snapshot start, s; times[0] = 0.
    positions : ndarray, shape (M, T, P, 3)
        Exact positions X(t) of P particles in each of M snapshots, m.
    velocity : ndarray, shape (M, T, P, 3)
        Exact velocities u(X(t), t), m/s.
    acceleration : ndarray, shape (M, T, P, 3)
        Exact Lagrangian accelerations, m/s².
    """

    times: np.ndarray
    positions: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray


@dataclass(frozen=True)
class DoubleFrameSample:
    """Double-frame recordings: a pair of frames per snapshot and Δt.

    Attributes
    ----------
    dt : ndarray, shape (K,)
        Frame separations Δt_k, s.
    runs : tuple of K ParticleSnapshots
        runs[k] holds M snapshots at times (0, Δt_k).
    shared_first_frame : bool
        True when snapshot m of every run is the same particles in the same flow at
        t (:func:`shared_start`); False for one independent experiment per Δt
        (:func:`double_frame`).
    """

    dt: np.ndarray
    runs: tuple[ParticleSnapshots, ...]
    shared_first_frame: bool = False


def max_step(field: KSField, dt_min: float) -> float:
    """Longest RK4 step allowed: min(Δt_min/2, 0.05 τ_η, 0.2/ω_N), s."""
    limits = [0.5 * dt_min, 0.05 * field.parameters.tau_eta]
    if field.omega.max() > 0:
        limits.append(0.2 / field.omega.max())
    return min(limits)


def integrate(field: KSField, x0: np.ndarray, times: np.ndarray, *, h_max: float) -> np.ndarray:
    """Positions of particles advected by a field, with RK4.

    Parameters
    ----------
    field : KSField
        The flow.
    x0 : ndarray, shape (P, 3)
        Positions at times[0], m.
    times : ndarray, shape (T,)
        Increasing output times, s.
    h_max : float
        Longest step, s; each interval between output times is cut in equal steps.

    Returns
    -------
    ndarray, shape (T, P, 3)
        Positions at the output times, m.
    """
    times = np.asarray(times, dtype=float)
    if times.ndim != 1 or len(times) < 1 or np.any(np.diff(times) <= 0):
        raise ValueError(f"times must be a strictly increasing 1-D array, got {times}")
    if not (np.isfinite(h_max) and h_max > 0):
        raise ValueError(f"h_max must be > 0, got {h_max}")
    steps: list[np.ndarray] = []
    record = [0]
    for lo, hi in pairwise(times):
        n = int(np.ceil((hi - lo) / h_max * (1 - 1e-12)))
        steps.append(np.full(n, (hi - lo) / n))
        record.append(record[-1] + n)
    h = np.concatenate(steps) if steps else np.empty(0)
    starts = times[0] + np.concatenate([[0.0], np.cumsum(h)])
    stage_times = np.empty(2 * len(h) + 1)
    stage_times[0::2] = starts
    stage_times[1::2] = starts[:-1] + 0.5 * h
    phases = np.ascontiguousarray(field.phases(stage_times))
    x0 = np.ascontiguousarray(x0, dtype=np.float64)
    return ks_kernels.rk4_trajectories(
        x0, phases, h, np.asarray(record, dtype=np.int64), field.wavevectors, field.a, field.b
    )


class TracerFlow(Protocol):
    """What :func:`follow_snapshots` needs of a flow: one snapshot's tracers followed."""

    @property
    def u_rms(self) -> float:
        """u′, m/s: sets the margin of the seeding box."""
        ...

    def follow_snapshot(
        self, m: int, rng: np.random.Generator, seed_box: Box, n_seed: int, times: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Seed ``n_seed`` tracers uniformly in ``seed_box`` (with ``rng``) in snapshot
        ``m`` and follow them over ``times`` (s after the snapshot's start, from 0).

        Returns
        -------
        positions, velocity, acceleration : ndarray, shape (T, n_seed, 3)
            Exact X(t), u(X(t), t) and Lagrangian acceleration, m, m/s, m/s².
        """
        ...


@dataclass(frozen=True)
class KSFlow:
    """Kinematic simulation: each snapshot draws its own KS realization of a spectrum.

    Attributes
    ----------
    spectrum : Spectrum
        The flow's spectrum.
    n_modes : int
        KS modes.
    unsteadiness : float
        λ of the KS frequencies (:func:`simulator.ks_field.draw_ks_field`).

    Examples
    --------
    The 10 Hz condition's Pope spectrum on 50 modes: a :class:`TracerFlow` that draws a
    fresh realization for every snapshot it follows.

    >>> import numpy as np
    >>> import simulator
    >>> preset = simulator.flow_preset("lem-10hz")
    >>> flow = simulator.KSFlow(simulator.PopeSpectrum(preset.parameters), n_modes=50)
    >>> flow.u_rms  # m/s
    0.19
    >>> seed_box = simulator.Box((0.02, 0.02, 0.002))  # m
    >>> times = np.array([0.0, 1e-3])  # s
    >>> x, u, a = flow.follow_snapshot(0, np.random.default_rng(0), seed_box, 3, times)
    >>> x.shape, u.shape, a.shape  # (T, P, 3): m, m/s, m/s²
    ((2, 3, 3), (2, 3, 3), (2, 3, 3))
    """

    spectrum: Spectrum
    n_modes: int = 200
    unsteadiness: float = DEFAULT_UNSTEADINESS

    @property
    def u_rms(self) -> float:
        """The spectrum's prescribed u′, m/s."""
        return self.spectrum.parameters.u_rms

    def follow_snapshot(
        self, m: int, rng: np.random.Generator, seed_box: Box, n_seed: int, times: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """A fresh realization drawn from ``rng``, then its tracers (:class:`TracerFlow`)."""
        flow = draw_ks_field(
            self.spectrum, n_modes=self.n_modes, unsteadiness=self.unsteadiness, rng=rng
        )
        x0 = seed_box.sample(n_seed, rng)
        shape = (len(times), n_seed, 3)
        positions, velocity, acceleration = np.empty(shape), np.empty(shape), np.empty(shape)
        if len(times) > 1:
            positions[:] = integrate(flow, x0, times, h_max=max_step(flow, np.diff(times).min()))
        else:
            positions[0] = x0
        for f, t in enumerate(times):
            u, _, _, a = flow.derivatives(positions[f], t)
            velocity[f] = u
            acceleration[f] = a
        return positions, velocity, acceleration


def _check_positive(name: str, values) -> np.ndarray:
    arr = np.atleast_1d(np.asarray(values, dtype=float))
    if arr.size == 0 or np.any(~np.isfinite(arr)) or np.any(arr <= 0):
        raise ValueError(f"{name} must be finite and > 0, got {values!r}")
    return arr


def _check_count(name: str, value: int, minimum: int = 1) -> int:
    if not isinstance(value, int | np.integer) or value < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def follow_snapshots(
    flow: TracerFlow,
    times: np.ndarray,
    *,
    particles: int,
    snapshots: int,
    region: Box = SHEET,
    rng: np.random.Generator | int | None = None,
    progress: Progress | None = None,
    first: int = 0,
    count: int | None = None,
) -> ParticleSnapshots:
    """Seed independent snapshots and follow their particles over ``times``.

    Parameters
    ----------
    flow : TracerFlow
        The flow (:class:`KSFlow`: each snapshot draws its own realization).
    times : array_like, shape (T,)
        Output times after the seeding, s, starting at 0 and increasing.
    particles : int
        Mean number of particles inside ``region`` (the seeding box is ``region``
        padded by 6 u' times[-1] and holds proportionally more).
    snapshots : int
        Number of independent snapshots M.
    region : Box
        The illuminated volume.
    rng : numpy.random.Generator, int or None
        Randomness; snapshot j uses the j-th of ``snapshots`` spawned children, so
        results do not depend on how snapshots are chunked (give an int seed, or a fresh
        Generator, to get the same snapshots in separate calls).
    progress : callable(done, total), optional
        Called after each snapshot.
    first, count : int
        Follow only snapshots ``first`` … ``first + count − 1`` of the ``snapshots``
        (default: all), e.g. one chunk of a run computed in parallel.

    Returns
    -------
    ParticleSnapshots
        The ``count`` snapshots followed.

    Examples
    --------
    Two independent snapshots of about 100 tracers in a 20 × 20 × 2 mm slab, followed
    over 2 ms: the seeding box is padded by 6u′ × 2 ms on every side, so about 5 times
    more tracers are followed than the slab holds.

    >>> import simulator
    >>> preset = simulator.flow_preset("lem-10hz")
    >>> flow = simulator.KSFlow(simulator.PopeSpectrum(preset.parameters), n_modes=50)
    >>> slab = simulator.Box((0.02, 0.02, 0.002))  # m
    >>> sample = simulator.follow_snapshots(flow, [0.0, 1e-3, 2e-3], particles=100,
    ...                                     snapshots=2, region=slab, rng=0)
    >>> sample.positions.shape  # (M, T, P, 3), m
    (2, 3, 495, 3)
    >>> slab.contains(sample.positions[:, 0]).sum(axis=1)  # in the slab at t = 0
    array([ 94, 106])
    """
    times = np.asarray(times, dtype=float)
    if times.ndim != 1 or times[0] != 0 or np.any(np.diff(times) <= 0):
        raise ValueError(f"times must start at 0 and increase strictly, got {times}")
    _check_count("particles", particles)
    _check_count("snapshots", snapshots)
    count = snapshots - first if count is None else count
    if not (isinstance(first, int) and 0 <= first and 1 <= count and first + count <= snapshots):
        raise ValueError(
            f"first = {first!r} and count = {count!r} must select snapshots of 0 … {snapshots - 1}"
        )
    margin = MARGIN_IN_U_RMS * flow.u_rms * times[-1]
    seed_box = region.padded(margin)
    n_seed = round(particles * seed_box.volume / region.volume)
    children = np.random.default_rng(rng).spawn(snapshots)[first : first + count]
    shape = (count, len(times), n_seed, 3)
    positions, velocity, acceleration = np.empty(shape), np.empty(shape), np.empty(shape)
    for m, child in enumerate(children):
        positions[m], velocity[m], acceleration[m] = flow.follow_snapshot(
            first + m, child, seed_box, n_seed, times
        )
        if progress is not None:
            progress(m + 1, count)
    travel = np.abs(positions - positions[:, :1]).max(initial=0.0)
    if travel > margin:
        # A particle from beyond the seeding box could then have entered the region.
        log.warning(
            "a particle travelled %.3g m, more than the %.3g m seeding margin", travel, margin
        )
    return ParticleSnapshots(times, positions, velocity, acceleration)


def double_frame(
    flow: TracerFlow,
    dt: np.ndarray,
    *,
    particles: int,
    snapshots: int,
    region: Box = SHEET,
    rng: np.random.Generator | int | None = None,
    progress: Progress | None = None,
    first: int = 0,
    count: int | None = None,
) -> DoubleFrameSample:
    """Independent double-frame experiments, one per Δt, each of M snapshots.

    Parameters
    ----------
    dt : array_like, shape (K,)
        Frame separations, s, > 0.
    Other parameters as in :func:`follow_snapshots`.

    Returns
    -------
    DoubleFrameSample

    Examples
    --------
    Three frame pairs at each of the 10 Hz condition's two shortest Δt, each Δt an
    experiment of its own (its own flows and tracers):

    >>> import simulator
    >>> preset = simulator.flow_preset("lem-10hz")
    >>> flow = simulator.KSFlow(simulator.PopeSpectrum(preset.parameters), n_modes=50)
    >>> slab = simulator.Box((0.02, 0.02, 0.002))  # m
    >>> sample = simulator.double_frame(flow, preset.dt[:2], particles=100, snapshots=3,
    ...                                 region=slab, rng=0)
    >>> [run.positions.shape for run in sample.runs]  # (M, 2, P, 3): frames a and b, m
    [(3, 2, 114, 3), (3, 2, 128, 3)]
    >>> sample.shared_first_frame
    False
    """
    dt = _check_positive("dt", dt)
    children = np.random.default_rng(rng).spawn(len(dt))
    done = [0]

    def step(_: int, __: int) -> None:
        done[0] += 1
        if progress is not None:
            progress(done[0], len(dt) * (snapshots - first if count is None else count))

    runs = tuple(
        follow_snapshots(
            flow,
            np.array([0.0, d]),
            particles=particles,
            snapshots=snapshots,
            region=region,
            rng=child,
            progress=step,
            first=first,
            count=count,
        )
        for d, child in zip(dt, children, strict=True)
    )
    return DoubleFrameSample(dt=dt, runs=runs)


def shared_start(
    flow: TracerFlow,
    dt: np.ndarray,
    *,
    particles: int,
    snapshots: int,
    region: Box = SHEET,
    rng: np.random.Generator | int | None = None,
    progress: Progress | None = None,
    first: int = 0,
    count: int | None = None,
) -> DoubleFrameSample:
    """Frame pairs at every Δt from the same M snapshots: frame a is shared.

    What a time-resolved recording gives when the second frame is taken Δt_k after a
    common first one (the paper's acquisition): all Δt see the same particles in the
    same flow, so the sampling noise of the statistics is common to every Δt and
    cancels in the multi-Δt fit.

    Parameters
    ----------
    dt : array_like, shape (K,)
        Frame separations, s, > 0, strictly increasing.
    Other parameters as in :func:`follow_snapshots`.

    Returns
    -------
    DoubleFrameSample
        With ``shared_first_frame`` True.

    Examples
    --------
    Three snapshots seen at the 10 Hz condition's two shortest Δt: frame a is the same
    at both.

    >>> import numpy as np
    >>> import simulator
    >>> preset = simulator.flow_preset("lem-10hz")
    >>> flow = simulator.KSFlow(simulator.PopeSpectrum(preset.parameters), n_modes=50)
    >>> slab = simulator.Box((0.02, 0.02, 0.002))  # m
    >>> sample = simulator.shared_start(flow, preset.dt[:2], particles=100, snapshots=3,
    ...                                 region=slab, rng=0)
    >>> [run.positions.shape for run in sample.runs]  # (M, 2, P, 3), m
    [(3, 2, 128, 3), (3, 2, 128, 3)]
    >>> first, second = sample.runs
    >>> np.array_equal(first.positions[:, 0], second.positions[:, 0])  # frame a
    True
    >>> (second.times * 1e3).round(3)  # frames a and b of Δt_1, ms
    array([0.   , 0.194])
    """
    dt = _check_positive("dt", dt)
    if np.any(np.diff(dt) <= 0):
        raise ValueError(f"dt must increase strictly for a shared first frame, got {dt}")
    sample = follow_snapshots(
        flow,
        np.concatenate([[0.0], dt]),
        particles=particles,
        snapshots=snapshots,
        region=region,
        rng=rng,
        progress=progress,
        first=first,
        count=count,
    )
    runs = tuple(
        ParticleSnapshots(
            np.array([0.0, d]),
            sample.positions[:, [0, k + 1]],
            sample.velocity[:, [0, k + 1]],
            sample.acceleration[:, [0, k + 1]],
        )
        for k, d in enumerate(dt)
    )
    return DoubleFrameSample(dt=dt, runs=runs, shared_first_frame=True)
