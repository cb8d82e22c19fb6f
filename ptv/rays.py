"""Straight rays, the currency of the camera protocol inside ``ptv``."""

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class Rays:
    """N straight rays X(s) = origin + s·direction.

    Attributes
    ----------
    origins : ndarray, shape (N, 3)
        A point of each ray, m; NaN rows are invalid rays.
    directions : ndarray, shape (N, 3)
        Unit directions; NaN rows are invalid rays.
    """

    origins: np.ndarray
    directions: np.ndarray

    @property
    def valid(self) -> np.ndarray:
        """Mask of usable rays, shape (N,)."""
        return np.isfinite(self.origins).all(axis=1) & np.isfinite(self.directions).all(axis=1)
