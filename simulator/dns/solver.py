"""Pseudo-spectral Navier–Stokes solver in a periodic box (docs/dns.md §3, §4).

Solves, for incompressible velocity u (∇·u = 0),

    ∂u/∂t = u × ω − ∇(p + |u|²/2) + ν∇²u + f,    ω = ∇ × u,

in Fourier space: ∂û/∂t = P(k)·[u × ω]^(k) − ν|k|²û + f̂, where P(k) = I − kkᵀ/|k|² projects
onto divergence-free fields (and so removes the pressure). The product u × ω is formed on
the grid from six inverse transforms and brought back by three forward ones, then cut by
the 2/3 rule. Time stepping is the classical RK4 applied with an integrating factor
exp(−ν|k|²t): the viscous term is integrated exactly and only advection limits the step.

The hook of :meth:`NavierStokesSolver.advance` sees the physical velocity of each RK4
stage, already on the grid for the nonlinear term, so tracers can be advanced with RK4
on exactly the fields the flow used.
"""

from collections.abc import Callable
from dataclasses import dataclass
from math import ceil, isfinite

import numpy as np
import scipy.fft

from simulator.dns import spectral_kernels as kern
from simulator.dns.diagnostics import (
    MeasuredParameters,
    SpectralSums,
    measured_parameters,
    spectral_sums,
)
from simulator.dns.forcing import ConstantPowerForcing, ForcedBand
from simulator.dns.grid import Grid
from simulator.dns.transforms import PrunedTransforms

#: CFL number C = h·max(|u| + |v| + |w|)/Δx used by default (docs/dns.md §4: RK4 with
#: this scheme was measured stable up to about 2.4; half of that keeps a margin).
CFL_NUMBER = 1.2

#: Stage hook: hook(stage, time, velocity, velocity_hat) with stage 0…3, time in s, the
#: stage's physical velocity (3, N, N, N) in m/s and its coefficients (3, N, N, N//2 + 1)
#: (both read-only, valid during the call only).
StageHook = Callable[[int, float, np.ndarray, np.ndarray], None]


@dataclass(frozen=True)
class FlowState:
    """The flow at one instant.

    Attributes
    ----------
    velocity_hat : ndarray, shape (3, N, N, N//2 + 1), complex128
        rfftn coefficients of the velocity ('backward' normalisation: u = N⁻³ Σ û e^{ik·x}),
        divergence-free and zero outside the 2/3-rule modes, m/s.
    time : float
        t, s.
    """

    velocity_hat: np.ndarray
    time: float


@dataclass(frozen=True)
class FlowFields:
    """Physical-space fields of a state on the grid points x_i = i L/N.

    Attributes
    ----------
    velocity : ndarray, shape (3, N, N, N)
        u, m/s.
    gradient : ndarray, shape (3, 3, N, N, N)
        gradient[i, j] = ∂u_i/∂x_j, 1/s.
    dudt : ndarray, shape (3, N, N, N)
        ∂u/∂t (the local, Eulerian time derivative, forcing included), m/s².
    """

    velocity: np.ndarray
    gradient: np.ndarray
    dudt: np.ndarray

    def acceleration(self) -> np.ndarray:
        """Lagrangian acceleration a = ∂u/∂t + (u·∇)u on the grid, m/s², shape (3, N, N, N)."""
        return self.dudt + np.einsum("jxyz,ijxyz->ixyz", self.velocity, self.gradient)


def landing_step(interval: float, max_step: float) -> tuple[int, float]:
    """The largest step ≤ max_step that cuts interval into equal steps.

    Parameters
    ----------
    interval : float
        Time to cover (> 0), s.
    max_step : float
        Largest step allowed (the CFL step), s.

    Returns
    -------
    steps : int
        Number of steps n = ⌈interval/max_step⌉.
    step : float
        interval/n, s.
    """
    for name, value in (("interval", interval), ("max_step", max_step)):
        if not (isfinite(value) and value > 0):
            raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
    steps = max(1, ceil(interval / max_step * (1.0 - 1e-12)))
    return steps, interval / steps


