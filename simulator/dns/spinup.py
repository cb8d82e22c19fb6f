"""From random noise to a stationary flow, and independent snapshots of it (docs/dns.md §5).

1. :func:`initial_state`: random phases with a prescribed spectrum shape (default
   E₀ ∝ k⁴ exp(−2(k/k_p)²) peaking at the forced band), divergence-free, from ``rng``.
2. :func:`spin_up`: steps at the CFL limit until a given number of eddy times
   ∫dt/T_L(t) has elapsed, T_L(t) = L/u′ measured at every step.
3. Optionally, a finer grid starts from a stationary coarse one: :func:`coarse_setup`
   has N/2 points in the same box with ν·2^{4/3} (so the same k_max η), and
   :func:`upsample` pads its spectrum with zeros.
4. :func:`stationary_window`: snapshots a fixed interval apart (3 T_L: independent),
   each interval cut into equal steps, and the time-averaged scales of the window.
"""

import logging
from collections.abc import Callable
from dataclasses import dataclass
from math import isfinite

import numpy as np

from simulator.dns.diagnostics import MeasuredParameters, measured_parameters
from simulator.dns.forcing import DEFAULT_BAND, ConstantPowerForcing
from simulator.dns.grid import DnsSetup, Grid
from simulator.dns.solver import CFL_NUMBER, FlowState, NavierStokesSolver, landing_step

logger = logging.getLogger(__name__)

#: Eddy times ∫dt/T_L from noise to stationarity (docs/dns.md §5: measured at 64³).
SPIN_UP_FROM_NOISE = 6.0

#: Eddy times from an upsampled stationary coarse field (docs/dns.md §5: measured at 128³).
SPIN_UP_FROM_COARSE = 4.0

#: Stationary kinetic energy over (ε/k₀)^{2/3}, k₀ = 2π/L, with the default forcing
#: band (docs/dns.md §5); the initial noise gets this energy.
STATIONARY_ENERGY = 2.4

#: Snapshot spacing in eddy times T_L (docs/dns.md §5: the field's correlation between
#: snapshots, measured at 128³, is 0.42 at 1 T_L, 0.16 at 2 T_L and 0.02 at 3 T_L).
DEFAULT_SPACING = 3.0

#: Progress callback: progress(done, total).
Progress = Callable[[float, float], None]


def _eddy_time(energy, inverse_k):
    """L/u′ with L = (π/(2u′²))∫E/k dk and u′² = (2/3)E (arrays or numbers), s."""
    return np.pi / 2.0 * inverse_k / (2.0 * energy / 3.0) ** 1.5


@dataclass(frozen=True)
class History:
    """Time series of a run, one entry per step (the state at the start of the step).

    Attributes
    ----------
    times : ndarray, shape (S,)
        t, s.
    energy : ndarray, shape (S,)
        Kinetic energy ½⟨|u|²⟩, m²/s².
    dissipation : ndarray, shape (S,)
        2ν⟨s_ij s_ij⟩, m²/s³.
    inverse_k : ndarray, shape (S,)
        ∫E(k)/k dk, m³/s².
    steps : ndarray, shape (S,)
        Step sizes h, s.
    """

    times: np.ndarray
    energy: np.ndarray
    dissipation: np.ndarray
    inverse_k: np.ndarray
    steps: np.ndarray

    def eddy_time(self) -> np.ndarray:
        """T_L = L/u′ at each entry, s, with L = (π/(2u′²))∫E/k dk, u′² = (2/3)E."""
        return _eddy_time(self.energy, self.inverse_k)

    def mean(self, name: str) -> float:
        """Time average of one series over the run (each entry weighted by its step)."""
        return float(np.sum(getattr(self, name) * self.steps) / np.sum(self.steps))


class _Recorder:
    def __init__(self) -> None:
        self.rows: list[tuple[float, ...]] = []

    def add(self, solver: NavierStokesSolver, state: FlowState, step: float) -> float:
        """Record the state; returns its eddy time T_L, s."""
        s = solver.sums(state)
        self.rows.append((state.time, s.energy, s.dissipation, s.inverse_k, step))
        return float(_eddy_time(s.energy, s.inverse_k))

    def history(self) -> History:
        a = np.array(self.rows, dtype=float).reshape(-1, 5)
        return History(*(np.ascontiguousarray(a[:, c]) for c in range(5)))


