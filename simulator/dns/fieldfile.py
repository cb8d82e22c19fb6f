"""A time series of periodic velocity fields in HDF5 (docs/dns.md §9).

Layout (format ``synptv-periodic-field``, version 1; SI units)::

    /               attrs: format, format_version, n (points per axis N),
                           box_side L (m), nu ν (m²/s), epsilon ε (m²/s³, the mean
                           injection = mean dissipation rate)
    /x              (N,) float64, m: grid coordinates x_i = i L/N (the same on y and z)
    /times          (T,) float64, s, strictly increasing
    /u, /v, /w      (T, N, N, N) float64 or float32, m/s: the velocity components along
                    x, y, z at the grid points, indexed [t, i_x, i_y, i_z]; one chunk per
                    snapshot
    /measured       (optional) attrs: the measured scales (MeasuredParameters, SI)

The fields are periodic with period L on each axis (the point x = L is the point 0).
:func:`write_field_file` and :class:`FieldFileWriter` write under a temporary name and
rename when complete; :func:`read_field_file` checks everything above and raises a
one-line ValueError naming the file and the dataset.
"""

import os
from dataclasses import dataclass, fields
from math import isfinite
from pathlib import Path

import h5py
import numpy as np

from simulator.dns.diagnostics import MeasuredParameters

FORMAT = "synptv-periodic-field"
FORMAT_VERSION = 1

_COMPONENTS = ("u", "v", "w")
_ATTRIBUTES = ("n", "box_side", "nu", "epsilon")


@dataclass(frozen=True)
class PeriodicFieldSeries:
    """Velocity fields of a periodic box at several times.

    Attributes
    ----------
    box_side : float
        L, m.
    nu : float
        ν, m²/s.
    epsilon : float
        ε, m²/s³.
    times : ndarray, shape (T,)
        s, strictly increasing.
    velocity : ndarray, shape (T, 3, N, N, N)
        u at x_i = i L/N, m/s (float64 or float32).
    parameters : MeasuredParameters or None
        The measured scales, when known.

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
    >>> series.n, series.velocity.shape
    (32, (4, 3, 32, 32, 32))
    """

    box_side: float
    nu: float
    epsilon: float
    times: np.ndarray
    velocity: np.ndarray
    parameters: MeasuredParameters | None = None

    @property
    def n(self) -> int:
        """Points per axis N."""
        return self.velocity.shape[-1]


def _header(f: h5py.File, n: int, box_side: float, nu: float, epsilon: float) -> None:
    for name, value in (("box_side", box_side), ("nu", nu), ("epsilon", epsilon)):
        if not (isfinite(value) and value > 0):
            raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
    f.attrs["format"] = FORMAT
    f.attrs["format_version"] = FORMAT_VERSION
    f.attrs["n"] = n
    f.attrs["box_side"] = float(box_side)
    f.attrs["nu"] = float(nu)
    f.attrs["epsilon"] = float(epsilon)
    f.create_dataset("x", data=np.arange(n) * (box_side / n))


def _write_parameters(f: h5py.File, parameters: MeasuredParameters | None) -> None:
    if parameters is not None:
        group = f.require_group("measured")
        for key, value in parameters.as_dict().items():
            group.attrs[key] = value


