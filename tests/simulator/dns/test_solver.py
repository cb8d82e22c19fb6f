"""Pseudo-spectral solver: an exact Navier–Stokes solution, incompressibility, the exact
injection of ε, energy conservation by the nonlinear term, the 2/3 rule, RK4's order, the
stage hook and the fields."""

from math import pi

import numpy as np
import pytest
import scipy.fft
from scipy.integrate import solve_ivp

from simulator.dns.forcing import ConstantPowerForcing
from simulator.dns.grid import Grid
from simulator.dns.solver import FlowState, NavierStokesSolver, landing_step

GRID = Grid(32, 2 * pi)
NU = 0.05


def mesh(grid: Grid) -> tuple[np.ndarray, ...]:
    x = grid.coordinates()
    return np.meshgrid(x, x, x, indexing="ij")


def taylor_green(grid: Grid, k: float, plane: int) -> np.ndarray:
    """The 2-D Taylor–Green vortex (sin kx cos ky, −cos kx sin ky) in one coordinate plane.

    plane 0: (x, y); 1: (y, z); 2: (z, x).
    """
    xyz = mesh(grid)
    a, b = plane, (plane + 1) % 3
    u = np.zeros((3, *grid.shape))
    u[a] = np.sin(k * xyz[a]) * np.cos(k * xyz[b])
    u[b] = -np.cos(k * xyz[a]) * np.sin(k * xyz[b])
    return u


def random_state(solver: NavierStokesSolver, seed: int, *, peak: float = 3.0) -> FlowState:
    """A smooth random divergence-free state with energy near the low wavenumbers."""
    noise = np.random.default_rng(seed).standard_normal((3, *solver.grid.shape))
    uh = solver.state(noise).velocity_hat
    k = np.sqrt(solver.grid.k_squared()) / solver.grid.k0
    uh *= np.exp(-((k / peak) ** 2))
    return FlowState(uh / np.sqrt(np.mean(solver.velocity(FlowState(uh, 0.0)) ** 2)), 0.0)


@pytest.mark.parametrize("plane", [0, 1, 2])
def test_taylor_green_decays_exactly(plane):
    # (u·∇)u of this vortex is a gradient, removed by the projection: the exact solution
    # is u₀ exp(−2νk²t). One decay time 1/(2νk²) in CFL steps; the integrating factor is
    # exact, so only round-off remains (~1e-15 per step): 1e-8 leaves a factor 10⁶.
    # A wrong viscous factor (e.g. νk²) errs by O(1); a missing projection, by O(h).
    k = 2.0
    solver = NavierStokesSolver(GRID, nu=NU)
    u0 = taylor_green(GRID, k, plane)
    state = solver.state(u0)
    decay = 1.0 / (2 * NU * k**2)
    steps, h = landing_step(decay, solver.max_step(state))
    for _ in range(steps):
        state = solver.advance(state, h)
    assert state.time == pytest.approx(decay, rel=1e-14)
    exact = u0 * np.exp(-2 * NU * k**2 * state.time)
    error = np.abs(solver.velocity(state) - exact).max() / np.abs(exact).max()
    assert error <= 1e-8


def test_divergence_stays_zero():
    solver = NavierStokesSolver(GRID, nu=NU, forcing=ConstantPowerForcing(1.0))
    state = random_state(solver, 1)
    for _ in range(3):
        state = solver.advance(state, 0.5 * solver.max_step(state))
    kx, ky, kz = GRID.wavenumbers()
    uh = state.velocity_hat
    div = kx[:, None, None] * uh[0] + ky[None, :, None] * uh[1] + kz[None, None, :] * uh[2]
    scale = np.sqrt(GRID.k_squared()) * np.sqrt(np.sum(np.abs(uh) ** 2, axis=0))
    # k·û is a sum of three products: round-off is a few ulps of |k||û|
    assert np.abs(div).max() <= 1e-14 * scale.max()
    grad = solver.fields(state).gradient
    trace = grad[0, 0] + grad[1, 1] + grad[2, 2]
    assert np.abs(trace).max() <= 1e-12 * np.abs(grad).max()


