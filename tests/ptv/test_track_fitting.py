"""Track fitting: cubics reproduced exactly, errors that match the scatter, short tracks
left out, and a window that follows the noise and the trajectory's fourth derivative."""

import itertools

import numpy as np
import pytest

from ptv.tracking.fitting import centred_weights, choose_window, fit_tracks, track_outliers

RATE = 1000.0  # Hz


def _cubic_tracks(rng, lengths, gap_every=0):
    """Tracks of random cubics x(t) = Σ c_k t^k, frames with a gap every ``gap_every``."""
    track, frame, coef = [], [], []
    for i, n in enumerate(lengths):
        step = np.ones(n - 1, dtype=int)
        if gap_every:
            step[gap_every - 1 :: gap_every] = rng.integers(
                2, 5, size=len(step[gap_every - 1 :: gap_every])
            )
        f = 7 * i + np.r_[0, np.cumsum(step)]
        track.append(np.full(n, i))
        frame.append(f)
        coef.append(np.repeat(rng.normal(0, [1e-3, 0.1, 10, 300], size=(3, 4))[None], n, 0))
    track, frame, c = np.concatenate(track), np.concatenate(frame), np.concatenate(coef)
    t = frame / RATE
    x = c[..., 0] + c[..., 1] * t[:, None] + c[..., 2] * t[:, None] ** 2
    x += c[..., 3] * t[:, None] ** 3
    v = c[..., 1] + 2 * c[..., 2] * t[:, None] + 3 * c[..., 3] * t[:, None] ** 2
    a = 2 * c[..., 2] + 6 * c[..., 3] * t[:, None]
    return track, frame, x, v, a


@pytest.mark.parametrize("gaps", [0, 4])
def test_a_cubic_is_reproduced_at_every_point_ends_and_gaps_included(gaps):
    rng = np.random.default_rng(1)
    track, frame, x, v, a = _cubic_tracks(rng, [5, 6, 9, 14, 40], gap_every=gaps)
    if gaps:
        assert np.any(np.diff(frame)[np.diff(track) == 0] > 1)
    fit = fit_tracks(track, frame, x, RATE, window=9, noise=1e-5)
    np.testing.assert_allclose(fit.position, x, rtol=0, atol=1e-12)
    np.testing.assert_allclose(fit.velocity, v, rtol=0, atol=1e-9)
    np.testing.assert_allclose(fit.acceleration, a, rtol=0, atol=1e-6)
    # A quadratic fit reproduces a parabola.
    t = frame / RATE
    parabola = np.repeat((3.0 + 2.0 * t - 4.0 * t**2)[:, None], 3, axis=1)
    fit2 = fit_tracks(track, frame, parabola, RATE, window=7, noise=0, degree=2)
    np.testing.assert_allclose(fit2.velocity, np.repeat((2 - 8 * t)[:, None], 3, 1), atol=1e-9)
    np.testing.assert_allclose(fit2.acceleration, -8.0, rtol=0, atol=1e-6)


def test_rows_keep_their_order():
    rng = np.random.default_rng(2)
    track, frame, x, _, a = _cubic_tracks(rng, [12, 30, 8])
    order = rng.permutation(len(track))
    fit = fit_tracks(track[order], frame[order], x[order], RATE, window=7, noise=0)
    np.testing.assert_array_equal(fit.frame, frame[order])
    np.testing.assert_allclose(fit.acceleration, a[order], rtol=0, atol=1e-6)


def test_tracks_too_short_are_nan_and_short_ones_use_all_points():
    rng = np.random.default_rng(3)
    track, frame, x, _, a = _cubic_tracks(rng, [1, 2, 3, 4, 5, 6])
    fit = fit_tracks(track, frame, x, RATE, window=11, noise=1e-5)
    short = track < 4  # fewer than degree + 2 = 5 points
    for field in (fit.position, fit.velocity, fit.acceleration):
        assert np.all(np.isnan(field[short])) and np.all(np.isfinite(field[~short]))
    assert np.all(np.isnan(fit.acceleration_error[short]))
    np.testing.assert_allclose(fit.acceleration[~short], a[~short], rtol=0, atol=1e-6)
    # Five points fitted by a cubic: one degree of freedom, errors larger than with six.
    five, six = fit.acceleration_error[track == 4], fit.acceleration_error[track == 5]
    assert five.min() > six.min()


