"""Exact Lagrangian statistics of a recording's truth: the reference of
:mod:`ptv.stats.lagrangian`, written apart from it.

The truth (:class:`simulator.recording.RecordedParticles` or
:class:`validation.score.trajectories.TrueTrajectories`) gives every particle's exact
velocity and Lagrangian acceleration at each frame it is seen. A *run* is a particle's
stretch of consecutive frames (one that leaves the volume and comes back starts
another). Each run is taken in turn:

- ⟨a_c²⟩ and ⟨|u|²⟩: means over its particle-frames;
- S2ᴸ(Lτ₀) = ⟨|u(f + L) − u(f)|²⟩: mean over its pairs of frames L apart.

``margin`` keeps only the frames with ``margin`` frames of their run on either side (for
a pair, before f and after f + L): an estimator that needs f ± s, or f + L + s, measures
over such a population, and particles that stay long in the volume are not a random
sample of the flow (in kinematic simulation ⟨a²⟩ grows with the sweeping speed), so
``margin`` separates an estimator's error from the choice of its population.
"""

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class ExactLagrangian:
    """The exact statistics of a recording's particles.

    Attributes
    ----------
    lags : ndarray of int, shape (J,)
        L, frames.
    acceleration : ndarray, shape (3,)
        ⟨a_c²⟩ per component, m²/s⁴.
    acceleration_total : float
        ⟨|a|²⟩, m²/s⁴.
    velocity_variance : float
        ⟨|u|²⟩ (no mean subtracted), m²/s².
    structure : ndarray, shape (J,)
        S2ᴸ(Lτ₀), m²/s².
    points : int
        Particle-frames counted.
    pairs : ndarray of int, shape (J,)
        Pairs counted per lag.
    margin : int
        Frames of the run required on either side.
    """

    lags: np.ndarray
    acceleration: np.ndarray
    acceleration_total: float
    velocity_variance: float
    structure: np.ndarray
    points: int
    pairs: np.ndarray
    margin: int


def exact_lagrangian(
    particle: np.ndarray,
    frame: np.ndarray,
    velocity: np.ndarray,
    acceleration: np.ndarray,
    lags,
    *,
    margin: int = 0,
) -> ExactLagrangian:
    """⟨a²⟩, ⟨|u|²⟩ and S2ᴸ at ``lags`` from the exact velocities and accelerations.

    Parameters
    ----------
    particle, frame : ndarray of int, shape (N,)
        Particle id and frame number; (particle, frame) unique.
    velocity, acceleration : ndarray, shape (N, 3)
        Exact u and a at each particle-frame, m/s and m/s².
    lags : sequence of int
        L ≥ 1, frames.
    margin : int
        Frames of its run each counted frame needs on either side, ≥ 0.

    Returns
    -------
    ExactLagrangian
    """
    particle, frame = np.asarray(particle), np.asarray(frame)
    velocity = np.asarray(velocity, dtype=float)
    acceleration = np.asarray(acceleration, dtype=float)
    lags = np.asarray(lags, dtype=int)
    n = len(particle)
    if frame.shape != (n,) or velocity.shape != (n, 3) or acceleration.shape != (n, 3):
        raise ValueError("particle, frame (N,), velocity and acceleration (N, 3) must align")
    if lags.ndim != 1 or np.any(lags < 1):
        raise ValueError(f"lags must be integers >= 1, got {lags!r}")
    if not isinstance(margin, int) or margin < 0:
        raise ValueError(f"margin must be an integer >= 0, got {margin!r}")
    order = np.lexsort((frame, particle))
    p, f = particle[order], frame[order]
    u, a = velocity[order], acceleration[order]
    if np.any((p[1:] == p[:-1]) & (f[1:] == f[:-1])):
        raise ValueError("a particle is given twice in one frame")
    breaks = np.flatnonzero((p[1:] != p[:-1]) | (f[1:] != f[:-1] + 1)) + 1
    a_sum, u_sum, points = np.zeros(3), 0.0, 0
    s2_sum, pairs = np.zeros(len(lags)), np.zeros(len(lags), dtype=int)
    for begin, end in zip(np.r_[0, breaks], np.r_[breaks, n], strict=True):
        inner = slice(begin + margin, end - margin)
        a_sum += np.sum(a[inner] ** 2, axis=0)
        u_sum += float(np.sum(u[inner] ** 2))
        points += max(end - begin - 2 * margin, 0)
        for j, lag in enumerate(lags):
            first, last = begin + margin, end - margin - lag  # pairs (i, i + L), i < last
            if last > first:
                du = u[first + lag : last + lag] - u[first:last]
                s2_sum[j] += float(np.sum(du**2))
                pairs[j] += last - first
    if points == 0:
        raise ValueError(f"no particle-frame has {margin} frames of its run on either side")
    with np.errstate(invalid="ignore", divide="ignore"):
        structure = np.where(pairs > 0, s2_sum / pairs, np.nan)
    return ExactLagrangian(
        lags=lags,
        acceleration=a_sum / points,
        acceleration_total=float(a_sum.sum() / points),
        velocity_variance=u_sum / points,
        structure=structure,
        points=points,
        pairs=pairs,
        margin=margin,
    )