def _check_count(name: str, value, minimum: float) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ValueError(f"{name} must be a number ≥ {minimum}, got {value!r}")
    if not (isfinite(value) and value >= minimum):
        raise ValueError(f"{name} must be a number ≥ {minimum}, got {value!r}")
    return float(value)


def _check_snapshots(snapshots) -> None:
    if isinstance(snapshots, bool) or not isinstance(snapshots, int) or snapshots < 1:
        raise ValueError(f"snapshots must be an integer ≥ 1, got {snapshots!r}")


def initial_state(
    solver: NavierStokesSolver,
    *,
    rng: np.random.Generator | int | None = None,
    energy: float | None = None,
    spectrum: Callable[[np.ndarray], np.ndarray] | None = None,
) -> FlowState:
    """A random divergence-free field with a given spectrum shape, at t = 0.

    Gaussian white noise on the grid is transformed, projected, cut by the 2/3 rule and
    rescaled shell by shell to the shape, then to the energy.

    Parameters
    ----------
    solver : NavierStokesSolver
        Its grid and forcing (the default peak k_p is the forced band's edge).
    rng : numpy.random.Generator or int or None
        Source of the noise (same seed, same bits).
    energy : float, optional
        Kinetic energy ½⟨|u|²⟩, m²/s²; default STATIONARY_ENERGY (ε/k₀)^{2/3} with a
        forcing, else required.
    spectrum : callable(k) -> E₀(k), optional
        Shape of the spectrum (any scale), k in 1/m; default k⁴ exp(−2(k/k_p)²).

    Returns
    -------
    FlowState
        û, shape (3, N, N, N//2 + 1), m/s (``velocity_hat``), at t = 0 (``time``).

    Examples
    --------
    With a forcing, the start holds the stationary energy 2.4 (ε/k₀)^{2/3}
    (docs/dns.md §5), so that the spin-up need not build it up:

    >>> import simulator
    >>> setup = simulator.dns_setup(1e-6, 0.1, 32)
    >>> forcing = simulator.ConstantPowerForcing(0.1)
    >>> solver = simulator.NavierStokesSolver(setup.grid, nu=1e-6, forcing=forcing)
    >>> state = simulator.initial_state(solver, rng=0)
    >>> state.velocity_hat.shape, state.time
    ((3, 32, 32, 17), 0.0)
    >>> energy = solver.sums(state).energy  # ½⟨|u|²⟩, m²/s²
    >>> round(energy / (2.4 * (0.1 / setup.grid.k0) ** (2 / 3)), 9)
    1.0
    """
    grid = solver.grid
    band = DEFAULT_BAND if solver.forcing is None else solver.forcing.band
    if energy is None:
        if solver.forcing is None:
            raise ValueError("energy is required for a flow without forcing")
        energy = STATIONARY_ENERGY * (solver.forcing.epsilon / grid.k0) ** (2.0 / 3.0)
    if not (isfinite(energy) and energy > 0):
        raise ValueError(f"energy must be a finite number > 0, got {energy!r}")
    if spectrum is None:
        peak = band * grid.k0

        def spectrum(k: np.ndarray) -> np.ndarray:
            return k**4 * np.exp(-2.0 * (k / peak) ** 2)

    noise = np.random.default_rng(rng).standard_normal((3, *grid.shape))
    uh = solver.state(noise).velocity_hat
    k = np.sqrt(grid.k_squared())
    shell = np.rint(k / grid.k0).astype(np.intp)
    mode_energy = grid.mode_weights() * np.sum(np.abs(uh) ** 2, axis=0)
    have = np.bincount(shell.ravel(), weights=mode_energy.ravel())
    shells = np.arange(len(have)) * grid.k0
    want = np.zeros_like(have)
    want[1:] = np.asarray(spectrum(shells[1:]), dtype=float)
    if not (np.all(np.isfinite(want)) and np.all(want >= 0)):
        raise ValueError("spectrum must be finite and ≥ 0 at the grid's shells")
    gain = np.sqrt(np.divide(want, have, out=np.zeros_like(have), where=have > 0))
    uh *= gain[shell]
    total = np.sum(grid.mode_weights() * np.sum(np.abs(uh) ** 2, axis=0)) / (2.0 * grid.n**6)
    if not total > 0:
        raise ValueError("spectrum holds no energy on the grid's kept modes")
    uh *= np.sqrt(energy / total)
    return FlowState(uh, 0.0)


