"""The protocol every camera calibration offers, whatever its model.

Triangulation, matching and metrics use only this protocol; they never ask which
model a calibration is (docs/conventions.md §6).
"""

from typing import Protocol

import numpy as np


class RayBundle(Protocol):
    """N straight rays: ``origins`` (N, 3) m and unit ``directions`` (N, 3)."""

    origins: np.ndarray
    directions: np.ndarray


class CameraModel(Protocol):
    """A calibrated camera: pixels to rays in the measurement volume and back.

    ``pixel_to_ray(xy)`` takes pixels (N, 2), px, and returns their rays (``origins``
    and unit ``directions``, (N, 3), m; NaN rows outside the calibrated area);
    ``project(points)`` takes world points (N, 3), m, and returns their pixels (N, 2),
    px (NaN where not imaged). Every calibration of :mod:`ptv.calibration` offers both.

    Examples
    --------
    A camera of one's own works with triangulation and matching once it has the two
    methods. Two telecentric cameras of 10 µm per pixel, one looking along Z, one
    along X:

    >>> import numpy as np
    >>> import ptv
    >>> class Telecentric:  # pixels = two world coordinates / 10 µm, rays along ``view``
    ...     def __init__(self, axes, view):
    ...         self.axes, self.view = list(axes), view
    ...     def project(self, points):
    ...         return np.asarray(points)[:, self.axes] / 1e-5
    ...     def pixel_to_ray(self, xy):
    ...         origins, directions = np.zeros((len(xy), 3)), np.zeros((len(xy), 3))
    ...         origins[:, self.axes] = np.asarray(xy) * 1e-5
    ...         directions[:, self.view] = 1.0
    ...         return ptv.Rays(origins, directions)
    >>> cameras = [Telecentric((0, 1), view=2), Telecentric((1, 2), view=0)]
    >>> point = np.array([[1e-3, 2e-3, 3e-3]])  # m
    >>> found = ptv.triangulate_pixels(cameras, [camera.project(point) for camera in cameras])
    >>> bool(np.allclose(found.points, point, rtol=0, atol=1e-12))
    True
    """

    def pixel_to_ray(self, xy: np.ndarray) -> RayBundle:
        """Rays (N rows; NaN outside the calibrated area) of pixels xy (N, 2)."""
        ...

    def project(self, points: np.ndarray) -> np.ndarray:
        """Pixels (N, 2) of world points (N, 3) in m; NaN where not imaged."""
        ...


def on_image(xy: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
    """Pixels inside [−½, W−½] × [−½, H−½] (the sensor's area), shape (N,); NaN → False."""
    width, height = image_size
    with np.errstate(invalid="ignore"):
        return (
            (xy[:, 0] >= -0.5)
            & (xy[:, 0] <= width - 0.5)
            & (xy[:, 1] >= -0.5)
            & (xy[:, 1] <= height - 0.5)
        )
