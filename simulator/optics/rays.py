"""Bundles of straight rays: the common currency of cameras and calibrations.

A camera (physical or calibrated) answers ``pixel_to_ray(xy) -> Rays``; triangulation
needs nothing else. Invalid rays (a pixel whose light never reaches the medium, a
failed undistortion) are rows of NaN.
"""

from dataclasses import dataclass

import numpy as np

#: Tolerance on |direction| − 1 for a direction to count as a unit vector.
UNIT_TOLERANCE = 1e-9


def as_points(values: object, dim: int, name: str) -> np.ndarray:
    """Return ``values`` as a C-contiguous float64 array of shape (N, dim).

    Raises ``ValueError`` naming ``name``, the shape and what was expected when the
    array is not (N, dim) or holds non-finite values.
    """
    array = np.ascontiguousarray(values, dtype=np.float64)
    if array.ndim != 2 or array.shape[1] != dim:
        raise ValueError(f"{name} must be an array of shape (N, {dim}); got shape {array.shape}")
    bad = ~np.isfinite(array).all(axis=1)
    if bad.any():
        index = int(np.flatnonzero(bad)[0])
        raise ValueError(
            f"{name} must be finite; row {index} is {array[index].tolist()} "
            f"({int(bad.sum())} non-finite row(s) of {len(array)})"
        )
    return array


@dataclass(frozen=True, eq=False)
class Rays:
    """N straight rays X(s) = origin + s·direction.

    Attributes
    ----------
    origins : ndarray, shape (N, 3)
        A point of each ray, m (world frame). For a camera behind a window this is
        where the ray enters the last medium (water).
    directions : ndarray, shape (N, 3)
        Unit direction of each ray (dimensionless), pointing away from the camera.

    Rows that are NaN in either array are invalid rays (see ``valid``).
    """

    origins: np.ndarray
    directions: np.ndarray

    def __post_init__(self) -> None:
        origins = np.array(self.origins, dtype=np.float64)
        directions = np.array(self.directions, dtype=np.float64)
        if origins.ndim != 2 or origins.shape[1] != 3:
            raise ValueError(f"Rays.origins must have shape (N, 3); got {origins.shape}")
        if directions.shape != origins.shape:
            raise ValueError(
                f"Rays.directions must have the shape of origins {origins.shape}; "
                f"got {directions.shape}"
            )
        ok = np.isfinite(origins).all(axis=1) & np.isfinite(directions).all(axis=1)
        norms = np.linalg.norm(directions[ok], axis=1)
        if norms.size and np.max(np.abs(norms - 1.0)) > UNIT_TOLERANCE:
            worst = float(norms[np.argmax(np.abs(norms - 1.0))])
            raise ValueError(f"Rays.directions must be unit vectors; found a norm of {worst!r}")
        origins[~ok] = np.nan
        directions[~ok] = np.nan
        origins.setflags(write=False)
        directions.setflags(write=False)
        object.__setattr__(self, "origins", origins)
        object.__setattr__(self, "directions", directions)

    def __len__(self) -> int:
        return len(self.origins)

    @property
    def valid(self) -> np.ndarray:
        """Boolean mask (N,): True where the ray is defined (finite)."""
        return np.isfinite(self.origins[:, 0])

    def point_at(self, s: float | np.ndarray) -> np.ndarray:
        """Points at signed distance ``s`` (m) along each ray.

        Parameters
        ----------
        s : float or ndarray, shape (N,)
            Distance from the origin along the unit direction, m.

        Returns
        -------
        ndarray, shape (N, 3)
            origin + s·direction, m; NaN for invalid rays.
        """
        s = np.asarray(s, dtype=np.float64)
        if s.ndim == 0:
            return self.origins + s * self.directions
        if s.shape != (len(self),):
            raise ValueError(
                f"s must be a scalar or have shape ({len(self)},) like the rays; got {s.shape}"
            )
        return self.origins + s[:, None] * self.directions
