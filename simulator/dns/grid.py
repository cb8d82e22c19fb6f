"""The periodic grid of the DNS and its physical units (docs/dns.md §1).

A cubic box of side L holds N points per axis at x_i = i L/N, i = 0 … N−1. Real fields
are indexed [i_x, i_y, i_z]; a vector field has shape (3, N, N, N), component first.
Fourier coefficients are ``scipy.fft.rfftn`` over the three spatial axes (the last one
halved: shape (3, N, N, N//2 + 1)) with the default 'backward' normalisation, so
u(x) = N⁻³ Σ_k û(k) e^{ik·x}. Wavenumbers are k = (2π/L)·n with n = fftfreq(N)·N on the
first two axes and rfftfreq(N)·N on the last.

Dealiasing is the 2/3 rule applied per axis (a cube): the modes kept have 3|n_i| < N on
every axis, and the resolution is quoted with k_max = (N/3)(2π/L). With the physical
inputs ν, ε, N and k_max η the box side follows as L = 2πNη/(3 k_max η).
"""

import logging
from dataclasses import dataclass
from math import isfinite, pi

import numpy as np
import scipy.fft

logger = logging.getLogger(__name__)

#: Smallest grid accepted: below it the forced band and the dissipation range overlap.
MIN_POINTS = 32

#: Default resolution k_max η.
DEFAULT_KMAX_ETA = 1.5

#: Below this k_max η the velocity gradients are under-resolved: refused.
MIN_KMAX_ETA = 1.0

#: Below this k_max η a warning is logged (the dissipation spectrum is cut near its peak).
WARN_KMAX_ETA = 1.5

#: Full-size float64 arrays (3 components, physical or spectral) held by a solver:
#: the state, the RK4 accumulator and stage state, a tendency, the six-component
#: transform buffer counted twice (spectral and physical) and the FFT's own copies.
_SOLVER_ARRAYS = 14.0

#: Interpreter, NumPy, SciPy, numba and h5py once imported, bytes.
_BASELINE_BYTES = 250 * 2**20

#: Per tracer: position, stage positions, velocities and the interpolation stencil.
_BYTES_PER_TRACER = 2048


