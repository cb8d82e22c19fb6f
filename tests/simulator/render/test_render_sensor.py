"""The sensor against shot-noise + read-noise theory and the ADC formula.

Statistical tolerances: with n independent pixels the sample mean has standard error
√(V/n) and the sample variance ≈ V √((2 + γ₂)/n), γ₂ (excess kurtosis) being < 0.1
here; every check allows 5 standard errors (a 6e-7 two-sided chance for a Gaussian
statistic). Seeds are fixed, so the tests are deterministic all the same.
"""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from simulator.render.sensor import Sensor, _background_table, _fill_from_uniforms

N_SIDE = (400, 500)  # 2e5 pixels
N = N_SIDE[0] * N_SIDE[1]


def assert_moments(dn, *, mean, var):
    dn = dn.astype(np.float64)
    assert dn.mean() == pytest.approx(mean, abs=5 * math.sqrt(var / dn.size))
    assert dn.var() == pytest.approx(var, abs=5 * var * math.sqrt(2.1 / dn.size))


def poisson_read_moments(mu, *, gain, read, offset):
    """E and Var of round(g (Poisson(μ) + N(0, σ²)) + o), Sheppard's 1/12 for rounding."""
    return gain * mu + offset, gain**2 * (mu + read**2) + 1 / 12


@pytest.mark.parametrize(
    ("signal", "background"),
    [(50.0, 0.0), (0.0, 50.0), (30.0, 20.0)],
    ids=["signal-only", "background-only", "both"],
)
def test_mean_and_variance_match_poisson_plus_read_noise(signal, background):
    sensor = Sensor(gain=0.5, read_noise=8.0, offset=100.0, bit_depth=16, background=background)
    dn = sensor.record(np.full(N_SIDE, signal), rng=11)
    assert dn.dtype == np.uint16 and dn.shape == N_SIDE
    mean, var = poisson_read_moments(signal + background, gain=0.5, read=8.0, offset=100.0)
    assert_moments(dn, mean=mean, var=var)


def test_mixed_image_each_part_follows_theory():
    sensor = Sensor(gain=2.0, read_noise=3.0, offset=50.0, bit_depth=12, background=4.0)
    signal = np.zeros(N_SIDE)
    signal[:, ::2] = 400.0
    dn = sensor.record(signal, rng=5)
    m, v = poisson_read_moments(4.0, gain=2.0, read=3.0, offset=50.0)
    assert_moments(dn[:, 1::2], mean=m, var=v)
    m, v = poisson_read_moments(404.0, gain=2.0, read=3.0, offset=50.0)
    assert_moments(dn[:, ::2], mean=m, var=v)


def chi2_pvalue(counts, expected):
    """Pearson goodness of fit, bins with expectation < 5 merged into the tails."""
    keep = expected >= 5
    obs = np.concatenate([counts[keep], [counts[~keep].sum()]])
    exp = np.concatenate([expected[keep], [expected[~keep].sum()]])
    if exp[-1] == 0:
        obs, exp = obs[:-1], exp[:-1]
    return stats.chisquare(obs, exp * obs.sum() / exp.sum()).pvalue


@pytest.mark.parametrize(
    ("signal", "background"),
    [(0.0, 2.5), (2.5, 0.0), (3.0, 2.0), (20.0, 0.0), (1e-4, 4.9999)],
    ids=["table", "weak", "both", "weak-20", "tiny"],
)
def test_pure_shot_noise_is_poisson(signal, background):
    # Background from the table; weak signals (<= 25 e⁻) invert the Poisson CDF of their
    # own electrons and add the background's: the sum must be Poisson(signal + background).
    sensor = Sensor(gain=1.0, read_noise=0.0, offset=0.0, bit_depth=16, background=background)
    dn = sensor.record(np.full(N_SIDE, signal), rng=3).ravel()
    k = np.arange(80)
    counts = np.bincount(dn, minlength=k.size)[: k.size]
    assert counts.sum() == N
    assert chi2_pvalue(counts, N * stats.poisson.pmf(k, signal + background)) > 1e-3