def test_tendency_matches_an_independent_numpy_evaluation():
    # ∂û/∂t = P·D·FFT(u × ∇×u) − ν|k|²û + f̂ with full rfftn/irfftn and explicit masks
    forcing = ConstantPowerForcing(0.7)
    solver = NavierStokesSolver(GRID, nu=NU, forcing=forcing)
    state = random_state(solver, 2, peak=6.0)
    uh = state.velocity_hat
    kx, ky, kz = GRID.wavenumbers()
    k = [kx[:, None, None], ky[None, :, None], kz[None, None, :]]
    k = [np.broadcast_to(c, GRID.spectral_shape) for c in k]
    u = scipy.fft.irfftn(uh, s=GRID.shape, axes=(1, 2, 3))
    omega_hat = 1j * np.stack(
        [k[1] * uh[2] - k[2] * uh[1], k[2] * uh[0] - k[0] * uh[2], k[0] * uh[1] - k[1] * uh[0]]
    )
    omega = scipy.fft.irfftn(omega_hat, s=GRID.shape, axes=(1, 2, 3))
    ch = scipy.fft.rfftn(np.cross(u, omega, axis=0), axes=(1, 2, 3))
    k2 = GRID.k_squared()
    safe = np.where(k2 > 0, k2, 1.0)
    ch -= np.stack(k) * (k[0] * ch[0] + k[1] * ch[1] + k[2] * ch[2]) / safe
    n = np.stack([np.abs(c) / GRID.k0 for c in k])
    keep = np.all(3 * n < GRID.n, axis=0) & (k2 > 0)
    ch *= keep
    band = (k2 > 0) & (k2 <= (2 * GRID.k0) ** 2 * (1 + 1e-12))
    weights = GRID.mode_weights()
    e_band = 0.5 * np.sum(weights * band * np.sum(np.abs(uh) ** 2, axis=0)) / GRID.n**6
    expected = ch - NU * k2 * uh + band * (0.7 / (2 * e_band)) * uh
    got = solver.tendency(state)
    assert np.abs(got - expected).max() <= 1e-12 * np.abs(expected).max()


def test_forcing_injects_exactly_epsilon():
    # ⟨u·f⟩ on the grid, f = tendency(forced) − tendency(unforced), equals ε: the forcing
    # is ε/(2E_f)·û on its band. Round-off of sums over 32³ points: 1e-12 relative.
    epsilon = 0.37
    forced = NavierStokesSolver(GRID, nu=NU, forcing=ConstantPowerForcing(epsilon))
    free = NavierStokesSolver(GRID, nu=NU)
    for seed in (3, 4):
        state = random_state(forced, seed)
        f = scipy.fft.irfftn(
            forced.tendency(state) - free.tendency(state), s=GRID.shape, axes=(1, 2, 3)
        )
        u = forced.velocity(state)
        assert np.mean(np.sum(u * f, axis=0)) == pytest.approx(epsilon, rel=1e-12)
        assert forced.injection(state) == pytest.approx(epsilon, rel=1e-13)


def test_energy_changes_by_injection_minus_dissipation():
    # The dealiased, projected u × ω does no work on a dealiased divergence-free u, so
    # dE/dt = ⟨u·∂u/∂t⟩ = ε_in − 2ν⟨s_ij s_ij⟩ exactly, to round-off (1e-11 of ε_diss).
    solver = NavierStokesSolver(GRID, nu=NU, forcing=ConstantPowerForcing(0.5))
    state = random_state(solver, 5, peak=8.0)
    dudt = scipy.fft.irfftn(solver.tendency(state), s=GRID.shape, axes=(1, 2, 3))
    dedt = np.mean(np.sum(solver.velocity(state) * dudt, axis=0))
    diss = solver.sums(state).dissipation
    assert dedt == pytest.approx(0.5 - diss, abs=1e-11 * diss)


def test_a_step_removes_what_the_forcing_would_amplify():
    # f̂ ∝ û amplifies anything in its band at ε/(2E_f), e-folding in a few T_L. A
    # compressive part (k ∥ û) is untouched by the projected nonlinear term, and a
    # non-Hermitian n_z = 0 plane is invisible to the inverse transform: left in the
    # state they would grow from round-off to O(1) (seen after ~100 T_L at 64³). Each
    # step must bring them back to round-off.
    solver = NavierStokesSolver(GRID, nu=NU, forcing=ConstantPowerForcing(1.0))
    state = random_state(solver, 9)
    uh = state.velocity_hat.copy()
    size = 1e-3 * np.abs(uh).max()
    uh[0, 1, 0, 0] += size  # u_x along k = (k₀, 0, 0): compressive, with its conjugate
    uh[0, -1, 0, 0] += size
    uh[0, 0, 2, 0] += 1j * size  # u_x at ±(0, 2, 0), solenoidal but anti-Hermitian
    uh[0, 0, -2, 0] += 1j * size
    after = solver.advance(FlowState(uh, 0.0), 0.5 * solver.max_step(state)).velocity_hat
    kx, ky, kz = GRID.wavenumbers()
    div = kx[:, None, None] * after[0] + ky[None, :, None] * after[1] + kz[None, None, :] * after[2]
    scale = np.sqrt(GRID.k_squared()).max() * np.abs(after).max()
    assert np.abs(div).max() <= 1e-14 * scale
    plane = after[:, :, :, 0]
    mirror = (-np.arange(GRID.n)) % GRID.n
    anti = plane - np.conj(plane[:, mirror][:, :, mirror])
    assert np.abs(anti).max() <= 1e-14 * np.abs(plane).max()


