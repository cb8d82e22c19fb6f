"""The largest particle speed of a recording, measured on its own links at the smallest Δt.

The double-frame link radius is r_k = max_speed·Δt_k + 5σ_b (docs/ptv.md §4). A
max_speed that suits one flow is many times too large for a slower one: the radius then
reaches past the spacing between particles and the links become ambiguous. So, unless
the user sets it, max_speed comes from the data:

1. the matched points of frames a and b of the first snapshots at the smallest Δt₀ are
   linked within a radius that starts at half the median nearest-neighbour spacing of
   frame a;
2. from those links, the mean velocity U (component-wise median of ΔX / Δt₀) and the
   robust rms σ_i of each component of ΔX / Δt₀ − U (1.4826 × its median absolute
   deviation, which a few mislinks do not move) give

       max_speed = |U| + k_v · max_i σ_i        (k_v = 5, as docs/ptv.md §4);

3. the radius max_speed·Δt₀ + 5σ_b replaces the first one and steps 2–3 repeat until it
   changes by less than 2 % (a first radius that cut the tails of the distribution grows
   at each step).

σ_i keeps the position noise (√2 σ_b per component of ΔX at Δt₀): the speed is
overestimated by it, never underestimated, and the radius at larger Δt errs on the wide
side. The estimate rests on the smallest Δt because there the displacements are
smallest against the spacing: if even those links are ambiguous, the recording cannot
be linked by distance alone, which the per-Δt ambiguity fraction of the run says.
"""

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ptv.tracking.linking import link

__all__ = ["LinkSpeed", "link_speed", "nearest_spacing"]

#: k_v of max_speed = |U| + k_v·σ: five standard deviations of one component.
SPEED_SIGMAS = 5.0
#: Gaussian σ per median absolute deviation.
MAD_TO_SIGMA = 1.4826
#: Iterations stop when the radius changes by less than this fraction.
CONVERGED = 0.02
MAX_ITERATIONS = 10


@dataclass(frozen=True)
class LinkSpeed:
    """A recording's largest particle speed, measured (see the module docstring).

    Attributes
    ----------
    max_speed : float
        |U| + 5 max_i σ_i, m/s.
    mean_velocity : tuple of 3 float
        U, the component-wise median of ΔX / Δt₀, m/s.
    velocity_rms : tuple of 3 float
        σ_i, the robust rms of each component of ΔX / Δt₀ − U, m/s (noise included).
    dt : float
        Δt₀, s.
    links : int
        Links the estimate rests on.
    snapshots : int
        Snapshots they come from.
    spacing : float
        Median nearest-neighbour distance of the matched points of frame a, m.
    iterations : int
        Radii tried.
    """

    max_speed: float
    mean_velocity: tuple[float, float, float]
    velocity_rms: tuple[float, float, float]
    dt: float
    links: int
    snapshots: int
    spacing: float
    iterations: int

    def as_dict(self) -> dict:
        """JSON-able form (SI units)."""
        return {
            "max_speed": self.max_speed,
            "mean_velocity": list(self.mean_velocity),
            "velocity_rms": list(self.velocity_rms),
            "dt": self.dt,
            "links": self.links,
            "snapshots": self.snapshots,
            "spacing": self.spacing,
            "iterations": self.iterations,
        }


def nearest_spacing(points: np.ndarray) -> float:
    """Median distance from each point to its nearest neighbour, m (nan below 2 points).

    Parameters
    ----------
    points : ndarray, shape (N, 3)
        Positions, m.
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if len(points) < 2:
        return float("nan")
    distance, _ = cKDTree(points).query(points, k=2)
    return float(np.median(distance[:, 1]))


def link_speed(
    frames: Sequence[tuple[np.ndarray, np.ndarray]], dt: float, *, position_noise: float
) -> LinkSpeed:
    """max_speed from the links of some snapshots at one Δt (module docstring).

    Parameters
    ----------
    frames : sequence of (ndarray (N_a, 3), ndarray (N_b, 3))
        Matched points of frames a and b of each snapshot, m.
    dt : float
        Their Δt, s (> 0).
    position_noise : float
        σ_b, m: the 5σ_b of the radius.

    Returns
    -------
    LinkSpeed

    Raises
    ------
    ValueError
        Fewer than 10 links at any radius tried (too few particles to measure a speed:
        set max_speed).
    """
    if not (np.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be finite and > 0, got {dt!r}")
    frames = [(np.asarray(a, float), np.asarray(b, float)) for a, b in frames]
    frames = [(a, b) for a, b in frames if len(a) >= 2 and len(b)]
    spacing = float(np.nanmedian([nearest_spacing(a) for a, _ in frames])) if frames else np.nan
    if not np.isfinite(spacing) or spacing <= 0:
        raise ValueError(
            "too few matched particles in the first snapshots to measure their speed; "
            "set [linking] max_speed"
        )
    radius, iterations = 0.5 * spacing, 0
    while iterations < MAX_ITERATIONS:
        iterations += 1
        displacements = np.concatenate([link(a, b, radius=radius).displacements for a, b in frames])
        if len(displacements) < 10:
            raise ValueError(
                f"only {len(displacements)} links within {radius * 1e3:.3g} mm at Δt = {dt:.4g} s "
                "in the first snapshots: too few to measure the particles' speed; set "
                "[linking] max_speed"
            )
        velocity = displacements / dt
        mean = np.median(velocity, axis=0)
        rms = MAD_TO_SIGMA * np.median(np.abs(velocity - mean), axis=0)
        speed = float(np.linalg.norm(mean) + SPEED_SIGMAS * rms.max())
        new_radius = speed * dt + 5 * position_noise
        converged = abs(new_radius - radius) < CONVERGED * radius
        radius = new_radius
        if converged:
            break
    return LinkSpeed(
        max_speed=speed,
        mean_velocity=tuple(float(v) for v in mean),
        velocity_rms=tuple(float(v) for v in rms),
        dt=float(dt),
        links=len(displacements),
        snapshots=len(frames),
        spacing=spacing,
        iterations=iterations,
    )