def test_table_and_per_pixel_paths_agree():
    # A background pixel (table path) and a pixel whose signal is a denormal (per-pixel
    # path; Poisson(b + 1e-310) is Poisson(b)) must have the same DN distribution.
    sensor = Sensor(gain=0.37, read_noise=1.3, offset=3.2, bit_depth=8, background=4.0)
    table = sensor.record(np.zeros(N_SIDE), rng=1).ravel()
    exact = sensor.record(np.full(N_SIDE, 1e-310), rng=2).ravel()
    top = max(table.max(), exact.max()) + 1
    hist = np.stack([np.bincount(table, minlength=top), np.bincount(exact, minlength=top)])
    hist = hist[:, hist.sum(axis=0) >= 10]
    assert stats.chi2_contingency(hist).pvalue > 1e-3
    m, v = poisson_read_moments(4.0, gain=0.37, read=1.3, offset=3.2)
    assert_moments(table, mean=m, var=v)


def test_read_noise_clips_at_zero():
    # No offset: DN = 0 whenever g·r < ½, i.e. with probability Φ(½ / (g σ)).
    sensor = Sensor(gain=0.5, read_noise=8.0, offset=0.0)
    dn = sensor.record(np.zeros(N_SIDE), rng=4)
    p0 = stats.norm.cdf(0.5 / (0.5 * 8.0))
    assert (dn == 0).mean() == pytest.approx(p0, abs=5 * math.sqrt(p0 * (1 - p0) / N))


def test_full_well_saturates():
    sensor = Sensor(gain=1.0, read_noise=0.0, offset=5.0, full_well=1000.5, bit_depth=16)
    for noise in (True, False):
        dn = sensor.record(np.full((30, 40), 1e6), rng=0, noise=noise)
        np.testing.assert_array_equal(dn, 1005)
    # Absurd signals saturate too instead of overflowing the Poisson generator.
    dn = sensor.record(np.full((3, 4), 1e300), rng=0)
    np.testing.assert_array_equal(dn, 1005)


@pytest.mark.parametrize(
    ("signal", "background"), [(0.0, 95.0), (95.0, 0.0)], ids=["table", "per-pixel"]
)
def test_partial_saturation_follows_the_poisson_tail(signal, background):
    # DN = min(Poisson(95), 100): the top value takes the whole tail P(k >= 100).
    sensor = Sensor(gain=1.0, read_noise=0.0, offset=0.0, full_well=100, background=background)
    dn = sensor.record(np.full(N_SIDE, signal), rng=8).ravel()
    assert dn.max() == 100
    k = np.arange(101)
    expected = stats.poisson.pmf(k, 95.0)
    expected[-1] = stats.poisson.sf(99, 95.0)
    assert chi2_pvalue(np.bincount(dn, minlength=101), N * expected) > 1e-3


@pytest.mark.parametrize("bits", [8, 10, 12, 16])
def test_bit_depth_clips(bits):
    sensor = Sensor(
        gain=10.0, read_noise=8.0, offset=0.0, full_well=1e5, bit_depth=bits, background=10_000.0
    )
    assert sensor.max_dn == 2**bits - 1
    for noise in (True, False):
        dn = sensor.record(np.full((20, 30), 90_000.0), rng=0, noise=noise)
        np.testing.assert_array_equal(dn, 2**bits - 1)
        dn = sensor.record(np.zeros((20, 30)), rng=0, noise=noise)  # background alone
        np.testing.assert_array_equal(dn, 2**bits - 1)


def test_noise_free_mode_is_the_adc_formula():
    sensor = Sensor(
        gain=1.0, read_noise=8.0, offset=0.2, full_well=100.0, bit_depth=8, background=0.1
    )
    signal = np.array([[0.0, 0.3, 2.4, 3.4, 1e9, 99.8]])
    # DN = clip(round(g · min(s + b, 100) + 0.2)): 0.3 0.6 2.7 3.7 100.2 100.1
    np.testing.assert_array_equal(sensor.record(signal, noise=False), [[0, 1, 3, 4, 100, 100]])
    gained = Sensor(gain=3.0, read_noise=0.0, offset=0.0, full_well=1000.0, bit_depth=8)
    np.testing.assert_array_equal(gained.record(signal, noise=False), [[0, 1, 7, 10, 255, 255]])