def spin_up(
    solver: NavierStokesSolver,
    state: FlowState,
    *,
    eddy_times: float = SPIN_UP_FROM_NOISE,
    cfl: float = CFL_NUMBER,
    progress: Progress | None = None,
) -> tuple[FlowState, History]:
    """Step at the CFL limit until ∫dt/T_L(t) reaches eddy_times.

    The step is C Δx / max(|u| + |v| + |w|) with the speed of the previous step's stages
    (of the state for the first step).

    Parameters
    ----------
    solver : NavierStokesSolver
    state : FlowState
        Start.
    eddy_times : float
        Eddy times to run (≥ 0).
    cfl : float
        CFL number C.
    progress : callable(done, total), optional
        Called after each step with the eddy times elapsed and eddy_times.

    Returns
    -------
    state : FlowState
        The state reached.
    history : History
        One entry per step.

    Examples
    --------
    Half an eddy time from a random start on 32³ points (six make it stationary):

    >>> import numpy as np
    >>> import simulator
    >>> setup = simulator.dns_setup(1e-6, 0.1, 32)
    >>> forcing = simulator.ConstantPowerForcing(0.1)
    >>> solver = simulator.NavierStokesSolver(setup.grid, nu=1e-6, forcing=forcing)
    >>> start = simulator.initial_state(solver, rng=0)
    >>> state, history = simulator.spin_up(solver, start, eddy_times=0.5)
    >>> history.energy.shape == history.times.shape  # one entry per step, m²/s² and s
    True
    >>> elapsed = np.sum(history.steps / history.eddy_time())  # ∫dt/T_L
    >>> bool(0.5 <= elapsed < 0.6)
    True
    """
    eddy_times = _check_count("eddy_times", eddy_times, 0.0)
    recorder = _Recorder()
    done = 0.0
    step = solver.max_step(state, cfl=cfl)
    while done < eddy_times:
        t_l = recorder.add(solver, state, step)
        state = solver.advance(state, step)
        if not np.all(np.isfinite(state.velocity_hat[:, :2, :2, :2])):
            raise FloatingPointError(f"the flow blew up at t = {state.time:.6g} s")
        done += step / t_l
        if progress is not None:
            progress(min(done, eddy_times), eddy_times)
        step = cfl * solver.grid.spacing / solver.last_max_speed
    history = recorder.history()
    if len(history.times):
        logger.info(
            "spin-up: %d steps, %.3g s, %.2f eddy times; last ε_diss/ε_in = %.3f",
            len(history.times),
            state.time - history.times[0],
            done,
            history.dissipation[-1] / max(solver.injection(state), 1e-300),
        )
    return state, history