def _positive(name: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not isfinite(value):
        raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
    if value <= 0:
        raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
    return float(value)


def _check_points(n) -> int:
    if isinstance(n, bool) or not isinstance(n, int | np.integer):
        raise ValueError(f"n must be an integer, got {n!r}")
    n = int(n)
    if n < MIN_POINTS:
        raise ValueError(f"n must be at least {MIN_POINTS}, got {n}")
    if n % 2:
        raise ValueError(f"n must be even, got {n}")
    fast = scipy.fft.next_fast_len(n, real=True)
    if fast != n:
        raise ValueError(f"n = {n} is not FFT-friendly (2, 3, 5 factors); next is {fast}")
    return n


def memory_estimate(n: int, *, tracers: int = 0) -> int:
    """Peak resident memory of a DNS run on an n³ grid, bytes, before anything is allocated.

    Parameters
    ----------
    n : int
        Grid points per axis.
    tracers : int
        Number of tracers co-integrated with the flow.

    Returns
    -------
    int
        Bytes: the solver's full-size arrays (docs/dns.md §1; §7 compares this with the
        measured peak), the interpreter and libraries, and the tracers.
    """
    field = 3 * n**3 * 8  # one 3-component float64 field (≈ its half-spectrum in complex)
    return int(_BASELINE_BYTES + _SOLVER_ARRAYS * field + _BYTES_PER_TRACER * tracers)


def available_memory() -> int | None:
    """MemAvailable of /proc/meminfo, bytes (None where it cannot be read)."""
    try:
        with open("/proc/meminfo") as info:
            for line in info:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        return None
    return None


@dataclass(frozen=True)
class Grid:
    """A cubic periodic grid and its wavenumbers.

    Parameters
    ----------
    n : int
        Points per axis N (even, ≥ 32, a product of 2, 3 and 5).
    box_side : float
        Side L of the periodic box, m.
    """

    n: int
    box_side: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "n", _check_points(self.n))
        object.__setattr__(self, "box_side", _positive("box_side", self.box_side))

    @property
    def k0(self) -> float:
        """Fundamental wavenumber 2π/L, 1/m."""
        return 2.0 * pi / self.box_side

    @property
    def kmax(self) -> float:
        """Resolution wavenumber k_max = (N/3)(2π/L) of the 2/3 rule, 1/m."""
        return self.n * self.k0 / 3.0

    @property
    def spacing(self) -> float:
        """Grid spacing L/N, m."""
        return self.box_side / self.n

    @property
    def shape(self) -> tuple[int, int, int]:
        """Shape (N, N, N) of a physical scalar field."""
        return (self.n, self.n, self.n)

    @property
    def spectral_shape(self) -> tuple[int, int, int]:
        """Shape (N, N, N//2 + 1) of its rfftn coefficients."""
        return (self.n, self.n, self.n // 2 + 1)

    def coordinates(self) -> np.ndarray:
        """Grid coordinates x_i = i L/N along one axis, m, shape (N,)."""
        return np.arange(self.n) * self.spacing

    def wavenumbers(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Wavenumbers along the three axes, 1/m: shapes (N,), (N,), (N//2 + 1,)."""
        full = np.fft.fftfreq(self.n, 1.0 / self.n) * self.k0
        half = np.fft.rfftfreq(self.n, 1.0 / self.n) * self.k0
        return full, full.copy(), half

    def kept(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per-axis masks of the modes kept by the 2/3 rule (3|n_i| < N), shapes as
        :meth:`wavenumbers`."""
        full = 3 * np.abs(np.fft.fftfreq(self.n, 1.0 / self.n)) < self.n
        half = 3 * np.fft.rfftfreq(self.n, 1.0 / self.n) < self.n
        return full, full.copy(), half

    def k_squared(self) -> np.ndarray:
        """|k|² on the half spectrum, 1/m², shape (N, N, N//2 + 1)."""
        kx, ky, kz = self.wavenumbers()
        return kx[:, None, None] ** 2 + ky[None, :, None] ** 2 + kz[None, None, :] ** 2

    def mode_weights(self) -> np.ndarray:
        """How many modes of the full spectrum each half-spectrum coefficient stands for:
        1 on the planes n_z = 0 and n_z = N/2, else 2 (its complex conjugate), shape
        (N//2 + 1,)."""
        weights = np.full(self.n // 2 + 1, 2.0)
        weights[0] = weights[-1] = 1.0
        return weights


@dataclass(frozen=True)
class DnsSetup:
    """Physical inputs of a DNS and the grid they give.

    Attributes
    ----------
    nu : float
        Kinematic viscosity ν, m²/s.
    epsilon : float
        Prescribed energy injection rate ε, m²/s³ (the mean dissipation once stationary).
    kmax_eta : float
        Resolution k_max η asked for, with η = (ν³/ε)^{1/4}.
    grid : Grid
        N and the box side L = 2πNη/(3 k_max η).
    """

    nu: float
    epsilon: float
    kmax_eta: float
    grid: Grid

    @property
    def eta(self) -> float:
        """Kolmogorov length (ν³/ε)^{1/4} from the prescribed ε, m."""
        return (self.nu**3 / self.epsilon) ** 0.25

    @property
    def tau_eta(self) -> float:
        """Kolmogorov time (ν/ε)^{1/2}, s."""
        return (self.nu / self.epsilon) ** 0.5


def dns_setup(
    nu: float, epsilon: float, n: int, *, kmax_eta: float = DEFAULT_KMAX_ETA, tracers: int = 0
) -> DnsSetup:
    """Grid and box side of a DNS from its physical inputs, checked before any allocation.

    Parameters
    ----------
    nu : float
        Kinematic viscosity ν, m²/s.
    epsilon : float
        Energy injection rate ε, m²/s³.
    n : int
        Points per axis (even, ≥ 32, FFT-friendly).
    kmax_eta : float
        Resolution k_max η (≥ 1; a warning below 1.5).
    tracers : int
        Tracers to be co-integrated, counted in the memory check.

    Returns
    -------
    DnsSetup

    Raises
    ------
    ValueError
        A bad input, or a memory estimate above the machine's available memory.

    Examples
    --------
    Water (ν = 10⁻⁶ m²/s) at ε = 0.1 m²/s³ on 32³ points: η = 56 µm, and k_max η = 1.5
    makes the box 2.5 mm wide (docs/dns.md §1).

    >>> import simulator
    >>> setup = simulator.dns_setup(1e-6, 0.1, 32)  # ν (m²/s), ε (m²/s³), N
    >>> round(setup.eta * 1e6, 1), round(setup.grid.box_side * 1e3, 3)  # µm, mm
    (56.2, 2.513)
    >>> round(setup.grid.kmax * setup.eta, 3)
    1.5
    >>> simulator.dns_setup(1e-6, 0.1, 33)
    Traceback (most recent call last):
    ...
    ValueError: n must be even, got 33
    """
    nu = _positive("nu", nu)
    epsilon = _positive("epsilon", epsilon)
    kmax_eta = _positive("kmax_eta", kmax_eta)
    n = _check_points(n)
    if isinstance(tracers, bool) or not isinstance(tracers, int | np.integer) or tracers < 0:
        raise ValueError(f"tracers must be an integer ≥ 0, got {tracers!r}")
    if kmax_eta < MIN_KMAX_ETA:
        raise ValueError(f"kmax_eta must be at least {MIN_KMAX_ETA}, got {kmax_eta}")
    if kmax_eta < WARN_KMAX_ETA:
        logger.warning(
            "kmax_eta = %.3g < %.3g: the dissipation range is cut short", kmax_eta, WARN_KMAX_ETA
        )
    need, have = memory_estimate(n, tracers=int(tracers)), available_memory()
    if have is not None and need > have:
        raise ValueError(
            f"n = {n} needs about {need / 2**30:.1f} GiB, more than the "
            f"{have / 2**30:.1f} GiB available"
        )
    eta = (nu**3 / epsilon) ** 0.25
    box_side = 2.0 * pi * n * eta / (3.0 * kmax_eta)
    return DnsSetup(nu=nu, epsilon=epsilon, kmax_eta=kmax_eta, grid=Grid(n, box_side))