class NavierStokesSolver:
    """Forced (or decaying) incompressible Navier–Stokes on a periodic grid.

    Parameters
    ----------
    grid : Grid
        Points and box side.
    nu : float
        Kinematic viscosity ν, m²/s.
    forcing : ConstantPowerForcing, optional
        None for a decaying flow.
    workers : int
        Threads of the FFTs (scipy.fft ``workers``).

    Examples
    --------
    Ten RK4 steps at the CFL limit on 32³ points, from a random start:

    >>> import simulator
    >>> setup = simulator.dns_setup(1e-6, 0.1, 32)
    >>> forcing = simulator.ConstantPowerForcing(0.1)
    >>> solver = simulator.NavierStokesSolver(setup.grid, nu=1e-6, forcing=forcing)
    >>> state = simulator.initial_state(solver, rng=0)
    >>> step = solver.max_step(state)  # s
    >>> for _ in range(10):
    ...     state = solver.advance(state, step)
    >>> round(state.time / step)
    10
    >>> solver.velocity(state).shape  # u on the grid, (3, N, N, N), m/s
    (3, 32, 32, 32)
    >>> scales = solver.measure(state)  # its instantaneous scales
    >>> round(scales.epsilon_injection, 12), scales.u_rms > 0  # m²/s³, m/s
    (0.1, True)
    """

    def __init__(
        self,
        grid: Grid,
        *,
        nu: float,
        forcing: ConstantPowerForcing | None = None,
        workers: int = 1,
    ) -> None:
        if not (isinstance(nu, int | float) and isfinite(nu) and nu > 0):
            raise ValueError(f"nu must be a finite number > 0, got {nu!r}")
        if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
            raise ValueError(f"workers must be an integer ≥ 1, got {workers!r}")
        self.grid = grid
        self.nu = float(nu)
        self.forcing = forcing
        self.workers = workers
        self._band = None if forcing is None else ForcedBand(grid, forcing)
        self._k = grid.wavenumbers()
        self._fft = PrunedTransforms(grid, workers=workers)
        keep_x, keep_y, _ = grid.kept()
        self._keep = (keep_x, keep_y, self._fft.kept_z)
        self._k2 = grid.k_squared()
        self._mirror = (-np.arange(grid.n)) % grid.n  # index of −n along the first two axes
        self._factors: tuple[float, np.ndarray, np.ndarray] | None = None
        self._six = np.zeros((6, *grid.spectral_shape), np.complex128)
        self._stage = np.zeros((3, *grid.spectral_shape), np.complex128)
        self.last_max_speed = 0.0
        """max(|u| + |v| + |w|) over the stages of the last :meth:`advance`, m/s."""

    # -- conversions ---------------------------------------------------------------
    def state(self, velocity: np.ndarray, *, time: float = 0.0) -> FlowState:
        """The state of a physical velocity field, projected and cut by the 2/3 rule.

        Parameters
        ----------
        velocity : ndarray, shape (3, N, N, N)
            u on the grid, m/s.
        time : float
            t, s.
        """
        velocity = np.asarray(velocity, dtype=np.float64)
        if velocity.shape != (3, *self.grid.shape):
            raise ValueError(
                f"velocity must have shape {(3, *self.grid.shape)}, got {velocity.shape}"
            )
        if not np.all(np.isfinite(velocity)):
            raise ValueError("velocity contains NaN or infinite values")
        uh = scipy.fft.rfftn(velocity, axes=(1, 2, 3), workers=self.workers)
        self._clean(uh)
        return FlowState(uh, float(time))

    def _clean(self, uh: np.ndarray) -> None:
        """Project and cut û, and make its n_z = 0 plane Hermitian, in place.

        The forcing f̂ ∝ û amplifies whatever lies in its band, at about ε/(2E_f), e-folding
        in a few T_L: a compressive part (k·û ≠ 0) or a non-Hermitian part of the n_z = 0
        plane (which the inverse transform ignores) is left alone by the projected
        nonlinear term and would grow from round-off to O(1) within 100–200 T_L. Cleaning
        every step keeps both at round-off.
        """
        kern.project_dealias(uh, *self._k, *self._keep)
        plane = uh[:, :, :, 0]
        plane += np.conj(plane[:, self._mirror][:, :, self._mirror])
        plane *= 0.5

    def velocity(self, state: FlowState) -> np.ndarray:
        """u on the grid, m/s, shape (3, N, N, N)."""
        return self._inverse(state.velocity_hat)

    def _inverse(self, fh: np.ndarray) -> np.ndarray:
        return scipy.fft.irfftn(fh, s=self.grid.shape, axes=(-3, -2, -1), workers=self.workers)

    # -- right-hand side -----------------------------------------------------------
    def _nonlinear(
        self, uh: np.ndarray, stage: int, time: float, hook: StageHook | None
    ) -> np.ndarray:
        """P·[u × ω]^ cut by the 2/3 rule, plus f̂: the tendency without viscosity."""
        kern.velocity_and_vorticity(uh, *self._k, *self._keep, self._six)
        phys = self._fft.inverse(self._six)
        speed = kern.cross_in_place(phys.reshape(6, -1))
        self.last_max_speed = max(self.last_max_speed, speed)
        if hook is not None:
            u, coefficients = phys[:3], uh.view()
            u.flags.writeable = coefficients.flags.writeable = False
            hook(stage, time, u, coefficients)
        out = self._fft.forward(phys[3:])
        kern.project_dealias(out, *self._k, *self._keep)
        if self._band is not None:
            self._band.add_to(out, uh)
        return out

    def tendency(self, state: FlowState) -> np.ndarray:
        """∂û/∂t at the state, forcing and viscosity included.

        Returns
        -------
        ndarray, shape (3, N, N, N//2 + 1), complex128
            Coefficients of ∂u/∂t (same normalisation as the state), m/s².
        """
        out = self._nonlinear(state.velocity_hat, 0, state.time, None)
        out -= self.nu * self._k2 * state.velocity_hat
        return out

    def field_coefficients(self, state: FlowState) -> np.ndarray:
        """rfftn coefficients of u, ∇u and ∂u/∂t, stacked (no transform but the tendency's).

        Returns
        -------
        ndarray, shape (15, N, N, N//2 + 1), complex128
            Rows 0–2: u_i (m/s); row 3 + 3i + j: ∂u_i/∂x_j (1/s); rows 12–14: ∂u_i/∂t
            (m/s², forcing included). Same normalisation as the state.
        """
        uh = state.velocity_hat
        kx, ky, kz = self._k
        ik = (1j * kx[:, None, None], 1j * ky[None, :, None], 1j * kz[None, None, :])
        out = np.empty((15, *self.grid.spectral_shape), np.complex128)
        out[:3] = uh
        gradient = out[3:12].reshape(3, 3, *self.grid.spectral_shape)
        for j in range(3):
            np.multiply(uh, ik[j], out=gradient[:, j])
        out[12:] = self.tendency(state)
        return out

    def fields(self, state: FlowState) -> FlowFields:
        """Velocity, velocity gradient and ∂u/∂t on the grid (15 inverse transforms)."""
        phys = self._inverse(self.field_coefficients(state))
        return FlowFields(
            velocity=phys[:3],
            gradient=phys[3:12].reshape(3, 3, *self.grid.shape),
            dudt=phys[12:],
        )

    # -- diagnostics ---------------------------------------------------------------
    def sums(self, state: FlowState) -> SpectralSums:
        """Kinetic energy, dissipation and ∫E/k dk of the state."""
        return spectral_sums(state.velocity_hat, self.grid, self.nu)

    def injection(self, state: FlowState) -> float:
        """Power ⟨u·f⟩ of the forcing at the state, m²/s³ (0 without forcing)."""
        return 0.0 if self._band is None else self._band.injection(state.velocity_hat)

    def measure(self, state: FlowState) -> MeasuredParameters:
        """The instantaneous scales of the state."""
        sums = self.sums(state)
        return measured_parameters(
            self.grid,
            self.nu,
            energy=sums.energy,
            dissipation=sums.dissipation,
            inverse_k=sums.inverse_k,
            injection=self.injection(state),
        )

    # -- time stepping -------------------------------------------------------------
    def _integrating_factors(self, step: float) -> tuple[np.ndarray, np.ndarray]:
        if self._factors is None or self._factors[0] != step:
            e_half = np.exp(-0.5 * self.nu * step * self._k2)
            self._factors = (step, e_half * e_half, e_half)
        return self._factors[1], self._factors[2]

    def max_step(self, state: FlowState, *, cfl: float = CFL_NUMBER) -> float:
        """The CFL step h = C Δx / max(|u| + |v| + |w|) at this state, s."""
        if not (isfinite(cfl) and cfl > 0):
            raise ValueError(f"cfl must be a finite number > 0, got {cfl!r}")
        speed = kern.speed_sum_max(self.velocity(state).reshape(3, -1))
        if speed == 0.0:
            raise ValueError("the flow is at rest: no CFL step")
        return cfl * self.grid.spacing / speed

    def advance(self, state: FlowState, step: float, *, hook: StageHook | None = None) -> FlowState:
        """One RK4 step of size h with the viscous term integrated exactly.

        Parameters
        ----------
        state : FlowState
            û and t.
        step : float
            h, s (see :meth:`max_step` and :func:`landing_step`).
        hook : callable(stage, time, velocity, velocity_hat), optional
            Called at the four stages (times t, t + h/2, t + h/2, t + h) with the physical
            velocity of the stage, shape (3, N, N, N), m/s, and its coefficients, shape
            (3, N, N, N//2 + 1), both read-only and valid only during the call. RK4 on
            tracers: stage s interpolates this field at the tracers' stage-s positions.

        Returns
        -------
        FlowState
            û and t + h (a new array; the input is not modified).
        """
        if not (isfinite(step) and step > 0):
            raise ValueError(f"step must be a finite number > 0, got {step!r}")
        e_full, e_half = self._integrating_factors(step)
        u0, t, h = state.velocity_hat, state.time, step
        acc, us, keep = np.zeros_like(u0), self._stage, self._keep
        self.last_max_speed = 0.0
        k = self._nonlinear(u0, 0, t, hook)
        kern.rk_first(u0, k, e_full, e_half, h, *keep, acc, us)
        k = self._nonlinear(us, 1, t + 0.5 * h, hook)
        kern.rk_second(u0, k, e_half, h, *keep, acc, us)
        k = self._nonlinear(us, 2, t + 0.5 * h, hook)
        kern.rk_third(u0, k, e_full, e_half, h, *keep, acc, us)
        k = self._nonlinear(us, 3, t + h, hook)
        kern.rk_fourth(k, h, *keep, acc)
        self._clean(acc)
        return FlowState(acc, t + h)
