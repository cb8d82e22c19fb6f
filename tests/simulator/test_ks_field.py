"""KS field: incompressibility, amplitudes, kernels against the defining sums, isotropy."""

import numpy as np
import pytest
from scipy import stats

from simulator import ks_kernels
from simulator.ks_field import KSField, draw_ks_field, random_unit_vectors
from simulator.presets import flow_preset
from simulator.spectra import KolmogorovBandSpectrum, PopeSpectrum
from simulator.truth import longitudinal_structure_function

PARAMS = flow_preset("lem-10hz").parameters


@pytest.fixture(scope="module")
def field() -> KSField:
    return draw_ks_field(PopeSpectrum(PARAMS), n_modes=120, rng=7)


def direct_velocity(f: KSField, x: np.ndarray, t: float) -> np.ndarray:
    theta = x @ f.wavevectors.T + f.omega * t
    return np.cos(theta) @ f.a + np.sin(theta) @ f.b


def test_amplitudes_are_perpendicular_to_wavevectors(field):
    k_hat = field.wavevectors / np.linalg.norm(field.wavevectors, axis=1)[:, None]
    scale = np.linalg.norm(field.a, axis=1)
    assert np.abs(np.sum(k_hat * field.a, axis=1)).max() <= 1e-14 * scale.max()
    assert np.abs(np.sum(k_hat * field.b, axis=1)).max() <= 1e-14 * scale.max()


def test_amplitudes_carry_twice_the_mode_energy(field):
    expected = 2 * field.modes.energy
    assert np.allclose(np.sum(field.a**2, axis=1), expected, rtol=1e-12)
    assert np.allclose(np.sum(field.b**2, axis=1), expected, rtol=1e-12)


def test_divergence_vanishes_to_round_off(field):
    x = np.random.default_rng(1).uniform(-0.05, 0.05, (500, 3))
    _, _, grad, _ = field.derivatives(x, t=0.013)
    trace = np.trace(grad, axis1=1, axis2=2)
    # Each gradient entry is a sum of N terms of size |k||A|: compare with that scale.
    term_scale = np.sum(field.modes.k * np.linalg.norm(field.a, axis=1))
    assert np.abs(trace).max() < 1e-13 * term_scale


def test_velocity_kernel_matches_the_defining_sum(field):
    x = np.random.default_rng(2).uniform(-0.05, 0.05, (700, 3))
    u = field.velocity(x, t=0.21)
    assert np.abs(u - direct_velocity(field, x, 0.21)).max() < 1e-12 * PARAMS.u_rms


def test_gradient_and_time_derivative_match_finite_differences(field):
    x = np.random.default_rng(3).uniform(-0.05, 0.05, (50, 3))
    t, h, dt = 0.05, 1e-7, 1e-7
    u, dudt, grad, accel = field.derivatives(x, t)
    for j in range(3):
        e = np.zeros(3)
        e[j] = h
        fd = (field.velocity(x + e, t) - field.velocity(x - e, t)) / (2 * h)
        assert np.allclose(grad[:, :, j], fd, rtol=1e-5, atol=1e-6 * np.abs(grad).max())
    fd_t = (field.velocity(x, t + dt) - field.velocity(x, t - dt)) / (2 * dt)
    assert np.allclose(dudt, fd_t, rtol=1e-5, atol=1e-6 * np.abs(dudt).max())
    assert np.allclose(accel, dudt + np.einsum("pij,pj->pi", grad, u), rtol=1e-13)


def test_sincos_is_accurate_over_large_phases():
    theta = np.concatenate(
        [np.random.default_rng(4).uniform(-2e5, 2e5, 200_000), np.arange(-8, 9) * np.pi / 4]
    )
    s, c = ks_kernels.sincos_array(theta)
    # libm's sin is itself correctly rounded to < 1 ulp; allow a few ulp of |theta|'s
    # reduction on top.
    assert np.abs(s - np.sin(theta)).max() < 5e-16
    assert np.abs(c - np.cos(theta)).max() < 5e-16


def test_directions_are_uniform_on_the_sphere():
    v = random_unit_vectors(200_000, np.random.default_rng(5))
    assert np.allclose(np.linalg.norm(v, axis=1), 1, atol=1e-14)
    # Uniform on the sphere <=> each coordinate uniform on [-1, 1] (Archimedes).
    for j in range(3):
        assert stats.kstest(v[:, j], "uniform", args=(-1, 2)).pvalue > 1e-3


@pytest.mark.parametrize("spectrum_kind", [PopeSpectrum, KolmogorovBandSpectrum])
def test_component_variance_matches_u_rms_within_three_standard_errors(spectrum_kind):
    spectrum = spectrum_kind(PARAMS)
    rng = np.random.default_rng(6)
    per_realization = []
    for _ in range(300):
        f = draw_ks_field(spectrum, n_modes=100, rng=rng)
        x = rng.uniform(-1.0, 1.0, (300, 3))  # far apart: nearly independent samples
        per_realization.append(np.mean(f.velocity(x) ** 2))
    per_realization = np.asarray(per_realization)
    stderr = per_realization.std(ddof=1) / np.sqrt(len(per_realization))
    assert abs(per_realization.mean() - PARAMS.u_rms**2) < 3 * stderr


def test_realization_structure_function_is_the_discretised_integral(field):
    r = np.geomspace(1e-5, 0.5, 40)
    exact = longitudinal_structure_function(PopeSpectrum(PARAMS), r)
    # Discretisation (N = 120 over 4 decades) and the kL >= 0.5 truncation: < 0.5 %.
    assert np.allclose(field.longitudinal_structure_function(r), exact, rtol=5e-3)


def test_same_seed_gives_the_same_field():
    s = PopeSpectrum(PARAMS)
    a, b = draw_ks_field(s, rng=11), draw_ks_field(s, rng=11)
    assert np.array_equal(a.a, b.a) and np.array_equal(a.wavevectors, b.wavevectors)


@pytest.mark.parametrize("bad", [np.zeros((3, 2)), np.full((2, 3), np.nan)])
def test_bad_points_are_rejected(field, bad):
    with pytest.raises(ValueError, match="points"):
        field.velocity(bad)


def test_negative_unsteadiness_is_rejected():
    with pytest.raises(ValueError, match="unsteadiness"):
        draw_ks_field(PopeSpectrum(PARAMS), unsteadiness=-1)
