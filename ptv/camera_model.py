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
    """A calibrated camera: pixels to rays in the measurement volume and back."""

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
