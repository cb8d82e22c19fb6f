"""The claims on a recording's tracks (docs/claims.md #51–#53): the fit's floor written
apart from the stack, the claims passing on the recorded case, and failing when what
they guard is broken."""

import numpy as np
import pytest

from ptv.tracking.fitting import fit_tracks
from validation.claims import ClaimContext, run_claims
from validation.mutations import mutation
from validation.truth.fit_floor import fit_floor

IDS = ["tracks.fit_velocity", "tracks.fit_acceleration", "lagrangian.noise_removed"]


def _cubic_tracks(rng):
    """Three tracks (12, 6 and 30 frames) along random cubics, and their derivatives."""
    track = np.repeat([0, 1, 2], [12, 6, 30])
    frame = np.concatenate([np.arange(12), np.arange(6) + 3, np.arange(30)])
    t = (frame / 100.0)[:, None]
    c = rng.normal(size=(3, 4, 3))[track]
    position = c[:, 0] + c[:, 1] * t + c[:, 2] * t**2 + c[:, 3] * t**3
    velocity = c[:, 1] + 2 * c[:, 2] * t + 3 * c[:, 3] * t**2
    acceleration = 2 * c[:, 2] + 6 * c[:, 3] * t
    return track, frame, position, velocity, acceleration


def test_the_floor_has_no_bias_on_cubics_and_the_weights_of_a_least_squares_cubic():
    rng = np.random.default_rng(0)
    track, frame, position, velocity, acceleration = _cubic_tracks(rng)
    noisy = position + rng.normal(0.0, 1e-3, position.shape)
    fitted = fit_tracks(track, frame, noisy, 100.0, window=9, noise=1e-3)
    for order, exact, stack, error in (
        (1, velocity, fitted.velocity, fitted.velocity_error),
        (2, acceleration, fitted.acceleration, fitted.acceleration_error),
    ):
        floor = fit_floor(track, frame, position, exact, 100.0, window=9, noise=1e-3, order=order)
        assert floor.covered.all()
        np.testing.assert_allclose(floor.bias, 0.0, atol=1e-9 * np.abs(exact).max())
        # The same weights on the noisy positions give the stack's fit and its errors.
        again = fit_floor(track, frame, noisy, exact, 100.0, window=9, noise=1e-3, order=order)
        np.testing.assert_allclose(again.reference, stack, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(np.sqrt(floor.noise_variance), error, rtol=1e-9)


def test_a_track_with_a_gap_is_not_covered():
    track, frame, position, velocity, _ = _cubic_tracks(np.random.default_rng(1))
    frame = frame.copy()
    frame[5:12] += 1  # the first track skips a frame
    floor = fit_floor(track, frame, position, velocity, 100.0, window=9, noise=1e-3, order=1)
    np.testing.assert_array_equal(floor.covered, track != 0)
    assert np.isnan(floor.reference[track == 0]).all()


@pytest.fixture(scope="module")
def quick():
    return ClaimContext("quick")


def test_the_track_claims_pass_on_the_recorded_case(quick):
    results = run_claims(quick, ids=IDS)
    assert [r.id for r in results if not r.passed] == []
    by_id = {r.id: r for r in results}
    assert "floor" in by_id["tracks.fit_acceleration"].tolerance
    assert "false alarms" in by_id["lagrangian.noise_removed"].tolerance


@pytest.mark.parametrize(
    ("name", "killer"),
    [
        ("track-fit-derivatives-without-factorial", "tracks.fit_acceleration"),
        ("lagrangian-velocity-noise-halved", "lagrangian.noise_removed"),
    ],
)
def test_the_track_mutations_fail_their_claims(name, killer):
    with mutation(name).applied():
        (result,) = run_claims(ClaimContext("quick"), ids=[killer])
    assert not result.passed
