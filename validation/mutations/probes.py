"""Small inputs for the mutations' probes: two straight-ray cameras, a few points, and
the run statistics of a few random links."""

import numpy as np

from ptv.rays import Rays
from ptv.settings import StatisticsSettings
from ptv.stats import run_statistics
from ptv.stats.links import RunParticles

#: Three points in front of both probe cameras, m.
POINTS = np.array([[0.01, 0.02, 0.30], [-0.02, 0.01, 0.32], [0.00, -0.01, 0.28]])


class PinholeProbe:
    """A distortion-free pinhole camera (centre, unit rotation, focal length in px).

    Parameters
    ----------
    centre : array_like, shape (3,)
        Camera centre, m.
    focal_px : float
        Focal length, px; the principal point is the pixel origin.
    """

    def __init__(self, centre, focal_px: float = 1000.0) -> None:
        self.centre = np.asarray(centre, dtype=float)
        self.focal_px = focal_px

    def project(self, points: np.ndarray) -> np.ndarray:
        """Pixels (N, 2) of points (N, 3), m."""
        rel = np.asarray(points, dtype=float) - self.centre
        return self.focal_px * rel[:, :2] / rel[:, 2:]

    def pixel_to_ray(self, xy: np.ndarray) -> Rays:
        """Rays (N) through pixels (N, 2)."""
        xy = np.asarray(xy, dtype=float)
        directions = np.column_stack([xy / self.focal_px, np.ones(len(xy))])
        directions /= np.linalg.norm(directions, axis=1, keepdims=True)
        return Rays(np.broadcast_to(self.centre, directions.shape).copy(), directions)


def stereo_pair() -> tuple[PinholeProbe, PinholeProbe]:
    """Two probe cameras 0.2 m apart along X."""
    return PinholeProbe([-0.1, 0.0, 0.0]), PinholeProbe([0.1, 0.0, 0.0])


def run_statistics_probe() -> run_statistics.PtvStatistics:
    """The run statistics of three snapshots of 40 random links at three Δt."""
    rng = np.random.default_rng(0)
    runs = []
    for k, dt in enumerate((1e-3, 2e-3, 3e-3)):
        snapshots = [
            (rng.uniform(-0.03, 0.03, (40, 3)) * [1, 1, 0.03], rng.normal(0, 1e-4, (40, 3)))
            for _ in range(3)
        ]
        runs.append(RunParticles.from_links(k, dt, snapshots))
    settings = StatisticsSettings(n_bins=6, n_boot=5, plateau=(5e-3, 10e-3))
    return run_statistics.compute_statistics(runs, settings)