class FieldFileWriter:
    """Writes a field file one snapshot at a time (for series too large to hold).

    Use as a context manager: the file appears under its name only when the block ends
    without an exception; otherwise the temporary file is removed.

    Parameters
    ----------
    path : path-like
        The file to create (replaced if it exists).
    n : int
        Points per axis.
    box_side, nu, epsilon : float
        L (m), ν (m²/s), ε (m²/s³).
    dtype : {numpy.float64, numpy.float32}
        Storage type of u, v, w.
    """

    def __init__(
        self,
        path: os.PathLike | str,
        *,
        n: int,
        box_side: float,
        nu: float,
        epsilon: float,
        dtype=np.float64,
    ) -> None:
        self.path = Path(path)
        if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 1:
            raise ValueError(f"n must be an integer ≥ 1, got {n!r}")
        self.n = int(n)
        self.dtype = np.dtype(dtype)
        if self.dtype not in (np.dtype(np.float64), np.dtype(np.float32)):
            raise ValueError(f"dtype must be float64 or float32, got {self.dtype}")
        self._tmp = self.path.with_name(f".{self.path.name}.{os.getpid()}.tmp")
        self._file = h5py.File(self._tmp, "w")
        try:
            _header(self._file, self.n, box_side, nu, epsilon)
            shape = (0, self.n, self.n, self.n)
            for name in _COMPONENTS:
                self._file.create_dataset(
                    name,
                    shape=shape,
                    maxshape=(None, *shape[1:]),
                    dtype=self.dtype,
                    chunks=(1, *shape[1:]),
                )
            self._file.create_dataset("times", shape=(0,), maxshape=(None,), dtype=np.float64)
        except BaseException:
            self._discard()
            raise
        self._last = -np.inf

    def append(self, time: float, velocity: np.ndarray) -> None:
        """Add the snapshot at time (s, after the previous one): velocity (3, N, N, N), m/s."""
        velocity = np.asarray(velocity)
        if velocity.shape != (3, self.n, self.n, self.n):
            raise ValueError(
                f"velocity must have shape {(3, self.n, self.n, self.n)}, got {velocity.shape}"
            )
        if not (isfinite(time) and time > self._last):
            raise ValueError(f"time {time!r} does not follow the previous {self._last!r}")
        if not np.all(np.isfinite(velocity)):
            raise ValueError(f"velocity at t = {time} holds NaN or infinite values")
        t = self._file["times"].shape[0]
        self._file["times"].resize((t + 1,))
        self._file["times"][t] = time
        for c, name in enumerate(_COMPONENTS):
            ds = self._file[name]
            ds.resize((t + 1, *ds.shape[1:]))
            ds[t] = velocity[c].astype(self.dtype, copy=False)
        self._last = float(time)

    def close(self, parameters: MeasuredParameters | None = None) -> None:
        """Write the measured scales (optional) and publish the file under its name."""
        if self._file["times"].shape[0] == 0:
            self._discard()
            raise ValueError(f"{self.path}: no snapshot was written")
        _write_parameters(self._file, parameters)
        self._file.close()
        os.replace(self._tmp, self.path)

    def _discard(self) -> None:
        self._file.close()
        self._tmp.unlink(missing_ok=True)

    def __enter__(self) -> "FieldFileWriter":
        return self

    def __exit__(self, kind, value, traceback) -> None:
        if kind is not None:
            self._discard()
        elif self._file.id.valid:
            self.close()


def write_field_file(path: os.PathLike | str, series: PeriodicFieldSeries, *, dtype=None) -> None:
    """Write a whole series (see the module's layout).

    Parameters
    ----------
    path : path-like
        The file to create (replaced if it exists; it appears only once complete).
    series : PeriodicFieldSeries
        Velocity (T, 3, N, N, N) in m/s at T times in s, box side, ν and ε.
    dtype : {numpy.float64, numpy.float32}, optional
        Storage type of u, v, w; default that of ``series.velocity``.

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
    >>> simulator.write_field_file(path, series, dtype=np.float32)  # half the size
    >>> simulator.read_field_file(path).velocity.dtype.name
    'float32'
    >>> tmp.cleanup()
    """
    v = np.asarray(series.velocity)
    if v.ndim != 5 or v.shape[1] != 3 or not (v.shape[2] == v.shape[3] == v.shape[4]):
        raise ValueError(f"velocity must have shape (T, 3, N, N, N), got {v.shape}")
    if len(series.times) != v.shape[0]:
        raise ValueError(f"{len(series.times)} times for {v.shape[0]} snapshots")
    with FieldFileWriter(
        path,
        n=v.shape[-1],
        box_side=series.box_side,
        nu=series.nu,
        epsilon=series.epsilon,
        dtype=v.dtype if dtype is None else dtype,
    ) as writer:
        for t, snapshot in zip(series.times, v, strict=True):
            writer.append(float(t), snapshot)
        writer.close(series.parameters)


def _fail(path: Path, what: str) -> ValueError:
    return ValueError(f"{path}: {what}")