def two_mode_field(grid: Grid, p: tuple, q: tuple) -> np.ndarray:
    """cos(p·x) a + cos(q·x) b with a ⊥ p, b ⊥ q (divergence-free); p, q in units of k₀."""
    xyz = mesh(grid)
    u = np.zeros((3, *grid.shape))
    for n in (p, q):
        n = np.array(n, float)
        a = np.cross(n, [0.3, 0.5, 0.7])
        phase = sum(n[c] * grid.k0 * xyz[c] for c in range(3))
        u += a[:, None, None, None] * np.cos(phase)
    return u


def test_dealiasing_keeps_only_the_products_below_the_cutoff():
    # u = a cos(p·x) + b cos(q·x): u × ω has wavevectors ±(p ± q) besides the gradients
    # of single modes (removed by the projection). On 32³ the 2/3 rule keeps |n_i| ≤ 10:
    # p + q = (18, 1, 1) lies beyond N/2 and aliases onto (−14, 1, 1), which the cut must
    # empty; p − q (stored as its conjugate (−2, −1, 1)) is kept and must equal the
    # unaliased value, computed on a 64³ grid of the same box (cut-off 21, no alias).
    p, q = (10, 1, 0), (8, 0, 1)
    box = 2 * pi
    coarse, fine = Grid(32, box), Grid(64, box)
    results = {}
    for grid in (coarse, fine):
        solver = NavierStokesSolver(grid, nu=1.0)
        state = solver.state(two_mode_field(grid, p, q))
        nonlinear = solver.tendency(state) + 1.0 * grid.k_squared() * state.velocity_hat
        results[grid.n] = nonlinear / grid.n**3  # coefficients of the physical amplitude
    c, f = results[32], results[64]

    def at(a, n):
        return a[:, n[0], n[1], n[2]]

    ref = np.abs(at(f, (-2, -1, 1))).max()
    assert ref > 1.0  # the product exists
    assert np.abs(at(f, (18, 1, 1))).max() > 1.0  # and so does p + q, unaliased on 64³
    assert np.abs(at(c, (-2, -1, 1)) - at(f, (-2, -1, 1))).max() <= 1e-13 * ref
    # on 32³ nothing but p − q: in particular not the alias (−14, 1, 1) of p + q
    allowed = np.zeros(coarse.spectral_shape, bool)
    allowed[-2, -1, 1] = True
    assert np.abs(c[:, ~allowed]).max() <= 1e-14 * ref
    assert np.abs(at(f, (-14, 1, 1))).max() <= 1e-14 * ref  # no true product lands there


def test_rk4_converges_at_fourth_order_to_an_independent_integration():
    # Reference: scipy's DOP853 (rtol 1e-12) on the tendency, itself checked against NumPy
    # above. Halving h divides RK4's error by 2⁴ = 16 in the asymptotic range;
    # higher-order terms move the ratio by a few percent at these steps, so [13, 19]
    # fails a scheme of order 3 (ratio 8) or a wrong stage weight (an O(1) bias, ratio 1).
    solver = NavierStokesSolver(GRID, nu=NU, forcing=ConstantPowerForcing(1.0))
    state = random_state(solver, 6, peak=4.0)
    interval = 4.0 * solver.max_step(state)
    shape = state.velocity_hat.shape

    def rhs(t, y):
        uh = y.view(np.complex128).reshape(shape)
        return solver.tendency(FlowState(uh, t)).view(np.float64).ravel()

    y0 = state.velocity_hat.view(np.float64).ravel()
    ref = solve_ivp(
        rhs, (0.0, interval), y0, method="DOP853", rtol=1e-12, atol=1e-12 * np.abs(y0).max()
    )
    ref = ref.y[:, -1].view(np.complex128).reshape(shape)

    def run(steps: int) -> np.ndarray:
        s = state
        for _ in range(steps):
            s = solver.advance(s, interval / steps)
        return s.velocity_hat

    errors = [np.abs(run(n) - ref).max() for n in (4, 8, 16)]
    assert 13 <= errors[0] / errors[1] <= 19
    assert 13 <= errors[1] / errors[2] <= 19


