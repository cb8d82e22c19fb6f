"""The bootstrap every estimate of a run shares: drawn once, in blocks where snapshots
correlate, and paired between two measurements of the same snapshots."""

import numpy as np
import pytest

from ptv.settings import ANALYSIS_VOLUME, StatisticsSettings
from ptv.stats.eulerian import cell_sums, eulerian_fit, eulerian_moments, u_prime_replicates
from ptv.stats.links import RunParticles
from ptv.stats.run_statistics import compute_statistics

DT = np.array([1e-4, 2e-4, 3e-4, 4e-4, 5e-4])
SETTINGS = StatisticsSettings(n_boot=80, r_min=2e-3, n_bins=10, plateau=(3e-3, 20e-3))


def _field(rng):
    """A smooth random velocity field (wavelengths 2–6 cm, 0.1 m/s)."""
    k = rng.normal(size=(12, 3)) * 150.0
    amp = rng.normal(size=(12, 3)) * 0.06
    phase = rng.uniform(0, 2 * np.pi, 12)
    return lambda x: np.sin(x @ k.T + phase) @ amp


def _shared_runs(*, sigma, snapshots=24, particles=400, repeat=1, scale=1.0, rng=0):
    """Runs at every Δt from one frame a per snapshot, as a time-resolved recording cut
    into pairs gives; each snapshot recorded ``repeat`` times in a row (the extreme of
    correlated snapshots: ``repeat`` consecutive ones carry the information of one);
    positions measured with white noise σ and a scale error."""
    rng = np.random.default_rng(rng)
    lower, upper = (np.array(v) for v in ANALYSIS_VOLUME)
    frames = []
    for _ in range(snapshots // repeat):
        velocity = _field(rng)
        x = rng.uniform(lower, upper, size=(particles, 3))
        noise_a = rng.normal(scale=sigma, size=x.shape)
        moves = [velocity(x) * dt + rng.normal(scale=sigma, size=x.shape) - noise_a for dt in DT]
        frames += [(scale * (x + noise_a), [scale * d for d in moves])] * repeat
    runs = []
    for k, dt in enumerate(DT):
        positions = np.concatenate([x for x, _ in frames])
        runs.append(
            RunParticles(
                k=k,
                dt=float(dt),
                positions=positions,
                displacements=np.concatenate([d[k] for _, d in frames]),
                offsets=np.arange(snapshots + 1) * particles,
                snapshot_ids=np.arange(snapshots),
                detections=np.zeros((snapshots, 2, 2), dtype=np.int64),
                matches=np.zeros((snapshots, 2), dtype=np.int64),
                links=np.full(snapshots, particles),
                processed=np.arange(snapshots),
                in_analysis=np.ones(len(positions), dtype=bool),
                outlier=np.zeros(len(positions), dtype=bool),
            )
        )
    return runs


def _statistics(runs, settings=SETTINGS):
    return compute_statistics(runs, settings, shared_first_frame=True)


def test_unit_weights_give_the_point_estimate_of_u_prime():
    """u′ refitted with every snapshot drawn once is u′ itself: the replicates form the
    cell variances as the point estimate does."""
    runs = _shared_runs(sigma=20e-6)
    st = _statistics(runs)
    sums = [cell_sums(run.snapshot_arrays(), st.grid) for run in runs]
    x = [run.positions[run.used] for run in runs]
    d = [run.displacements[run.used] for run in runs]
    moments = eulerian_moments(x, d, DT, st.grid)
    fit = eulerian_fit(moments, min_count=SETTINGS.min_cell_count)
    ones = [np.ones((1, len(run.snapshot_ids))) for run in runs]
    got = u_prime_replicates(sums, ones, moments, fit)
    assert got[0] == pytest.approx(st.u_prime.value, rel=1e-12)
    assert np.isfinite(st.u_prime.replicates).all()
    assert st.u_prime.se_snapshots > 0


def test_the_plateau_error_is_the_spread_of_its_replicates():
    st = _statistics(_shared_runs(sigma=20e-6))
    assert st.plateau.replicates.shape == (SETTINGS.n_boot,)
    assert st.plateau.se_epsilon == pytest.approx(np.std(st.plateau.replicates, ddof=1))


def test_two_measurements_of_the_same_snapshots_pair_up():
    """The exact and the noisy positions of the same snapshots draw the same replicates:
    their ε ratio scatters far less than either ε, since which eddies the snapshots
    caught cancels in it."""
    exact = _statistics(_shared_runs(sigma=0.0))
    noisy = _statistics(_shared_runs(sigma=20e-6))
    assert exact.bootstrap.pairs_with(noisy.bootstrap.snapshot_ids)
    np.testing.assert_array_equal(exact.bootstrap.weights, noisy.bootstrap.weights)
    ratio = noisy.plateau.replicates / exact.plateau.replicates
    unpaired = np.hypot(noisy.plateau.se_epsilon, exact.plateau.se_epsilon) / exact.plateau.epsilon
    assert np.std(ratio, ddof=1) < unpaired / 3


def test_a_scale_error_stands_far_out_of_the_paired_error():
    """A 1.5 % calibration scale error on the same snapshots: the change of ε, a few
    percent, is tens of paired standard errors, where the unpaired error of the two ε
    would hide it."""
    exact = _statistics(_shared_runs(sigma=0.0))
    scaled = _statistics(_shared_runs(sigma=0.0, scale=1.015))
    change = scaled.plateau.epsilon / exact.plateau.epsilon - 1
    paired = np.std(scaled.plateau.replicates / exact.plateau.replicates, ddof=1)
    unpaired = np.hypot(scaled.plateau.se_epsilon, exact.plateau.se_epsilon) / exact.plateau.epsilon
    assert abs(change) > 0.015
    assert abs(change) > 20 * paired
    assert abs(change) < 2 * unpaired


def test_correlated_snapshots_are_resampled_in_blocks():
    """Every snapshot recorded four times in a row: the correlation is found, the
    bootstrap draws blocks, and the plateau's error comes out near that of the 12
    distinct snapshots, about twice the one that takes the 48 as independent."""
    runs = _shared_runs(sigma=20e-6, snapshots=48, repeat=4)
    st = _statistics(runs)
    assert st.bootstrap.block > 1
    assert st.bootstrap.correlation.effective_snapshots < 48 / 2
    alone = _statistics(runs, StatisticsSettings(**{**SETTINGS.__dict__, "snapshot_block": 1}))
    assert alone.bootstrap.block == 1
    assert st.plateau.se_epsilon > 1.5 * alone.plateau.se_epsilon


def test_a_block_is_never_more_than_a_quarter_of_the_snapshots():
    """A block forced beyond a quarter of the 48 snapshots draws as one of 12: a block of
    all 48 would draw every replicate alike and report no error at all."""
    runs = _shared_runs(sigma=20e-6, snapshots=48, repeat=4)
    forced = _statistics(runs, StatisticsSettings(**{**SETTINGS.__dict__, "snapshot_block": 48}))
    quarter = _statistics(runs, StatisticsSettings(**{**SETTINGS.__dict__, "snapshot_block": 12}))
    assert forced.plateau.se_epsilon > 0
    assert forced.plateau.se_epsilon == quarter.plateau.se_epsilon


def test_independent_snapshots_are_drawn_one_at_a_time():
    st = _statistics(_shared_runs(sigma=20e-6))
    assert st.bootstrap.block == 1


def test_a_bad_block_is_refused():
    with pytest.raises(ValueError, match="snapshot_block"):
        StatisticsSettings(snapshot_block=0)
