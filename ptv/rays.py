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

    Examples
    --------
    >>> import numpy as np
    >>> import ptv
    >>> rays = ptv.Rays(
    ...     origins=np.array([[0.0, 0.0, 0.0], [np.nan, np.nan, np.nan]]),
    ...     directions=np.array([[0.0, 0.6, 0.8], [np.nan, np.nan, np.nan]]),
    ... )
    >>> rays.valid  # the second pixel had no ray (outside the calibrated area)
    array([ True, False])
    >>> rays.origins[0] + 0.5 * rays.directions[0]  # 0.5 m along the first ray, m
    array([0. , 0.3, 0.4])
    """

    origins: np.ndarray
    directions: np.ndarray

    @property
    def valid(self) -> np.ndarray:
        """Mask of usable rays, shape (N,)."""
        return np.isfinite(self.origins).all(axis=1) & np.isfinite(self.directions).all(axis=1)
