"""Tracers advected through the DNS, in step with its time stepping (docs/dns.md §8).

A tracer obeys dX/dt = u(X, t). The flow is advanced by RK4 (:mod:`simulator.dns.solver`);
the tracers are advanced by the same RK4 on exactly the same stage fields: at stage s
the solver's stage velocity, interpolated by a periodic quintic spline
(:mod:`simulator.dns.interpolate`) at the tracers' stage positions

    X₀ = X,  X₁ = X + (h/2)k₀,  X₂ = X + (h/2)k₁,  X₃ = X + h k₂,
    X ← X + (h/6)(k₀ + 2k₁ + 2k₂ + k₃),   k_s = u_s(X_s),

so the pair (u, X) is one RK4 system and the tracers carry no time-interpolation error.
The steps land on the output times exactly (each interval cut into equal steps no longer
than the CFL step). At each output time the truth is interpolated from the state's own
fields: the velocity u, and the Lagrangian acceleration a = ∂u/∂t + (u·∇)u from the
interpolated ∂u/∂t (the Navier–Stokes right-hand side, forcing included) and ∇u.

The box tiles space periodically, so tracers may be anywhere: a measurement volume
larger than the box sees the same field repeated (docs/dns.md §8 says which
separations that limits).
"""

from dataclasses import dataclass

import numpy as np

from simulator.dns.interpolate import DEFAULT_ORDER, interpolate, spline_coefficients
from simulator.dns.solver import FlowState, NavierStokesSolver, landing_step

#: RK4 stage weights and the fraction of the step at which the next stage is taken.
_WEIGHTS = (1.0, 2.0, 2.0, 1.0)
_NEXT = (0.5, 0.5, 1.0)


@dataclass(frozen=True, eq=False)
class TracerTruth:
    """Tracers followed over output times.

    Attributes
    ----------
    positions : ndarray, shape (T, P, 3)
        X at each output time, m.
    velocity : ndarray, shape (T, P, 3)
        u(X, t), m/s.
    acceleration : ndarray, shape (T, P, 3)
        a = ∂u/∂t + (u·∇)u at (X, t), m/s².
    """

    positions: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray


def truth_at(
    solver: NavierStokesSolver, state: FlowState, points: np.ndarray, *, order: int = DEFAULT_ORDER
) -> tuple[np.ndarray, np.ndarray]:
    """Velocity and Lagrangian acceleration of the state at points.

    Parameters
    ----------
    solver : NavierStokesSolver
        The flow's solver (grid, ν, forcing).
    state : FlowState
        The flow at one instant.
    points : ndarray, shape (P, 3)
        Positions, m (anywhere: the box tiles space).
    order : {3, 5}
        Spline degree.

    Returns
    -------
    velocity : ndarray, shape (P, 3)
        u, m/s.
    acceleration : ndarray, shape (P, 3)
        ∂u/∂t + (u·∇)u, m/s².
    """
    values = interpolate(
        spline_coefficients(solver.field_coefficients(state), order=order, workers=solver.workers),
        solver.grid.box_side,
        points,
        order=order,
    )
    u, grad, dudt = values[:, :3], values[:, 3:12].reshape(-1, 3, 3), values[:, 12:]
    return u, dudt + np.einsum("pj,pij->pi", u, grad)


class _StageTracers:
    """The tracers' side of one RK4 step, fed by the solver's stage hook."""

    def __init__(self, x: np.ndarray, step: float, box_side: float, order: int, workers: int):
        self.x, self.h, self.box, self.order, self.workers = x, step, box_side, order, workers
        self.at = x
        self.sum = np.zeros_like(x)

    def __call__(self, stage: int, time: float, velocity, velocity_hat: np.ndarray) -> None:
        coeffs = spline_coefficients(velocity_hat, order=self.order, workers=self.workers)
        k = interpolate(coeffs, self.box, self.at, order=self.order)
        self.sum += _WEIGHTS[stage] * k
        if stage < 3:
            self.at = self.x + _NEXT[stage] * self.h * k

    def end(self) -> np.ndarray:
        """X at the end of the step."""
        return self.x + (self.h / 6.0) * self.sum


def follow_tracers(
    solver: NavierStokesSolver,
    state: FlowState,
    x0: np.ndarray,
    times: np.ndarray,
    *,
    order: int = DEFAULT_ORDER,
) -> tuple[TracerTruth, FlowState]:
    """Advance the flow and its tracers together over ``times``.

    Parameters
    ----------
    solver : NavierStokesSolver
        The flow's solver.
    state : FlowState
        The flow at the start (its time is the times' origin).
    x0 : ndarray, shape (P, 3)
        Tracer positions at the start, m.
    times : ndarray, shape (T,)
        Output times after the start, s: 0 first, strictly increasing.
    order : {3, 5}
        Spline degree of the interpolation.

    Returns
    -------
    TracerTruth
        Positions, velocity and acceleration at the output times.
    FlowState
        The flow at the last output time.

    Examples
    --------
    Two tracers carried 2 ms by a random 32³ flow, the flow advanced with them:

    >>> import numpy as np
    >>> import simulator
    >>> setup = simulator.dns_setup(1e-6, 0.1, 32)
    >>> forcing = simulator.ConstantPowerForcing(0.1)
    >>> solver = simulator.NavierStokesSolver(setup.grid, nu=1e-6, forcing=forcing)
    >>> state = simulator.initial_state(solver, rng=0)
    >>> x0 = np.array([[0.0, 0.0, 0.0], [1e-3, 0.0, 0.0]])  # m
    >>> truth, end = simulator.follow_dns_tracers(solver, state, x0, [0.0, 1e-3, 2e-3])
    >>> truth.positions.shape  # (T, P, 3), m; also velocity (m/s), acceleration (m/s²)
    (3, 2, 3)
    >>> round(float(end.time) * 1e3, 6)  # the flow at the last output time, ms
    2.0
    """
    times = np.asarray(times, dtype=float)
    if times.ndim != 1 or times[0] != 0 or np.any(np.diff(times) <= 0):
        raise ValueError(f"times must start at 0 and increase strictly, got {times}")
    x = np.array(x0, dtype=np.float64)
    if x.ndim != 2 or x.shape[1] != 3 or not np.isfinite(x).all():
        raise ValueError(f"tracer positions must be finite, shape (P, 3), got {x.shape}")
    shape = (len(times), len(x), 3)
    positions, velocity, acceleration = np.empty(shape), np.empty(shape), np.empty(shape)
    start = state.time
    for f, t in enumerate(times):
        if f:
            steps, h = landing_step(start + t - state.time, solver.max_step(state))
            for _ in range(steps):
                tracers = _StageTracers(x, h, solver.grid.box_side, order, solver.workers)
                state = solver.advance(state, h, hook=tracers)
                x = tracers.end()
        positions[f] = x
        velocity[f], acceleration[f] = truth_at(solver, state, x, order=order)
    return TracerTruth(positions, velocity, acceleration), state
