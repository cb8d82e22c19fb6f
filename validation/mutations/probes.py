"""Small inputs for the mutations' probes: two straight-ray cameras and a few points."""

import numpy as np

from ptv.rays import Rays

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