def test_hook_sees_the_four_stages():
    solver = NavierStokesSolver(GRID, nu=NU, forcing=ConstantPowerForcing(1.0))
    state = FlowState(random_state(solver, 7).velocity_hat, 0.25)
    seen = []

    def hook(stage, time, velocity, velocity_hat):
        assert not velocity.flags.writeable and not velocity_hat.flags.writeable
        assert np.abs(solver.velocity(FlowState(velocity_hat, time)) - velocity).max() <= 1e-13
        seen.append((stage, time, velocity.copy()))

    h = 0.01
    after = solver.advance(state, h, hook=hook)
    assert [s for s, _, _ in seen] == [0, 1, 2, 3]
    assert [t for _, t, _ in seen] == [0.25, 0.25 + h / 2, 0.25 + h / 2, 0.25 + h]
    # stage 0 is the state itself; the step without hook gives the same bits (and the
    # hook could not write into the state)
    assert np.abs(seen[0][2] - solver.velocity(state)).max() <= 1e-14
    assert np.array_equal(solver.advance(state, h).velocity_hat, after.velocity_hat)
    assert after.time == 0.25 + h


def test_fields_of_taylor_green():
    # u = (sin kx cos ky, −cos kx sin ky, 0) exp(−2νk²t): ∂u/∂t = −2νk²u, the gradient is
    # analytic and (u·∇)u = (k/2)(sin 2kx, sin 2ky, 0). Spectral derivatives of a
    # resolved trigonometric field are exact to round-off.
    k = 3.0
    solver = NavierStokesSolver(GRID, nu=NU)
    u0 = taylor_green(GRID, k, 0)
    fields = solver.fields(solver.state(u0))
    x, y, _ = mesh(GRID)
    grad = np.zeros((3, 3, *GRID.shape))
    grad[0, 0] = k * np.cos(k * x) * np.cos(k * y)
    grad[0, 1] = -k * np.sin(k * x) * np.sin(k * y)
    grad[1, 0] = k * np.sin(k * x) * np.sin(k * y)
    grad[1, 1] = -k * np.cos(k * x) * np.cos(k * y)
    assert np.abs(fields.velocity - u0).max() <= 1e-13
    assert np.abs(fields.gradient - grad).max() <= 1e-12 * k
    assert np.abs(fields.dudt + 2 * NU * k**2 * u0).max() <= 1e-12
    advection = np.stack([0.5 * k * np.sin(2 * k * x), 0.5 * k * np.sin(2 * k * y), 0 * x])
    expected = -2 * NU * k**2 * u0 + advection
    assert np.abs(fields.acceleration() - expected).max() <= 1e-12 * k


def test_landing_step_is_the_largest_equal_step_below_the_bound():
    for interval, bound in [(1.0, 0.3), (1.0, 0.25), (2.5e-3, 1e-4), (0.1, 1.0)]:
        steps, h = landing_step(interval, bound)
        assert h <= bound and steps * h == pytest.approx(interval, rel=1e-15)
        if steps > 1:
            assert interval / (steps - 1) > bound
    assert landing_step(1.0, 0.25) == (4, 0.25)


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: NavierStokesSolver(GRID, nu=0.0), "^nu"),
        (lambda: NavierStokesSolver(GRID, nu=1.0, workers=0), "^workers"),
        (lambda: NavierStokesSolver(GRID, nu=1.0).state(np.zeros((3, 8, 8, 8))), "^velocity"),
        (
            lambda: NavierStokesSolver(GRID, nu=1.0).state(np.full((3, *GRID.shape), np.nan)),
            "^velocity",
        ),
        (lambda: landing_step(0.0, 1.0), "^interval"),
        (lambda: landing_step(1.0, float("nan")), "^max_step"),
    ],
)
def test_bad_solver_inputs(call, match):
    with pytest.raises(ValueError, match=match):
        call()


def test_bad_states_and_steps_are_refused():
    solver = NavierStokesSolver(GRID, nu=NU, forcing=ConstantPowerForcing(1.0))
    rest = solver.state(np.zeros((3, *GRID.shape)))
    with pytest.raises(ValueError, match="at rest"):
        solver.max_step(rest)
    with pytest.raises(ValueError, match="no energy"):
        solver.tendency(rest)
    with pytest.raises(ValueError, match=r"^step"):
        solver.advance(random_state(solver, 8), -1.0)
    with pytest.raises(ValueError, match=r"^cfl"):
        solver.max_step(random_state(solver, 8), cfl=0.0)
