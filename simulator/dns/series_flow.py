"""Tracers in a periodic field time series read from a file (``[flow] kind = "grid"``,
docs/dns.md §12).

A field file (:mod:`simulator.dns.fieldfile`) holds u on the grid at T times. Between
them the velocity and its gradient are interpolated

- **in space** by the periodic quintic spline of each snapshot
  (:mod:`simulator.dns.interpolate`; ∇u from the snapshot's Fourier coefficients, ik û,
  the Nyquist planes set to zero), and
- **in time** by the cubic Lagrange polynomial through the four snapshots around t (the
  two on each side; the first or last four at the ends of the file), which also gives
  ∂u/∂t.

Tracers obey dX/dt = u(X, t), advanced by RK4 with steps no longer than a quarter of
the file's time step, landing on the output times. At each output time the truth is
the interpolated u and the Lagrangian acceleration a = ∂u/∂t + (u·∇)u.

The time interpolation is the error a file adds: at a fixed point u changes as fast as
the small eddies are swept past it, on the time η/u′, not τ_η. docs/dns.md §12 gives
the error against tracers co-integrated with the DNS as a function of the file's step.
"""

from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np
import scipy.fft

from simulator.dns.field_statistics import shell_energies
from simulator.dns.fieldfile import read_field_file, read_snapshot
from simulator.dns.grid import Grid
from simulator.dns.interpolate import DEFAULT_ORDER, interpolate, spline_coefficients

#: Snapshots through which the time interpolant passes (cubic).
TIME_NODES = 4
#: RK4 steps per file time step, at least.
STEPS_PER_FILE_STEP = 4
#: Snapshots whose spline coefficients are kept in memory (of u, and of u with ∇u).
_CACHED = TIME_NODES + 1