def test_the_weights_match_the_savitzky_golay_table():
    # Second derivative of the 5-point quadratic (= cubic) smoothing: (2, −1, −2, −1, 2)/7.
    np.testing.assert_allclose(
        centred_weights(5, degree=3)[2], np.array([2, -1, -2, -1, 2]) / 7, atol=1e-12
    )
    t = np.arange(-2, 3) / 10.0  # s, at 10 Hz
    np.testing.assert_allclose(centred_weights(5, degree=3, frame_rate=10.0)[1] @ t, 1.0)


def test_errors_match_the_scatter_over_noise_realisations():
    realisations, sigma = 2000, 2e-5
    frames = np.r_[0:6, 7, 8, 10:20, 23:30]  # gaps of 1, 1 and 2 frames
    n = len(frames)
    track = np.repeat(np.arange(realisations), n)
    frame = np.tile(frames, realisations)
    t = frame / RATE
    truth = np.stack([0.01 + 0.2 * t, -3 * t**2, 40 * t**3], axis=1)
    rng = np.random.default_rng(4)
    fit = fit_tracks(
        track, frame, truth + rng.normal(0, sigma, truth.shape), RATE, window=9, noise=sigma
    )
    exact_v = np.stack([0.2 + 0 * t, -6 * t, 120 * t**2], axis=1)
    exact_a = np.stack([0 * t, -6 + 0 * t, 240 * t], axis=1)
    for value, exact, error in (
        (fit.position, truth, fit.position_error),
        (fit.velocity, exact_v, fit.velocity_error),
        (fit.acceleration, exact_a, fit.acceleration_error),
    ):
        dev = (value - exact).reshape(realisations, n, 3)
        predicted = error.reshape(realisations, n)[0]
        samples = 3 * realisations
        rms = np.sqrt(np.mean(dev**2, axis=(0, 2)))
        # rms of 3R Gaussian deviations: relative SE 1/√(2·3R) = 0.9 %; 4.5 SE per point.
        assert np.all(np.abs(rms / predicted - 1) < 4.5 / np.sqrt(2 * samples))
        # Unbiased: the mean deviation within 4.5 SE of a mean of 3R.
        assert np.all(np.abs(dev.mean(axis=(0, 2))) < 4.5 * predicted / np.sqrt(samples))
    # The ends, fitted off-centre, are noisier than the middle.
    acc = fit.acceleration_error[:n]
    assert acc[0] > 2 * acc[n // 2]


def _sine_tracks(rng, tracks, length, omega, amplitude, sigma):
    """Tracks of x_c = A sin(ω t + φ_c), φ random per track and component, with noise."""
    frame = np.tile(np.arange(length), tracks)
    track = np.repeat(np.arange(tracks), length)
    phase = np.repeat(rng.uniform(0, 2 * np.pi, (tracks, 3)), length, axis=0)
    t = frame[:, None] / RATE
    x = amplitude * np.sin(omega * t + phase)
    acc = -(omega**2) * x
    return track, frame, x + rng.normal(0, sigma, x.shape), x, acc


def test_the_predicted_bias_is_the_actual_bias_on_a_sinusoid():
    omega, amplitude, window = 0.04 * RATE, 1e-3, 11  # ω τ = 0.04: ωT/2 = 0.2
    rng = np.random.default_rng(5)
    track, frame, _, x, acc = _sine_tracks(rng, 20, 60, omega, amplitude, 0.0)
    fit = fit_tracks(track, frame, x, RATE, window=window, noise=0.0)
    w = centred_weights(window, degree=3, frame_rate=RATE)[2]
    beta = np.sum(w * ((np.arange(window) - window // 2) / RATE) ** 4) / 24
    fourth = omega**4 * x  # x⁽⁴⁾ of a sine
    inner = (frame >= window // 2) & (frame < 60 - window // 2)
    actual = fit.acceleration[inner] - acc[inner]
    predicted = beta * fourth[inner]
    # Next term of the series: relative O((ωT/2)²) = 4 %, so 10 % bounds it.
    assert np.max(np.abs(actual - predicted)) < 0.1 * np.max(np.abs(predicted))
    # choose_window's table: bias from its own ⟨|x⁽⁴⁾|²⟩ estimate (3 A² ω⁸ / 2) on
    # tracks with little noise, against the rms bias of the fit.
    noisy = x + rng.normal(0, 1e-9, x.shape)
    choice = choose_window(track, frame, noisy, RATE, 1e-9, windows=[window])
    expected_m4 = 1.5 * amplitude**2 * omega**8
    assert choice.resolved
    assert abs(choice.fourth_derivative_mean_square / expected_m4 - 1) < 0.1
    rms_bias = np.sqrt(np.mean(np.sum(actual**2, axis=1)))
    assert abs(choice.bias_rms[0] / rms_bias - 1) < 0.15


@pytest.mark.parametrize("seed", [6, 7])
def test_the_window_grows_with_the_noise(seed):
    omega, amplitude = 0.1 * RATE, 1e-3
    chosen = []
    for sigma in (1e-8, 1e-7, 1e-6, 1e-5):
        rng = np.random.default_rng(seed)
        track, frame, noisy, _, _ = _sine_tracks(rng, 40, 120, omega, amplitude, sigma)
        choice = choose_window(track, frame, noisy, RATE, sigma)
        assert choice.resolved
        assert choice.window == choice.windows[np.argmin(choice.total_rms)]
        chosen.append(choice.window)
    assert all(b >= a for a, b in itertools.pairwise(chosen))
    assert chosen[-1] > chosen[0]


def test_unresolved_fourth_derivative_takes_the_largest_window():
    # A straight line: x⁽⁴⁾ = 0, nothing but noise to measure.
    rng = np.random.default_rng(8)
    track = np.repeat(np.arange(30), 50)
    frame = np.tile(np.arange(50), 30)
    x = np.stack([frame * 1e-4, 0 * frame, 0 * frame], axis=1) + rng.normal(0, 1e-5, (1500, 3))
    choice = choose_window(track, frame, x, RATE, 1e-5)
    assert not choice.resolved
    assert choice.window == choice.windows.max() == 49
    assert np.all(np.isnan(choice.bias_rms)) and np.all(np.isfinite(choice.noise_rms))


def test_bad_input_is_refused():
    track, frame, x = np.zeros(6, int), np.arange(6), np.zeros((6, 3))
    with pytest.raises(ValueError, match="odd"):
        fit_tracks(track, frame, x, RATE, window=6, noise=0)
    with pytest.raises(ValueError, match="same frame"):
        fit_tracks(track, np.r_[0, 0, 1, 2, 3, 4], x, RATE, window=5, noise=0)
    with pytest.raises(ValueError, match="degree"):
        choose_window(track, frame, x, RATE, 0.0, degree=4)


def test_false_points_are_outliers_and_gaussian_noise_is_not():
    rng = np.random.default_rng(7)
    track, frame, x, _, _ = _cubic_tracks(rng, [30] * 200)
    sigma = np.array([3e-6, 3e-6, 6e-6])
    noisy = x + rng.normal(size=x.shape) * sigma
    # One false point per track, 60 µm off (ten σ of the noisiest component), anywhere
    # along it, ends included.
    false = np.array([30 * i + rng.integers(0, 30) for i in range(200)])
    noisy[false] += rng.choice([-1, 1], size=(200, 1)) * np.array([60e-6, 0.0, 0.0])
    found = track_outliers(track, frame, noisy, RATE, window=9, noise=sigma)
    assert found[false].all()
    # Gaussian points beyond χ²₃ = 30.66 are one in 10⁶: none expected among 5800.
    assert np.count_nonzero(found) == len(false)


def test_outliers_need_a_positive_noise():
    track, frame = np.zeros(6, dtype=int), np.arange(6)
    with pytest.raises(ValueError, match="noise"):
        track_outliers(track, frame, np.zeros((6, 3)), RATE, window=5, noise=[1e-6, 0.0, 1e-6])
