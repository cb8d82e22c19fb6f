"""Mutations of track fitting and of the Lagrangian statistics (``ptv.tracking.fitting``,
``ptv.stats.lagrangian``).

Only the claims on the recorded case (``tracks.*``, ``lagrangian.*``: docs/claims.md
#51–#53) reach this code: no other claim fits a track or follows a particle over more
than two frames.
"""

import numpy as np

from ptv.stats import lagrangian
from ptv.tracking import fitting
from validation.mutations.base import Mutation
from validation.mutations.patching import Patch, edited


def _fitted_derivatives():
    """The centred cubic's weights of position, velocity and acceleration over 7 frames,
    and the acceleration fitted on a parabola x = t² (2 everywhere)."""
    weights = fitting.centred_weights(7, frame_rate=10.0)
    frame = np.arange(9)
    t = frame / 10.0
    position = np.column_stack([t**2, np.zeros(9), np.zeros(9)])
    fit = fitting.fit_tracks(np.zeros(9, dtype=int), frame, position, 10.0, window=7, noise=0.0)
    return np.concatenate([weights.ravel(), fit.acceleration[:, 0]])


def _velocity_variance():
    """⟨|u|²⟩ with the noise removed on 20 noisy straight tracks of 30 frames."""
    rng = np.random.default_rng(0)
    frame = np.tile(np.arange(30), 20)
    track = np.repeat(np.arange(20), 30)
    velocity = rng.normal(0.0, 0.1, (20, 3))[track]
    position = velocity * frame[:, None] * 1e-3 + rng.normal(0.0, 1e-5, (600, 3))
    sample = lagrangian.track_sample(track, frame, position, 1e3, resamples=20, rng=0)
    found = lagrangian.velocity_variance(sample, lagrangian.acceleration_variance(sample))
    return np.array([found.total])


TRACK_MUTATIONS: tuple[Mutation, ...] = (
    Mutation(
        "track-fit-derivatives-without-factorial",
        "the track fit's derivative weights lack their factorial: the k-th derivative is "
        "the polynomial's coefficient c_k, not k!·c_k (acceleration c₂ for 2c₂; velocity "
        "unchanged)",
        (
            Patch(
                "ptv.tracking.fitting:_derivative_weights",
                edited("np.array([factorial(k) for k in powers])", "np.ones(len(powers))"),
            ),
        ),
        ("tracks.fit_acceleration",),
        ("tracks",),
        _fitted_derivatives,
    ),
    Mutation(
        "lagrangian-velocity-noise-halved",
        "the noise term subtracted from the Lagrangian velocity variance halved: "
        "Σσ_c²/(sτ₀)² for 2Σσ_c²/(sτ₀)²",
        (
            Patch(
                "ptv.stats.lagrangian:velocity_variance",
                edited("factor = 2.0 / (steps * tau) ** 2", "factor = 1.0 / (steps * tau) ** 2"),
            ),
        ),
        ("lagrangian.noise_removed",),
        ("lagrangian",),
        _velocity_variance,
    ),
)