def coarse_setup(setup: DnsSetup) -> DnsSetup:
    """The same box and ε on N/2 points with ν·2^{4/3}, hence the same k_max η.

    Raises
    ------
    ValueError
        N/2 is not an acceptable grid.
    """
    return DnsSetup(
        setup.nu * 2.0 ** (4.0 / 3.0),
        setup.epsilon,
        setup.kmax_eta,
        Grid(setup.grid.n // 2, setup.grid.box_side),
    )


def upsample(state: FlowState, coarse: Grid, fine: Grid) -> FlowState:
    """The coarse field on a finer grid of the same box: its spectrum padded with zeros.

    Parameters
    ----------
    state : FlowState
        On the coarse grid.
    coarse, fine : Grid
        Same box side; fine.n ≥ coarse.n.
    """
    if not np.isclose(coarse.box_side, fine.box_side, rtol=1e-12) or fine.n < coarse.n:
        raise ValueError(
            f"cannot upsample from {coarse.n}³ in a {coarse.box_side:.6g} m box "
            f"to {fine.n}³ in a {fine.box_side:.6g} m box"
        )
    nc, nf = coarse.n, fine.n
    fh = np.zeros((3, *fine.spectral_shape), np.complex128)
    n = np.fft.fftfreq(nc, 1.0 / nc).astype(int)
    rows = np.where(n >= 0, n, nf + n)
    fh[:, rows[:, None], rows[None, :], : nc // 2 + 1] = state.velocity_hat
    fh[:, :, :, nc // 2] = 0.0  # the coarse Nyquist plane has no counterpart (cut anyway)
    fh *= (nf / nc) ** 3
    return FlowState(fh, state.time)


@dataclass(frozen=True)
class StationaryRun:
    """Snapshots of a stationary flow and its time-averaged scales.

    Attributes
    ----------
    states : tuple of FlowState
        The snapshots, ``interval`` apart (empty when they went to a callback).
    times : ndarray, shape (S,)
        Their times, s.
    interval : float
        Spacing of the snapshots, s.
    history : History
        Every step of the window.
    parameters : MeasuredParameters
        From the time-averaged energy, dissipation and ∫E/k dk of the window.
    """

    states: tuple[FlowState, ...]
    times: np.ndarray
    interval: float
    history: History
    parameters: MeasuredParameters

    @property
    def energy_budget(self) -> float:
        """Mean dissipation over mean injection in the window (1 when stationary)."""
        return self.parameters.epsilon / self.parameters.epsilon_injection


def stationary_window(
    solver: NavierStokesSolver,
    state: FlowState,
    *,
    snapshots: int,
    interval: float,
    cfl: float = CFL_NUMBER,
    on_snapshot: Callable[[FlowState], None] | None = None,
    progress: Progress | None = None,
) -> StationaryRun:
    """Snapshots ``interval`` apart, the first at the start; the averages over the window.

    Each interval is cut into equal steps no longer than the CFL step of its start
    (:func:`~simulator.dns.solver.landing_step`), so the snapshots fall exactly on
    t₀ + s·interval.

    Parameters
    ----------
    solver : NavierStokesSolver
        With a forcing.
    state : FlowState
        A stationary state (after :func:`spin_up`).
    snapshots : int
        Number S ≥ 1 of snapshots; the window lasts (S − 1)·interval (one interval if S = 1).
    interval : float
        Spacing, s (3 T_L for independent snapshots).
    cfl : float
        CFL number of the steps' upper bound.
    on_snapshot : callable(FlowState), optional
        Receives each snapshot instead of keeping it in memory (e.g. to write it).
    progress : callable(done, total), optional
        Called with the snapshots taken and S.
    """
    _check_snapshots(snapshots)
    interval = _check_count("interval", interval, 0.0)
    if interval == 0.0:
        raise ValueError("interval must be > 0")
    if solver.forcing is None:
        raise ValueError("a stationary window needs a forcing")
    recorder, kept, times = _Recorder(), [], []
    intervals = max(snapshots - 1, 1)
    for s in range(intervals + 1):
        if s < snapshots:
            times.append(state.time)
            (kept.append if on_snapshot is None else on_snapshot)(state)
            if progress is not None:
                progress(s + 1, snapshots)
        if s == intervals:
            break
        steps, step = landing_step(interval, solver.max_step(state, cfl=cfl))
        for _ in range(steps):
            recorder.add(solver, state, step)
            state = solver.advance(state, step)
    history = recorder.history()
    parameters = measured_parameters(
        solver.grid,
        solver.nu,
        energy=history.mean("energy"),
        dissipation=history.mean("dissipation"),
        inverse_k=history.mean("inverse_k"),
        injection=solver.forcing.epsilon,
    )
    logger.info(
        "stationary window: %d snapshots, %d steps, ε_diss/ε_in = %.4f, R_λ = %.1f",
        snapshots,
        len(history.times),
        parameters.epsilon / parameters.epsilon_injection,
        parameters.r_lambda,
    )
    return StationaryRun(tuple(kept), np.array(times), interval, history, parameters)


def stationary_flow(
    setup: DnsSetup,
    *,
    snapshots: int,
    spacing: float = DEFAULT_SPACING,
    rng: np.random.Generator | int | None = None,
    band: float = DEFAULT_BAND,
    from_coarse: bool = True,
    workers: int = 1,
    on_snapshot: Callable[[FlowState], None] | None = None,
    progress: Progress | None = None,
) -> tuple[NavierStokesSolver, StationaryRun]:
    """Spin a flow up from noise and keep independent snapshots of its stationary state.

    Parameters
    ----------
    setup : DnsSetup
        ν, ε, N and the box (from :func:`~simulator.dns.grid.dns_setup`).
    snapshots : int
        Snapshots to keep.
    spacing : float
        Their spacing in eddy times T_L (≥ 1; the default 3 makes them independent),
        T_L measured at the end of the spin-up (averaged over its last eddy time).
    rng : numpy.random.Generator or int or None
        Source of the initial noise.
    band : float
        Forced band k_f/(2π/L).
    from_coarse : bool
        Spin up N/2 first (same box, same k_max η) and upsample, when N/2 ≥ 32.
    workers : int
        FFT threads.
    on_snapshot : callable(FlowState), optional
        Receives each snapshot instead of keeping it.
    progress : callable(done, total), optional
        Called with the fraction of the work done and 1 (the phases weighted by their
        estimated cost).

    Returns
    -------
    solver : NavierStokesSolver
        The solver of the fine grid (to continue or to evaluate fields).
    run : StationaryRun

    Examples
    --------
    The smallest flow, 32³ points at ε = 0.1 m²/s³ in water, takes 2–3 s of CPU (six
    eddy times of spin-up, about 230 steps)::

        setup = simulator.dns_setup(1e-6, 0.1, 32)
        solver, run = simulator.stationary_flow(setup, snapshots=1, rng=0)
        run.states[0].velocity_hat.shape  # (3, 32, 32, 17)
        run.parameters.r_lambda           # 19.1, R_λ of the window
        run.energy_budget                 # 0.94, mean dissipation over injection

    Its options are checked before any work:

    >>> import simulator
    >>> setup = simulator.dns_setup(1e-6, 0.1, 32)
    >>> simulator.stationary_flow(setup, snapshots=4, spacing=0.5)
    Traceback (most recent call last):
    ...
    ValueError: spacing must be a number ≥ 1.0, got 0.5
    """
    spacing = _check_count("spacing", spacing, 1.0)
    _check_snapshots(snapshots)
    forcing = ConstantPowerForcing(setup.epsilon, band)
    use_coarse = from_coarse and setup.grid.n // 2 >= 32
    # work of each phase, in fine-grid eddy times (the coarse grid costs about 1/16)
    plan = [("coarse", SPIN_UP_FROM_NOISE / 16.0)] if use_coarse else []
    plan += [
        ("spin-up", SPIN_UP_FROM_COARSE if use_coarse else SPIN_UP_FROM_NOISE),
        ("window", max(snapshots - 1, 1) * spacing),
    ]
    weights = dict(plan)
    starts = dict(zip(weights, np.cumsum([0.0, *weights.values()])[:-1], strict=True))
    total = sum(weights.values())

    def report(name: str) -> Progress | None:
        if progress is None:
            return None
        return lambda done, of: progress((starts[name] + weights[name] * done / of) / total, 1.0)

    solver = NavierStokesSolver(setup.grid, nu=setup.nu, forcing=forcing, workers=workers)
    if use_coarse:
        small = coarse_setup(setup)
        coarse_solver = NavierStokesSolver(
            small.grid, nu=small.nu, forcing=forcing, workers=workers
        )
        state = initial_state(coarse_solver, rng=rng)
        state, _ = spin_up(
            coarse_solver, state, eddy_times=SPIN_UP_FROM_NOISE, progress=report("coarse")
        )
        state = upsample(state, small.grid, setup.grid)
        del coarse_solver
        eddy_times = SPIN_UP_FROM_COARSE
    else:
        state = initial_state(solver, rng=rng)
        eddy_times = SPIN_UP_FROM_NOISE
    state, history = spin_up(solver, state, eddy_times=eddy_times, progress=report("spin-up"))
    t_l = history.eddy_time()
    last = history.times >= history.times[-1] - t_l[-1]
    interval = spacing * float(np.sum(t_l[last] * history.steps[last]) / history.steps[last].sum())
    run = stationary_window(
        solver,
        state,
        snapshots=snapshots,
        interval=interval,
        on_snapshot=on_snapshot,
        progress=report("window"),
    )
    return solver, run