def lagrange_weights(nodes: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
    """Weights of the Lagrange polynomial through ``nodes`` at t, and of its derivative.

    Parameters
    ----------
    nodes : ndarray, shape (K,)
        Distinct times, s.
    t : float
        s.

    Returns
    -------
    weights, derivative : ndarray, shape (K,)
        f(t) ≈ Σ weights_i f_i and f′(t) ≈ Σ derivative_i f_i (1/s).
    """
    nodes = np.asarray(nodes, dtype=float)
    k = len(nodes)
    weights, derivative = np.empty(k), np.empty(k)
    for i in range(k):
        others = np.delete(nodes, i)
        denominator = np.prod(nodes[i] - others)
        factors = t - others
        weights[i] = np.prod(factors) / denominator
        derivative[i] = sum(np.prod(np.delete(factors, j)) for j in range(k - 1)) / denominator
    return weights, derivative


@dataclass(frozen=True)
class SeriesScales:
    """What a field file says of its flow.

    Attributes
    ----------
    n : int
        Points per axis.
    box_side : float
        L, m.
    nu, epsilon : float
        ν (m²/s) and the mean dissipation ε (m²/s³), as the file records them.
    u_rms : float
        rms of one velocity component over every snapshot, m/s.
    times : ndarray, shape (T,)
        The snapshots' times, s.
    shell_k, shell_energy : ndarray, shape (S,)
        The distinct |k| (1/m) and the mean energy of their modes over the snapshots
        (m²/s²), for the exact D_LL.
    """

    n: int
    box_side: float
    nu: float
    epsilon: float
    u_rms: float
    times: np.ndarray
    shell_k: np.ndarray
    shell_energy: np.ndarray

    @property
    def integral_scale(self) -> float:
        """L_int = (π/(2u′²)) Σ E(k)/k over the modes, m."""
        return float(np.pi / (2 * self.u_rms**2) * np.sum(self.shell_energy / self.shell_k))

    @property
    def eddy_time(self) -> float:
        """T_L = L_int/u′, s."""
        return self.integral_scale / self.u_rms

    @property
    def file_step(self) -> float:
        """The largest step between snapshots, s."""
        return float(np.max(np.diff(self.times)))


def series_scales(path: Path) -> SeriesScales:
    """Read and check a field file for a run (:func:`read_field_file`'s checks).

    Parameters
    ----------
    path : Path
        A field file.

    Returns
    -------
    SeriesScales
        u′, the shell energies, and from them L_int and T_L; the file's times.

    Raises
    ------
    ValueError
        Naming the file: what :func:`read_field_file` refuses; fewer than
        :data:`TIME_NODES` snapshots; a grid the spectral gradient cannot use (N odd,
        below 32 or not a product of 2, 3 and 5).

    Examples
    --------
    A decaying Taylor–Green vortex, an exact Navier–Stokes solution, on 32³ points at
    four times 1 ms apart:

    >>> import numpy as np
    >>> import simulator
    >>> n, side, amplitude, nu = 32, 0.01, 0.1, 1e-6  # points, L (m), m/s, ν (m²/s)
    >>> x = np.arange(n) * side / n  # grid coordinates, m
    >>> X, Y, _ = np.meshgrid(x, x, x, indexing="ij")
    >>> k = 2 * np.pi / side  # 1/m
    >>> vortex = np.stack([np.sin(k * X) * np.cos(k * Y), -np.cos(k * X) * np.sin(k * Y), 0 * X])
    >>> times = np.arange(4) * 1e-3  # s
    >>> decay = np.exp(-2 * nu * k**2 * times)[:, None, None, None, None]
    >>> series = simulator.PeriodicFieldSeries(
    ...     box_side=side, nu=nu, epsilon=nu * k**2 * amplitude**2, times=times,
    ...     velocity=amplitude * decay * vortex)  # (T, 3, N, N, N), m/s
    >>> import pathlib, tempfile
    >>> tmp = tempfile.TemporaryDirectory()
    >>> path = pathlib.Path(tmp.name) / "vortex.h5"
    >>> simulator.write_field_file(path, series)
    >>> scales = simulator.field_file_scales(path)
    >>> round(scales.u_rms, 4), round(amplitude / 6**0.5, 4)  # u′, m/s
    (0.0408, 0.0408)
    >>> round(scales.integral_scale / (3 * np.pi / (4 * 2**0.5 * k)), 3)  # one mode, |k| = √2 k
    1.0
    >>> scales.file_step  # s
    0.001
    >>> tmp.cleanup()
    """
    series = read_field_file(path)
    if len(series.times) < TIME_NODES:
        raise ValueError(
            f"{path}: {len(series.times)} snapshot(s); the cubic interpolation in time "
            f"needs at least {TIME_NODES}"
        )
    try:
        grid = Grid(series.n, series.box_side)
    except ValueError as err:
        raise ValueError(f"{path}: n = {series.n}: {err}") from None
    energies = []
    for velocity in series.velocity:
        k, energy = shell_energies(scipy.fft.rfftn(velocity, axes=(1, 2, 3)), grid)
        energies.append(energy)
    return SeriesScales(
        n=series.n,
        box_side=series.box_side,
        nu=series.nu,
        epsilon=series.epsilon,
        u_rms=float(np.sqrt(np.mean(series.velocity.astype(np.float64) ** 2))),
        times=series.times,
        shell_k=k,
        shell_energy=np.mean(energies, axis=0),
    )


class SeriesInterpolator:
    """u, ∇u and ∂u/∂t of a field file at any points and times within it.

    Parameters
    ----------
    path : Path
        A field file (checked by :func:`series_scales`).
    order : {3, 5}
        Spline degree in space.
    """

    def __init__(self, path: Path, *, order: int = DEFAULT_ORDER) -> None:
        self.path = Path(path)
        self.order = order
        with h5py.File(self.path, "r") as f:
            self.times = np.asarray(f["times"][()], dtype=float)
            self.n = int(f.attrs["n"])
            self.box_side = float(f.attrs["box_side"])
        self._grid = Grid(self.n, self.box_side)
        self._velocity_cache: OrderedDict[int, np.ndarray] = OrderedDict()
        self._gradient_cache: OrderedDict[int, np.ndarray] = OrderedDict()

    def _spectrum(self, index: int) -> np.ndarray:
        """rfftn coefficients of a snapshot's u, shape (3, N, N, N//2 + 1)."""
        _, velocity = read_snapshot(self.path, index)
        return scipy.fft.rfftn(velocity, axes=(1, 2, 3))

    def _cached(self, cache: OrderedDict, index: int, build) -> np.ndarray:
        if index in cache:
            cache.move_to_end(index)
            return cache[index]
        cache[index] = build(index)
        if len(cache) > _CACHED:
            cache.popitem(last=False)
        return cache[index]

    def _velocity_coefficients(self, index: int) -> np.ndarray:
        """Spline coefficients of a snapshot's u, shape (N, N, N, 3)."""
        return self._cached(
            self._velocity_cache,
            index,
            lambda i: spline_coefficients(self._spectrum(i), order=self.order),
        )

    def _all_coefficients(self, index: int) -> np.ndarray:
        """Spline coefficients of u (0–2) and ∇u (3 + 3i + j: ∂u_i/∂x_j) of a snapshot,
        shape (N, N, N, 12)."""
        return self._cached(self._gradient_cache, index, self._build_all)

    def _build_all(self, index: int) -> np.ndarray:
        u_hat = self._spectrum(index)
        k = list(self._grid.wavenumbers())
        for axis in (0, 1):  # the Nyquist mode has no derivative in a real field
            k[axis][self.n // 2] = 0.0
        k[2][-1] = 0.0
        shape = [(-1, 1, 1), (1, -1, 1), (1, 1, -1)]
        fields = [u_hat[i] for i in range(3)]
        fields += [1j * k[j].reshape(shape[j]) * u_hat[i] for i in range(3) for j in range(3)]
        return spline_coefficients(np.stack(fields), order=self.order)

    def _nodes(self, t: float) -> np.ndarray:
        """Indices of the :data:`TIME_NODES` snapshots around t."""
        j = int(np.searchsorted(self.times, t, side="right")) - 1
        first = min(max(j - TIME_NODES // 2 + 1, 0), len(self.times) - TIME_NODES)
        return np.arange(first, first + TIME_NODES)

    def check_time(self, t: float) -> None:
        """Refuse a time outside the file (no extrapolation)."""
        if not self.times[0] - 1e-12 * abs(self.times[0]) <= t <= self.times[-1] * (1 + 1e-12):
            raise ValueError(
                f"{self.path}: t = {t:.6g} s is outside the file's times "
                f"{self.times[0]:.6g} … {self.times[-1]:.6g} s"
            )

    def velocity(self, points: np.ndarray, t: float) -> np.ndarray:
        """u at points (P, 3) and time t, m/s, shape (P, 3)."""
        nodes = self._nodes(t)
        weights, _ = lagrange_weights(self.times[nodes], t)
        out = np.zeros((len(points), 3))
        for w, index in zip(weights, nodes, strict=True):
            coefficients = self._velocity_coefficients(int(index))
            out += w * interpolate(coefficients, self.box_side, points, order=self.order)
        return out

    def truth(self, points: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
        """u (m/s) and the Lagrangian acceleration ∂u/∂t + (u·∇)u (m/s²) at points and
        t, each shape (P, 3)."""
        nodes = self._nodes(t)
        weights, derivative = lagrange_weights(self.times[nodes], t)
        values = np.zeros((len(points), 12))
        dudt = np.zeros((len(points), 3))
        for w, dw, index in zip(weights, derivative, nodes, strict=True):
            coefficients = self._all_coefficients(int(index))
            at = interpolate(coefficients, self.box_side, points, order=self.order)
            values += w * at
            dudt += dw * at[:, :3]
        u, gradient = values[:, :3], values[:, 3:].reshape(-1, 3, 3)
        return u, dudt + np.einsum("pj,pij->pi", u, gradient)


def follow_in_series(
    interpolator: SeriesInterpolator, x0: np.ndarray, start: float, times: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Tracers from ``x0`` at file time ``start``, followed over ``times`` after it.

    Parameters
    ----------
    interpolator : SeriesInterpolator
    x0 : ndarray, shape (P, 3)
        Positions at ``start``, m.
    start : float
        File time of the seeding, s.
    times : ndarray, shape (T,)
        Output times after ``start``, s: 0 first, strictly increasing.

    Returns
    -------
    positions, velocity, acceleration : ndarray, shape (T, P, 3)
        m, m/s, m/s².

    Raises
    ------
    ValueError
        ``start + times[-1]`` beyond the file's last time.
    """
    interpolator.check_time(start)
    interpolator.check_time(start + times[-1])
    max_step = float(np.min(np.diff(interpolator.times))) / STEPS_PER_FILE_STEP
    x = np.array(x0, dtype=float)
    shape = (len(times), len(x), 3)
    positions, velocity, acceleration = np.empty(shape), np.empty(shape), np.empty(shape)
    now = start
    for f, t in enumerate(times):
        if f:
            interval = start + t - now
            steps = max(1, int(np.ceil(interval / max_step * (1 - 1e-12))))
            h = interval / steps
            for _ in range(steps):
                k0 = interpolator.velocity(x, now)
                k1 = interpolator.velocity(x + 0.5 * h * k0, now + 0.5 * h)
                k2 = interpolator.velocity(x + 0.5 * h * k1, now + 0.5 * h)
                k3 = interpolator.velocity(x + h * k2, now + h)
                x = x + (h / 6.0) * (k0 + 2 * k1 + 2 * k2 + k3)
                now += h
            now = start + t
        positions[f] = x
        velocity[f], acceleration[f] = interpolator.truth(x, now)
    return positions, velocity, acceleration


@dataclass(frozen=True)
class SeriesTracerFlow:
    """Tracers in a field file (:class:`simulator.particles.TracerFlow`).

    Snapshot m of an experiment of M snapshots seeds its tracers at the file time
    ``starts[m]`` and follows them there.

    Attributes
    ----------
    field_file : Path
    starts : tuple of float
        File times of the experiment's snapshots, s.
    u_rms : float
        The file's u′, m/s (the margin of the seeding box).

    Examples
    --------
    A decaying Taylor–Green vortex, an exact Navier–Stokes solution, on 32³ points at
    four times 1 ms apart:

    >>> import numpy as np
    >>> import simulator
    >>> n, side, amplitude, nu = 32, 0.01, 0.1, 1e-6  # points, L (m), m/s, ν (m²/s)
    >>> x = np.arange(n) * side / n  # grid coordinates, m
    >>> X, Y, _ = np.meshgrid(x, x, x, indexing="ij")
    >>> k = 2 * np.pi / side  # 1/m
    >>> vortex = np.stack([np.sin(k * X) * np.cos(k * Y), -np.cos(k * X) * np.sin(k * Y), 0 * X])
    >>> times = np.arange(4) * 1e-3  # s
    >>> decay = np.exp(-2 * nu * k**2 * times)[:, None, None, None, None]
    >>> series = simulator.PeriodicFieldSeries(
    ...     box_side=side, nu=nu, epsilon=nu * k**2 * amplitude**2, times=times,
    ...     velocity=amplitude * decay * vortex)  # (T, 3, N, N, N), m/s
    >>> import pathlib, tempfile
    >>> tmp = tempfile.TemporaryDirectory()
    >>> path = pathlib.Path(tmp.name) / "vortex.h5"
    >>> simulator.write_field_file(path, series)
    >>> u_rms = simulator.field_file_scales(path).u_rms
    >>> flow = simulator.SeriesTracerFlow(path, starts=(0.0,), u_rms=u_rms)

    One snapshot of tracers seeded at t = 0 in a 2 mm cube and followed 1 ms
    (:func:`simulator.follow_snapshots`): their velocities are the vortex's.

    >>> cube = simulator.Box((2e-3, 2e-3, 2e-3))  # m
    >>> sample = simulator.follow_snapshots(flow, [0.0, 1e-3], particles=5, snapshots=1,
    ...                                     region=cube, rng=0)
    >>> X, Y, _ = sample.positions[0, 0].T  # at t = 0, m
    >>> u_x = amplitude * np.sin(k * X) * np.cos(k * Y)  # the vortex's u_x at t = 0, m/s
    >>> bool(np.abs(sample.velocity[0, 0, :, 0] - u_x).max() < 1e-6)
    True
    >>> tmp.cleanup()
    """

    field_file: Path
    starts: tuple[float, ...]
    u_rms: float

    def follow_snapshot(
        self, m: int, rng: np.random.Generator, seed_box, n_seed: int, times: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Tracers seeded from ``rng`` in ``seed_box`` at ``starts[m]``, followed over
        ``times`` (:func:`follow_in_series`)."""
        x0 = seed_box.sample(n_seed, rng)
        return follow_in_series(SeriesInterpolator(self.field_file), x0, self.starts[m], times)


def snapshot_starts(times: np.ndarray, snapshots: int, duration: float) -> tuple[float, ...]:
    """File times of M snapshots spread evenly over a file, each followed ``duration``.

    Raises
    ------
    ValueError
        The file is shorter than ``duration``.
    """
    last = times[-1] - duration
    if last < times[0]:
        raise ValueError(
            f"the file spans {times[-1] - times[0]:.4g} s, less than the largest Δt "
            f"({duration:.4g} s)"
        )
    return tuple(float(t) for t in np.linspace(times[0], last, snapshots))