def test_same_seed_same_image():
    sensor = Sensor(background=3.0)
    rng = np.random.default_rng(0)
    signal = rng.uniform(0, 200, size=(50, 60))
    signal[rng.random(signal.shape) < 0.7] = 0.0
    a = sensor.record(signal, rng=42)
    b = sensor.record(signal, rng=np.random.default_rng(42))
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, sensor.record(signal, rng=43))
    gen = np.random.default_rng(42)
    first, second = sensor.record(signal, rng=gen), sensor.record(signal, rng=gen)
    assert not np.array_equal(first, second)  # the generator advances
    np.testing.assert_array_equal(first, a)


def test_huge_background_takes_the_per_pixel_path():
    sensor = Sensor(
        gain=0.5, read_noise=8.0, offset=10.0, full_well=1e6, bit_depth=16, background=1e5
    )
    assert _background_table(1e5, 0.5, 10.0, 8.0, 1e6, 16) is None
    dn = sensor.record(np.zeros((100, 100)), rng=9)
    m, v = poisson_read_moments(1e5, gain=0.5, read=8.0, offset=10.0)
    assert_moments(dn, mean=m, var=v)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"gain": 0.0}, "gain"),
        ({"gain": np.nan}, "gain"),
        ({"read_noise": -1.0}, "read_noise"),
        ({"offset": np.inf}, "offset"),
        ({"full_well": 0.5}, "full_well"),
        ({"bit_depth": 7}, "bit_depth"),
        ({"bit_depth": 17}, "bit_depth"),
        ({"bit_depth": 12.0}, "bit_depth"),
        ({"bit_depth": True}, "bit_depth"),
        ({"background": -1.0}, "background"),
    ],
)
def test_bad_sensor_raises(kwargs, match):
    with pytest.raises(ValueError, match=match):
        Sensor(**kwargs)


@pytest.mark.parametrize("noise", [True, False])
@pytest.mark.parametrize(
    ("image", "match"),
    [
        (np.zeros((2, 3, 4)), "2-D"),
        (np.zeros(5), "2-D"),
        (np.array([[0.0, np.nan]]), r"index \(0, 1\)"),
        (np.array([[0.0, 1.0], [np.inf, 0.0]]), r"index \(1, 0\)"),
        (np.array([[0.0, -1e-3]]), r"index \(0, 1\)"),
        (np.zeros((2, 2), dtype=complex), "real"),
        (np.array([["a"]]), "real"),
    ],
)
def test_bad_images_raise(image, match, noise):
    with pytest.raises(ValueError, match=match):
        Sensor().record(image, rng=0, noise=noise)


def test_weak_and_bright_signals_with_read_noise_follow_theory():
    sensor = Sensor(gain=0.4, read_noise=8.0, offset=10.0, bit_depth=12, background=1.5)
    for signal in (0.3, 24.0, 26.0, 300.0):
        dn = sensor.record(np.full(N_SIDE, signal), rng=13)
        m, v = poisson_read_moments(signal + 1.5, gain=0.4, read=8.0, offset=10.0)
        assert_moments(dn, mean=m, var=v)


@settings(max_examples=50, deadline=None)
@given(
    background=st.floats(0.0, 300.0),
    gain=st.floats(0.05, 5.0),
    read_noise=st.floats(0.0, 20.0),
    u=st.lists(st.floats(0.0, 1.0, exclude_max=True), min_size=1, max_size=50),
)
def test_table_cells_invert_the_cdf(background, gain, read_noise, u):
    # Every cell's DN (or its straddling mark) and the search from it give the first
    # DN whose CDF exceeds u, as a plain binary search of the CDF does.
    table = _background_table(background, gain, 10.0, read_noise, 10_000.0, 12)
    cdf, cells, dn = table.cdf, table.cells, table.dn
    u = np.array(u)
    expected = table.dn_lo + np.searchsorted(cdf, u, side="right")
    pixels = np.arange(u.size)
    got = np.zeros(u.size, np.uint16)
    _fill_from_uniforms(pixels, u, cells, cdf, table.dn_lo, got)
    np.testing.assert_array_equal(got, expected)
    cell = np.minimum((u * 2**16).astype(np.int64), 2**16 - 1)
    whole = dn[cell] != table.straddles
    np.testing.assert_array_equal(dn[cell][whole], expected[whole])
