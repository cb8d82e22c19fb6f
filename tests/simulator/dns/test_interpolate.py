"""Periodic B-spline interpolation: the spline itself, accuracy against the exact Fourier
sum, invariants (nodes, periodicity, linearity, order of points) and bad input."""

import numpy as np
import pytest
import scipy.fft
from hypothesis import given
from hypothesis import strategies as st
from scipy.interpolate import BSpline

from simulator.dns.interpolate import ORDERS, bspline_symbol, interpolate, spline_coefficients

EPS = np.finfo(float).eps
BOX = 0.05  # m: not 2π, so that the units of k and x are exercised
TARGET = 1e-3  # the requirement: rms error ≤ 0.1 % of the rms of the field

seeds = st.integers(0, 2**32 - 1)
orders = st.sampled_from(ORDERS)


def cardinal_bspline(order: int) -> BSpline:
    """The centred B-spline β_n of degree n (knots −(n+1)/2 … (n+1)/2), from SciPy."""
    return BSpline.basis_element(np.arange(order + 2) - (order + 1) / 2, extrapolate=False)


# --- the spline --------------------------------------------------------------------------


@pytest.mark.parametrize("order", ORDERS)
def test_the_prefilter_symbol_is_the_transform_of_the_integer_samples(order):
    beta = cardinal_bspline(order)
    j = np.arange(-(order // 2), order // 2 + 1)
    theta = np.linspace(-np.pi, np.pi, 101)
    direct = np.nan_to_num(beta(j)) @ np.cos(np.outer(j, theta))
    assert np.abs(bspline_symbol(order, theta) - direct).max() < 1e-15


@pytest.mark.parametrize("order", ORDERS)
def test_a_unit_coefficient_gives_the_periodised_b_spline(order):
    n, node = 8, np.array([2, 5, 7])
    coeffs = np.zeros((n, n, n, 1))
    coeffs[node[0], node[1], node[2], 0] = 1.0
    rng = np.random.default_rng(0)
    points = rng.uniform(-BOX, 2 * BOX, (3000, 3))
    beta = cardinal_bspline(order)
    expected = np.ones(len(points))
    for d in range(3):
        s = points[:, d] * n / BOX - node[d]
        shifts = np.arange(-3, 4)[:, None] * n  # the images of the node within reach
        expected *= np.nan_to_num(beta(s[None, :] - shifts)).sum(axis=0)
    # Products of three polynomials of O(1) terms in [0, 1]: a few ulp each.
    assert np.abs(interpolate(coeffs, BOX, points, order=order)[:, 0] - expected).max() < 1e-14


# --- accuracy against the exact Fourier sum ----------------------------------------------


def wavenumbers(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """k_x, k_y, k_z (1/m) on the rfftn grid, shape (N, N, N//2 + 1) each."""
    k0 = 2 * np.pi / BOX
    m, mz = np.fft.fftfreq(n, 1 / n), np.fft.rfftfreq(n, 1 / n)
    return tuple(np.meshgrid(m * k0, m * k0, mz * k0, indexing="ij"))


def turbulent_field(n: int, spectrum: str, rng: np.random.Generator) -> np.ndarray:
    """rfftn coefficients, shape (3, N, N, N//2 + 1), of a random divergence-free field.

    Its energy spectrum is E(k) ∝ k^{-5/3} exp(−5.2 kη) ("k53", the shape of the brief) or the
    von Kármán–Pao E ∝ (k/k_p)⁴ (1 + (k/k_p)²)^{-17/6} exp(−5.2 kη) with its peak at the
    second shell, k_p = 2 (2π/L) ("vkp", like a DNS forced at the largest scales, which puts
    more of the energy near the cutoff), with k_max η = 1.5 for k_max = (N/3)(2π/L). As the
    solver's 2/3 rule, it keeps the cube of modes 3|n_i| < N (k = (2π/L) n); there is no
    Nyquist mode.
    """
    kx, ky, kz = wavenumbers(n)
    k = np.sqrt(kx**2 + ky**2 + kz**2)
    k0 = 2 * np.pi / BOX
    eta = 1.5 / (n / 3 * k0)
    ks = np.where(k > 0, k, 1.0)
    if spectrum == "k53":
        energy = ks ** (-5 / 3) * np.exp(-5.2 * ks * eta)
    else:
        kp = 2 * k0
        energy = (ks / kp) ** 4 * (1 + (ks / kp) ** 2) ** (-17 / 6) * np.exp(-5.2 * ks * eta)
    # A mode's energy is E(k) dk spread over the shell's 4πk² dk modes.
    amplitude = np.where(k > 0, np.sqrt(energy) / ks, 0.0)
    kept = 3 * np.rint(np.maximum(np.maximum(np.abs(kx), np.abs(ky)), np.abs(kz)) / k0) < n
    noise = scipy.fft.rfftn(rng.standard_normal((3, n, n, n)), axes=(1, 2, 3))
    u_hat = noise * amplitude * kept
    unit = np.stack([kx, ky, kz]) / ks
    return u_hat - unit * np.sum(unit * u_hat, axis=0)


def gradient_field(u_hat: np.ndarray) -> np.ndarray:
    """rfftn coefficients of ∂u_i/∂x_j, shape (9, N, N, N//2 + 1), component 3i + j."""
    k = wavenumbers(u_hat.shape[1])
    return np.stack([1j * k[j] * u_hat[i] for i in range(3) for j in range(3)])


def fourier_sum(field_hat: np.ndarray, points: np.ndarray) -> np.ndarray:
    """The field Σ_k f̂(k) e^{ik·x} / N³ at points (P, 3), directly; shape (P, C).

    The half spectrum kz ≥ 0 stands for the full one: the planes 0 < kz < N/2 count twice
    (with their conjugates), kz = 0 and N/2 once. Nyquist modes in x and y are assumed absent.
    """
    n = field_hat.shape[1]
    k0 = 2 * np.pi / BOX
    m, mz = np.fft.fftfreq(n, 1 / n), np.fft.rfftfreq(n, 1 / n)
    weight = np.where((mz == 0) | (mz == n / 2), 1.0, 2.0)
    out = np.empty((len(points), field_hat.shape[0]))
    for lo in range(0, len(points), 128):
        x = points[lo : lo + 128]
        ex = np.exp(1j * k0 * np.outer(x[:, 0], m))
        ey = np.exp(1j * k0 * np.outer(x[:, 1], m))
        ez = np.exp(1j * k0 * np.outer(x[:, 2], mz)) * weight
        total = np.einsum("cabz,pa,pb,pz->pc", field_hat, ex, ey, ez, optimize=True)
        out[lo : lo + 128] = total.real / n**3
    return out


def rms_error(field_hat: np.ndarray, values: np.ndarray, exact: np.ndarray) -> float:
    """rms of (values − exact) over points and components, over the rms of the field."""
    n = field_hat.shape[1]
    field = scipy.fft.irfftn(field_hat, s=(n, n, n), axes=(1, 2, 3))
    return float(np.sqrt(np.mean((values - exact) ** 2) / np.mean(field**2)))


def spline_error(field_hat: np.ndarray, order: int, points: np.ndarray) -> float:
    values = interpolate(spline_coefficients(field_hat, order=order), BOX, points, order=order)
    return rms_error(field_hat, values, fourier_sum(field_hat, points))


def test_the_oracle_reproduces_the_grid_values():
    u_hat = turbulent_field(8, "k53", np.random.default_rng(0))
    i = np.random.default_rng(1).integers(0, 8, (50, 3))
    field = scipy.fft.irfftn(u_hat, s=(8, 8, 8), axes=(1, 2, 3))
    # A sum of ~200 terms of the field's size: round-off well below 1e-12 of it.
    exact = fourier_sum(u_hat, i * BOX / 8)
    assert np.abs(exact - field[:, i[:, 0], i[:, 1], i[:, 2]].T).max() < 1e-12 * np.abs(field).max()


# The target is the requirement, not a measured figure. Measured here (32³, 64³), error / rms:
# quintic k53 5.0e-5, 3.8e-5; vkp 2.0e-4, 1.1e-4; cubic k53 3.7e-4, 2.6e-4 (on vkp the cubic
# gives 1.5e-3 and 7.6e-4: it misses the target at 32³, one reason it is not the default).
# Velocity gradients, quintic: k53 4.1e-4, 3.9e-4; vkp 7.9e-4, 6.0e-4 (cubic: 2.3-5e-3).
@pytest.mark.parametrize("n", [32, 64])
@pytest.mark.parametrize(("order", "spectrum"), [(5, "k53"), (5, "vkp"), (3, "k53")])
def test_velocity_error_is_below_a_thousandth_of_its_rms(n, order, spectrum):
    rng = np.random.default_rng(n)
    u_hat = turbulent_field(n, spectrum, rng)
    points = rng.uniform(-2 * BOX, 3 * BOX, (1000, 3))  # several tiles, negative included
    assert spline_error(u_hat, order, points) < TARGET


@pytest.mark.parametrize("n", [32, 64])
@pytest.mark.parametrize("spectrum", ["k53", "vkp"])
def test_quintic_gradient_error_is_below_a_thousandth_of_its_rms(n, spectrum):
    rng = np.random.default_rng(n + 1)
    grad_hat = gradient_field(turbulent_field(n, spectrum, rng))
    points = rng.uniform(-BOX, 2 * BOX, (600, 3))
    assert spline_error(grad_hat, 5, points) < TARGET


def test_the_target_rejects_trilinear_and_unfiltered_splines():
    n = 64
    rng = np.random.default_rng(3)
    u_hat = turbulent_field(n, "k53", rng)
    points = rng.uniform(0.0, BOX, (1000, 3))
    exact = fourier_sum(u_hat, points)
    grid = np.moveaxis(scipy.fft.irfftn(u_hat, s=(n, n, n), axes=(1, 2, 3)), 0, -1)
    s = points * n / BOX
    cell = np.floor(s).astype(int)
    t = s - cell
    trilinear = np.zeros_like(exact)
    for corner in np.ndindex(2, 2, 2):
        weight = np.prod(np.where(corner, t, 1 - t), axis=1)
        index = (cell + corner) % n
        trilinear += weight[:, None] * grid[index[:, 0], index[:, 1], index[:, 2]]
    assert rms_error(u_hat, trilinear, exact) > TARGET
    for order in ORDERS:  # the grid values taken as coefficients: the prefilter skipped
        unfiltered = interpolate(np.ascontiguousarray(grid), BOX, points, order=order)
        assert rms_error(u_hat, unfiltered, exact) > TARGET


# --- invariants ---------------------------------------------------------------------------


def round_off(order: int, coeff_max: float, cells: float) -> float:
    """Bound on the round-off of a spline value at a point |x|/Δ ≤ ``cells`` from the origin.

    The (n+1)³ positive weights sum to 1, so accumulating them costs ≤ (n+1)³ ε max|c|. The
    position carries ≤ 4 ulp of |x|/Δ, and the spline's slope along an axis, in grid units, is
    ≤ 2 max|c| (β_n' is a difference of two β_{n−1}, whose translates sum to 1).
    """
    return EPS * coeff_max * ((order + 1) ** 3 + 3 * 2 * 4 * (cells + 1))


def prefilter_round_off(order: int, n: int, field_max: float) -> float:
    """Round-off of the coefficients, hence of s(x_i) = f_i, from the prefilter.

    The FFTs round to ≈ ε log₂(N³) of the field's size, amplified by the condition number
    of the division, (max B / min B)³ = 3³ (cubic) or 7.5³ (quintic); 4× for the two FFTs
    and the division.
    """
    condition = (1.0 / bspline_symbol(order, np.pi)) ** 3
    return 4 * EPS * np.log2(n**3 + 1) * condition * field_max


@given(
    seed=seeds,
    order=orders,
    n=st.integers(1, 12),
    ncomp=st.integers(1, 4),
    box=st.floats(1e-3, 1e3),
    tiles=st.integers(-1000, 1000),
)
def test_the_spline_passes_through_the_grid_values(seed, order, n, ncomp, box, tiles):
    rng = np.random.default_rng(seed)
    field = rng.standard_normal((ncomp, n, n, n))  # white: Nyquist modes included
    coeffs = spline_coefficients(scipy.fft.rfftn(field, axes=(1, 2, 3)), order=order)
    nodes = rng.integers(0, n, (40, 3))
    shift = rng.integers(-1, 2, (40, 3)) * tiles
    points = nodes * (box / n) + shift * box
    values = interpolate(coeffs, box, points, order=order)
    expected = field[:, nodes[:, 0], nodes[:, 1], nodes[:, 2]].T
    cells = np.abs(points).max() * n / box
    bound = round_off(order, np.abs(coeffs).max(), cells)
    bound += prefilter_round_off(order, n, np.abs(field).max())
    assert np.abs(values - expected).max() <= bound


@given(seed=seeds, order=orders, n=st.integers(1, 12), tiles=st.integers(-1000, 1000))
def test_shifts_by_whole_boxes_leave_the_values_unchanged(seed, order, n, tiles):
    rng = np.random.default_rng(seed)
    box = rng.uniform(1e-3, 1e3)
    coeffs = rng.standard_normal((n, n, n, 3))
    points = rng.uniform(0.0, box, (50, 3))
    shifted = points + rng.integers(-1, 2, (50, 3)) * tiles * box
    base = interpolate(coeffs, box, points, order=order)
    moved = interpolate(coeffs, box, shifted, order=order)
    cells = np.abs(shifted).max() * n / box
    assert np.abs(moved - base).max() <= 2 * round_off(order, np.abs(coeffs).max(), cells)


factors = st.floats(-1e3, 1e3).filter(lambda v: v == 0 or abs(v) > 1e-100)  # no subnormals


@given(seed=seeds, order=orders, n=st.integers(1, 12), a=factors, b=factors)
def test_the_interpolant_is_linear_in_the_field(seed, order, n, a, b):
    rng = np.random.default_rng(seed)
    f, g = rng.standard_normal((2, 2, n, n, n))
    points = rng.uniform(-BOX, 2 * BOX, (50, 3))

    def coefficients(field):
        return spline_coefficients(scipy.fft.rfftn(field, axes=(1, 2, 3)), order=order)

    def at_points(field):
        return interpolate(coefficients(field), BOX, points, order=order)

    combined = at_points(a * f + b * g)
    expected = a * at_points(f) + b * at_points(g)
    # Either side: prefilter and accumulation round-off on fields of size |a| f and |b| g
    # (the points lie within 3 boxes of the origin); 3× for both sides and the last sum.
    field_max = abs(a) * np.abs(f).max() + abs(b) * np.abs(g).max()
    coeff_max = abs(a) * np.abs(coefficients(f)).max() + abs(b) * np.abs(coefficients(g)).max()
    bound = 3 * (prefilter_round_off(order, n, field_max) + round_off(order, coeff_max, 3 * n))
    assert np.abs(combined - expected).max() <= bound


def test_values_do_not_depend_on_the_order_of_the_points():
    rng = np.random.default_rng(4)
    coeffs = rng.standard_normal((16, 16, 16, 5))
    points = rng.uniform(-BOX, 2 * BOX, (3000, 3))
    permutation = rng.permutation(len(points))
    for order in ORDERS:
        values = interpolate(coeffs, BOX, points, order=order)
        assert np.array_equal(
            interpolate(coeffs, BOX, points[permutation], order=order), values[permutation]
        )


def test_no_points_give_an_empty_result():
    coeffs = np.zeros((4, 4, 4, 15))
    assert interpolate(coeffs, BOX, np.empty((0, 3))).shape == (0, 15)


# --- bad input ------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("points", "message"),
    [
        (np.zeros((5, 2)), r"points must have shape \(P, 3\)"),
        (np.zeros(3), r"points must have shape \(P, 3\)"),
        (np.array([[0.0, np.nan, 0.0]]), "points must be finite"),
        (np.array([[0.0, 0.0, -np.inf]]), "points must be finite"),
        (np.array([[1e16, 0.0, 0.0]]), "2\\*\\*52 grid spacings"),
    ],
)
def test_bad_points_are_rejected(points, message):
    with pytest.raises(ValueError, match=message):
        interpolate(np.zeros((8, 8, 8, 3)), BOX, points)


@pytest.mark.parametrize("shape", [(8, 8, 8), (8, 8, 9, 3), (8, 8, 8, 0), (1, 8, 8, 8, 3)])
def test_coefficients_of_a_wrong_shape_are_rejected(shape):
    with pytest.raises(ValueError, match=r"coeffs must have shape \(N, N, N, C\)"):
        interpolate(np.zeros(shape), BOX, np.zeros((2, 3)))


@pytest.mark.parametrize("box", [0.0, -1.0, np.nan, np.inf])
def test_a_bad_box_side_is_rejected(box):
    with pytest.raises(ValueError, match="box_side must be positive and finite"):
        interpolate(np.zeros((8, 8, 8, 3)), box, np.zeros((2, 3)))


@pytest.mark.parametrize("shape", [(8, 8, 5), (3, 8, 8, 8), (3, 8, 6, 5), (0, 8, 8, 5)])
def test_fourier_coefficients_of_a_wrong_shape_are_rejected(shape):
    with pytest.raises(ValueError, match=r"field_hat must have shape \(C, N, N, N//2 \+ 1\)"):
        spline_coefficients(np.zeros(shape, dtype=complex))


@pytest.mark.parametrize("order", [1, 4, "5"])
def test_an_unknown_order_is_rejected(order):
    with pytest.raises(ValueError, match="order must be one of"):
        spline_coefficients(np.zeros((1, 4, 4, 3), dtype=complex), order=order)
    with pytest.raises(ValueError, match="order must be one of"):
        interpolate(np.zeros((4, 4, 4, 1)), BOX, np.zeros((1, 3)), order=order)
