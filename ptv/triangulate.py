"""Least-squares 3-D points from rays of several cameras (docs/ptv.md §2).

For rays (O_c, V_c) with A_c = I − V_c V_cᵀ, the point minimising Σ_c w_c d_c², where
d_c = |A_c (P − O_c)| is its distance to ray c, solves
(Σ_c w_c A_c) P = Σ_c w_c A_c O_c. For two rays it is the midpoint of their common
perpendicular.
"""

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ptv.camera_model import CameraModel

#: Below this conditioning (smallest/largest eigenvalue of Σ w A) rays count as parallel.
_MIN_CONDITION = 1e-12


@dataclass(frozen=True)
class Triangulation:
    """Points triangulated from C cameras.

    Attributes
    ----------
    points : ndarray, shape (N, 3)
        Least-squares points, m; NaN where fewer than two valid, non-parallel rays.
    ray_distances : ndarray, shape (C, N)
        Distance of each camera's ray to the point, m.
    """

    points: np.ndarray
    ray_distances: np.ndarray

    @property
    def rms_distance(self) -> np.ndarray:
        """Root-mean-square ray distance per point, shape (N,), m."""
        return np.sqrt(np.mean(self.ray_distances**2, axis=0))


def closest_points(
    origins: np.ndarray, directions: np.ndarray, *, weights: np.ndarray | None = None
) -> Triangulation:
    """Weighted least-squares intersection of C rays for each of N points.

    Parameters
    ----------
    origins : ndarray, shape (C, N, 3)
        A point of each ray, m.
    directions : ndarray, shape (C, N, 3)
        Unit directions; rows of NaN mark missing rays.
    weights : ndarray, shape (C, N), optional
        w_c = 1/σ_c² (lateral ray uncertainty at the point); 1 by default.

    Returns
    -------
    Triangulation

    Examples
    --------
    Public as :func:`ptv.triangulate_rays`. Two points (N = 2) seen by two cameras
    (C = 2): the first point's rays, along X at Z = 0 and along Y at Z = 2 mm, pass
    1 mm from their least-squares point, the midpoint of their common perpendicular; the
    second point has one ray only (NaN), so no point.

    >>> import numpy as np
    >>> import ptv
    >>> nan = [np.nan] * 3
    >>> origins = np.array([[[0, 0, 0], [0, 0, 0]], [[0, 0, 2e-3], nan]])  # (C, N, 3), m
    >>> directions = np.array([[[1, 0, 0], [1, 0, 0]], [[0, 1, 0], nan]])
    >>> found = ptv.triangulate_rays(origins, directions)
    >>> found.points  # m
    array([[0.   , 0.   , 0.001],
           [  nan,   nan,   nan]])
    >>> found.ray_distances[:, 0]  # each ray's distance from the first point, m
    array([0.001, 0.001])
    """
    o = np.asarray(origins, dtype=float)
    v = np.asarray(directions, dtype=float)
    if o.ndim != 3 or o.shape[-1] != 3 or v.shape != o.shape:
        raise ValueError(
            f"origins and directions must both be (C, N, 3), got {o.shape} and {v.shape}"
        )
    w = np.ones(o.shape[:2]) if weights is None else np.asarray(weights, dtype=float)
    if w.shape != o.shape[:2] or np.any(w < 0):
        raise ValueError(f"weights must be >= 0 with shape {o.shape[:2]}, got {w.shape}")
    valid = np.all(np.isfinite(o), axis=-1) & np.all(np.isfinite(v), axis=-1)
    w = np.where(valid, w, 0.0)
    o = np.where(valid[..., None], o, 0.0)
    v = np.where(valid[..., None], v, 0.0)
    a = np.eye(3) - v[..., :, None] * v[..., None, :]  # (C, N, 3, 3)
    lhs = np.einsum("cn,cnij->nij", w, a)
    rhs = np.einsum("cn,cnij,cnj->ni", w, a, o)
    eig = np.linalg.eigvalsh(lhs)
    solvable = (valid.sum(axis=0) >= 2) & (eig[:, 0] > _MIN_CONDITION * eig[:, -1])
    points = np.full((o.shape[1], 3), np.nan)
    if solvable.any():
        points[solvable] = np.linalg.solve(lhs[solvable], rhs[solvable][..., None])[..., 0]
    offset = np.einsum("cnij,cnj->cni", a, points[None] - o)
    distances = np.where(valid, np.linalg.norm(offset, axis=-1), np.nan)
    return Triangulation(points=points, ray_distances=distances)


def triangulate(cameras: Sequence[CameraModel], pixels: Sequence[np.ndarray]) -> Triangulation:
    """Triangulate corresponding pixels seen by several calibrated cameras.

    Parameters
    ----------
    cameras : sequence of C CameraModel
        Calibrations offering ``pixel_to_ray``.
    pixels : sequence of C ndarray, shape (N, 2)
        Row n of every array is the image of the same point, px; NaN rows are missing.

    Returns
    -------
    Triangulation

    Examples
    --------
    Public as :func:`ptv.triangulate_pixels`. Two Tsai cameras 0.5 m away, turned ±20°
    about Y, see three points; their pixels give the points back, and a point one
    camera missed (NaN) is NaN:

    >>> import numpy as np
    >>> import ptv
    >>> from scipy.spatial.transform import Rotation
    >>> def camera(angle):  # 0.5 m from the origin, turned ``angle`` degrees about Y
    ...     turn = Rotation.from_euler("y", angle, degrees=True).as_matrix()
    ...     return ptv.TsaiCalibration(turn, [0, 0, 0.5], focal_length=0.05, kappa1=0.0,
    ...                                sx=1.0, principal_point=(319.5, 239.5),
    ...                                pixel_size=(1e-5, 1e-5))
    >>> cameras = [camera(-20), camera(20)]
    >>> points = np.array([[0.0, 0.0, 0.0], [2e-3, -1e-3, 1e-3], [-3e-3, 2e-3, -1e-3]])
    >>> pixels = [camera.project(points) for camera in cameras]
    >>> pixels[1][2] = np.nan  # the second camera missed the third point
    >>> found = ptv.triangulate_pixels(cameras, pixels)
    >>> bool(np.allclose(found.points[:2], points[:2], rtol=0, atol=1e-12))  # m
    True
    >>> bool(np.isnan(found.points[2]).all())
    True
    """
    if len(cameras) != len(pixels) or len(cameras) < 2:
        raise ValueError(
            f"need one pixel array per camera and at least two cameras, "
            f"got {len(cameras)} cameras and {len(pixels)} pixel arrays"
        )
    shapes = {np.shape(p) for p in pixels}
    if len(shapes) != 1 or len(next(iter(shapes))) != 2 or next(iter(shapes))[1] != 2:
        raise ValueError(f"pixel arrays must all be (N, 2) of one N, got shapes {sorted(shapes)}")
    rays = [
        cam.pixel_to_ray(np.asarray(xy, dtype=float))
        for cam, xy in zip(cameras, pixels, strict=True)
    ]
    origins = np.stack([r.origins for r in rays])
    directions = np.stack([r.directions for r in rays])
    return closest_points(origins, directions)