def read_field_file(path: os.PathLike | str) -> PeriodicFieldSeries:
    """Read and check a field file.

    Parameters
    ----------
    path : path-like
        A field file (:func:`write_field_file`, :class:`FieldFileWriter`).

    Returns
    -------
    PeriodicFieldSeries
        velocity as stored (float64 or float32).

    Raises
    ------
    ValueError
        Naming the file and the dataset: not a field file, a missing dataset or
        attribute, NaN or infinite values, a non-cubic or mismatched shape, a box side
        inconsistent with the grid coordinates, times not strictly increasing.

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
    >>> back = simulator.read_field_file(path)
    >>> back.times * 1e3, back.box_side, back.nu  # ms, m, m²/s
    (array([0., 1., 2., 3.]), 0.01, 1e-06)
    >>> np.array_equal(back.velocity, series.velocity)
    True
    >>> tmp.cleanup()
    """
    path = Path(path)
    try:
        f = h5py.File(path, "r")
    except OSError as error:
        raise _fail(path, f"not a readable HDF5 file ({error})") from None
    with f:
        attrs = {name: _attribute(path, f, name) for name in _ATTRIBUTES}
        n = attrs["n"]
        if int(n) != n:
            raise _fail(path, f"attribute 'n' must be an integer, got {n}")
        n = int(n)
        for name in ("x", "times", *_COMPONENTS):
            if name not in f or not isinstance(f[name], h5py.Dataset):
                raise _fail(path, f"missing dataset '{name}'")
        x = np.asarray(f["x"][()], dtype=float)
        times = np.asarray(f["times"][()], dtype=float)
        for name, a in (("x", x), ("times", times)):
            if not np.all(np.isfinite(a)):
                raise _fail(path, f"dataset '{name}' holds NaN or infinite values")
        if times.ndim != 1 or len(times) == 0:
            raise _fail(path, f"dataset 'times' must have shape (T,), T ≥ 1, got {times.shape}")
        if np.any(np.diff(times) <= 0):
            raise _fail(path, "dataset 'times' is not strictly increasing")
        box = attrs["box_side"]
        if x.shape != (n,) or not np.allclose(x, np.arange(n) * (box / n), rtol=0, atol=1e-9 * box):
            raise _fail(path, f"dataset 'x' is not i·box_side/n for n = {n}, box_side = {box} m")
        dtypes = set()
        for name in _COMPONENTS:
            shape, dtype = f[name].shape, f[name].dtype
            if len(shape) != 4 or not (shape[1] == shape[2] == shape[3]):
                raise _fail(path, f"dataset '{name}' must have shape (T, N, N, N), got {shape}")
            if shape != (len(times), n, n, n):
                raise _fail(
                    path, f"dataset '{name}' has shape {shape}, expected {(len(times), n, n, n)}"
                )
            if dtype not in (np.float64, np.float32):
                raise _fail(path, f"dataset '{name}' must be float64 or float32, got {dtype}")
            dtypes.add(dtype)
        velocity = np.empty((len(times), 3, n, n, n), max(dtypes, key=lambda d: d.itemsize))
        for c, name in enumerate(_COMPONENTS):
            f[name].read_direct(velocity, dest_sel=np.s_[:, c])
            if not np.all(np.isfinite(velocity[:, c])):
                raise _fail(path, f"dataset '{name}' holds NaN or infinite values")
        parameters = _read_parameters(path, f)
    return PeriodicFieldSeries(
        box_side=box,
        nu=attrs["nu"],
        epsilon=attrs["epsilon"],
        times=times,
        velocity=velocity,
        parameters=parameters,
    )


def _attribute(path: Path, f: h5py.File, name: str) -> float:
    if name not in f.attrs:
        raise _fail(path, f"missing attribute '{name}'")
    value = f.attrs[name]
    try:
        number = float(value)
    except (TypeError, ValueError):
        number = float("nan")
    if not (isfinite(number) and number > 0):
        raise _fail(path, f"attribute '{name}' must be a finite number > 0, got {value!r}")
    return number


def _read_parameters(path: Path, f: h5py.File) -> MeasuredParameters | None:
    if "measured" not in f:
        return None
    group = f["measured"].attrs
    names = [field.name for field in fields(MeasuredParameters)]
    missing = [name for name in names if name not in group]
    if missing:
        raise _fail(path, f"group 'measured' lacks attribute '{missing[0]}'")
    values = {name: group[name].item() for name in names}
    values["n"] = int(values["n"])
    return MeasuredParameters(**values)


def read_snapshot(path: os.PathLike | str, index: int) -> tuple[float, np.ndarray]:
    """One snapshot of a field file, without reading the others.

    Parameters
    ----------
    path : path-like
        A field file (the whole file is checked by :func:`read_field_file`; this checks
        the snapshot it reads).
    index : int
        Which snapshot, 0 … T − 1.

    Returns
    -------
    time : float
        Its time, s.
    velocity : ndarray, shape (3, N, N, N), float64
        u, m/s.

    Raises
    ------
    ValueError
        Naming the file: no such snapshot, a missing dataset, NaN or infinite values.
    """
    path = Path(path)
    with h5py.File(path, "r") as f:
        for name in ("times", *_COMPONENTS):
            if name not in f:
                raise _fail(path, f"missing dataset '{name}'")
        count = f["times"].shape[0]
        if not 0 <= index < count:
            raise _fail(path, f"no snapshot {index}: the file holds {count}")
        velocity = np.stack([np.asarray(f[name][index], dtype=np.float64) for name in _COMPONENTS])
        time = float(f["times"][index])
    if not np.all(np.isfinite(velocity)):
        raise _fail(path, f"snapshot {index} holds NaN or infinite values")
    return time, velocity


def read_field_file_parameters(path: os.PathLike | str) -> MeasuredParameters:
    """The measured scales a field file records (``/measured``).

    Raises
    ------
    ValueError
        Naming the file: a file without them, or with one missing.
    """
    path = Path(path)
    with h5py.File(path, "r") as f:
        parameters = _read_parameters(path, f)
    if parameters is None:
        raise _fail(path, "no 'measured' group: the file does not record its flow's scales")
    return parameters
