"""World → pixel mappings of the cameras, batched and timed, with their derivatives.

Reconstruction uses only the camera protocol (:mod:`ptv.camera_model`): ``project``
for world → pixel and ``pixel_to_ray`` for pixel → ray. Derivatives of ``project`` are
central differences, all points and all their shifted copies in one call per camera.
Every call is timed and counted (:class:`Mappings`), so that the cost of a slow
calibration (e.g. a model-free one whose ``project`` inverts rays by Newton) shows in
the diagnostics.
"""

import logging
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numba import njit

from ptv.box import Box, check_box
from ptv.camera_model import CameraModel
from ptv.settings import IPRSettings

logger = logging.getLogger(__name__)


@dataclass
class Mappings:
    """The cameras, with the time spent in their protocol calls.

    Attributes
    ----------
    cameras : sequence of CameraModel
        One calibration per camera.
    points_projected : int
        World points passed to ``project`` so far (all cameras).
    seconds_project : float
        Time spent in ``project``, s.
    rays_computed : int
        Pixels passed to ``pixel_to_ray`` so far.
    seconds_rays : float
        Time spent in ``pixel_to_ray``, s.
    """

    cameras: Sequence[CameraModel]
    points_projected: int = 0
    seconds_project: float = 0.0
    rays_computed: int = 0
    seconds_rays: float = 0.0

    def __len__(self) -> int:
        return len(self.cameras)

    def project(self, camera: int, points: np.ndarray) -> np.ndarray:
        """Pixels (N, 2) of world points (N, 3) m in one camera; NaN where not imaged."""
        points = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
        if len(points) == 0:
            return np.empty((0, 2))
        t0 = time.perf_counter()
        xy = np.asarray(self.cameras[camera].project(points), dtype=np.float64)
        self.seconds_project += time.perf_counter() - t0
        self.points_projected += len(points)
        if xy.shape != (len(points), 2):
            raise ValueError(
                f"camera {camera}: project returned shape {xy.shape} for {len(points)} points"
            )
        return xy

    def rays(self, camera: int, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Origins and unit directions (N, 3) of the rays of pixels xy (N, 2)."""
        xy = np.ascontiguousarray(xy, dtype=np.float64).reshape(-1, 2)
        if len(xy) == 0:
            return np.empty((0, 3)), np.empty((0, 3))
        t0 = time.perf_counter()
        rays = self.cameras[camera].pixel_to_ray(xy)
        self.seconds_rays += time.perf_counter() - t0
        self.rays_computed += len(xy)
        origins = np.asarray(rays.origins, dtype=np.float64)
        directions = np.asarray(rays.directions, dtype=np.float64)
        norm = np.linalg.norm(directions, axis=1, keepdims=True)
        with np.errstate(invalid="ignore", divide="ignore"):
            return origins, directions / norm

    def project_with_jacobian(
        self, camera: int, points: np.ndarray, step: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Pixels and their derivatives by central differences, one ``project`` call.

        Parameters
        ----------
        camera : int
            Camera index.
        points : ndarray, shape (N, 3)
            World points, m.
        step : float
            Difference step along each world axis, m.

        Returns
        -------
        xy : ndarray, shape (N, 2)
            Pixels, px (NaN where not imaged).
        jacobian : ndarray, shape (N, 2, 3)
            ∂(x, y)/∂(X, Y, Z), px/m; where a shifted point is not imaged, the one-sided
            difference on the other side, NaN where neither is.
        """
        n = len(points)
        shifts = np.concatenate([np.zeros((1, 3)), step * np.eye(3), -step * np.eye(3)])
        all_xy = self.project(camera, (points[None, :, :] + shifts[:, None, :]).reshape(-1, 3))
        all_xy = all_xy.reshape(7, n, 2)
        xy = all_xy[0]
        plus, minus = all_xy[1:4], all_xy[4:7]  # (3, N, 2)
        jac = (plus - minus) / (2 * step)
        one_plus = (plus - xy[None]) / step
        one_minus = (xy[None] - minus) / step
        jac = np.where(np.isfinite(jac), jac, np.where(np.isfinite(one_plus), one_plus, one_minus))
        return xy, np.transpose(jac, (1, 2, 0))

    def log_cost(self) -> None:
        """Log the time spent in the protocol calls so far."""
        rate = self.points_projected / max(self.seconds_project, 1e-12)
        logger.info(
            "project: %d points in %.2f s (%.3g points/s); pixel_to_ray: %d pixels in %.2f s",
            self.points_projected,
            self.seconds_project,
            rate,
            self.rays_computed,
            self.seconds_rays,
        )


def voxel_size(mappings: Mappings, centre: np.ndarray, *, step: float) -> tuple[float, np.ndarray]:
    """Object-space size of a pixel at ``centre``, and the image motion per axis.

    Parameters
    ----------
    mappings : Mappings
        The cameras.
    centre : ndarray, shape (3,)
        A point seen by the cameras (the volume's centre), m.
    step : float
        Difference step, m.

    Returns
    -------
    voxel : float
        Mean over the cameras of |det(J Jᵀ)|^(−1/4) (J = ∂(x, y)/∂(X, Y, Z)): the side
        of the object-space square imaged on one pixel, m.
    motion : ndarray, shape (3,)
        RMS over the cameras of |∂(x, y)/∂X_k|, px/m, per world axis k.
    """
    sides, norms = [], []
    for c in range(len(mappings)):
        _xy, jac = mappings.project_with_jacobian(c, np.asarray(centre, float)[None], step)
        j = jac[0]
        if not np.isfinite(j).all():
            continue
        det = np.linalg.det(j @ j.T)
        if det > 0:
            sides.append(det**-0.25)
        norms.append(np.linalg.norm(j, axis=0))
    if not sides:
        raise ValueError(f"no camera images the volume's centre {np.asarray(centre).tolist()} m")
    return float(np.mean(sides)), np.sqrt(np.mean(np.square(norms), axis=0))


@njit(cache=True, nogil=True)
def _catmull_rom(t):  # pragma: no cover (compiled)
    """Weights of the 4 nodes around fraction t ∈ [0, 1) (cubic convolution, a = −½)."""
    t2 = t * t
    t3 = t2 * t
    return (
        -0.5 * t3 + t2 - 0.5 * t,
        1.5 * t3 - 2.5 * t2 + 1.0,
        -1.5 * t3 + 2.0 * t2 + 0.5 * t,
        0.5 * t3 - 0.5 * t2,
    )


@njit(cache=True, nogil=True)
def _tricubic(values, origin, step, points):  # pragma: no cover (compiled)
    """Cubic-convolution interpolation of values (nx, ny, nz, 2) on a regular grid;
    NaN where the 4 × 4 × 4 stencil leaves the grid or holds a NaN node."""
    nx, ny, nz = values.shape[0], values.shape[1], values.shape[2]
    out = np.full((points.shape[0], 2), np.nan)
    wx = np.empty(4)
    wy = np.empty(4)
    wz = np.empty(4)
    for p in range(points.shape[0]):
        u = (points[p, 0] - origin[0]) / step[0]
        v = (points[p, 1] - origin[1]) / step[1]
        w = (points[p, 2] - origin[2]) / step[2]
        if not (np.isfinite(u) and np.isfinite(v) and np.isfinite(w)):
            continue
        i = int(np.floor(u))
        j = int(np.floor(v))
        k = int(np.floor(w))
        if i < 1 or j < 1 or k < 1 or i + 2 >= nx or j + 2 >= ny or k + 2 >= nz:
            continue
        wx[0], wx[1], wx[2], wx[3] = _catmull_rom(u - i)
        wy[0], wy[1], wy[2], wy[3] = _catmull_rom(v - j)
        wz[0], wz[1], wz[2], wz[3] = _catmull_rom(w - k)
        sx = 0.0
        sy = 0.0
        for a in range(4):
            for b in range(4):
                wab = wx[a] * wy[b]
                for c in range(4):
                    wt = wab * wz[c]
                    sx += wt * values[i - 1 + a, j - 1 + b, k - 1 + c, 0]
                    sy += wt * values[i - 1 + a, j - 1 + b, k - 1 + c, 1]
        out[p, 0] = sx
        out[p, 1] = sy
    return out


def _extend_quadratically(values: np.ndarray) -> np.ndarray:
    """Grid values (nx, ny, nz, 2) with their NaN nodes filled, where they can be, by
    quadratic extrapolation from the three next nodes along an axis: v_i = 3 v_{i±1} −
    3 v_{i±2} + v_{i±3}. Two sweeps over the axes also fill nodes beyond an edge and a
    corner of the imaged region; the others stay NaN."""
    out = values.copy()
    for _sweep in range(2):
        for axis in range(3):
            v = np.moveaxis(out, axis, 0)  # a view: filling it fills out
            inner = np.arange(v.shape[0] - 3)
            for node, step in ((inner, 1), (inner + 3, -1)):
                near = node + step
                guess = 3.0 * v[near] - 3.0 * v[near + step] + v[near + 2 * step]
                current = v[node]
                fill = np.isnan(current) & np.isfinite(guess)
                current[fill] = guess[fill]
                v[node] = current
    return out


class GridMapping:
    """A camera whose ``project`` is interpolated from a regular grid of its own values.

    ``project`` of some calibrations is slow (the model-free one inverts its pixel →
    line map by Newton: about 6·10³ points/s), and reconstruction projects millions of
    points. The camera's ``project`` is called once on the nodes of a grid covering the
    volume (with two nodes of margin), and points are then projected by cubic
    convolution (Catmull–Rom, tricubic; error O(h³): below 10⁻³ px for a few-mm grid
    on smooth mappings, refraction through flat windows included). Nodes the camera
    does not image (beyond its sensor, or beyond the pixels a model-free calibration
    covers) are extended quadratically from the three next nodes along an axis, so that
    the stencils of points near the edge of the view stay whole and keep the O(h³)
    error (cubic convolution reproduces quadratics). Only a point with a corner of its
    own grid cell not imaged, or whose stencil leaves the grid, asks the camera itself.
    ``pixel_to_ray`` is the camera's.

    Parameters
    ----------
    camera : CameraModel
        The calibration.
    box : Box
        The volume to cover, m.
    spacing : float
        Grid step, m, > 0.
    """

    def __init__(self, camera: CameraModel, box, *, spacing: float) -> None:
        if not (np.isfinite(spacing) and spacing > 0):
            raise ValueError(f"spacing must be > 0 m, got {spacing!r}")
        lower, upper = (np.asarray(v, dtype=np.float64) for v in box)
        n = np.maximum(np.ceil((upper - lower) / spacing).astype(int), 1) + 5
        step = (upper - lower) / (n - 5)
        origin = lower - 2 * step
        axes = [origin[k] + step[k] * np.arange(n[k]) for k in range(3)]
        nodes = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
        t0 = time.perf_counter()
        values = np.asarray(camera.project(nodes), dtype=np.float64)
        self.seconds_grid = time.perf_counter() - t0
        self.camera = camera
        values = values.reshape(*n, 2)
        self.imaged = np.isfinite(values).all(axis=-1)
        self.values = np.ascontiguousarray(_extend_quadratically(values))
        self.origin = origin
        self.step = step
        self.fallback = 0
        logger.info("grid mapping: %s nodes, step %s mm, built in %.2f s", n.tolist(),
                    np.round(step * 1e3, 3).tolist(), self.seconds_grid)  # fmt: skip

    def project(self, points: np.ndarray) -> np.ndarray:
        """Pixels (N, 2) of world points (N, 3) m; NaN where not imaged."""
        points = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
        xy = _tricubic(self.values, self.origin, self.step, points)
        unsure = np.isnan(xy[:, 0]) | ~self._cell_imaged(points)
        missing = np.flatnonzero(unsure & np.isfinite(points).all(axis=1))
        if missing.size:
            self.fallback += missing.size
            xy[missing] = self.camera.project(points[missing])
        return xy

    def _cell_imaged(self, points: np.ndarray) -> np.ndarray:
        """Whether all 8 corners of each point's grid cell are imaged, (N,) bool."""
        with np.errstate(invalid="ignore"):
            index = np.floor((points - self.origin) / self.step)
        shape = np.array(self.imaged.shape)
        inside = np.all((index >= 0) & (index <= shape - 2), axis=1)
        i, j, k = np.where(inside[:, None], index, 0).astype(np.int64).T
        imaged = inside.copy()
        for di in (0, 1):
            for dj in (0, 1):
                for dk in (0, 1):
                    imaged &= self.imaged[i + di, j + dj, k + dk]
        return imaged

    def pixel_to_ray(self, xy: np.ndarray):
        """The camera's rays."""
        return self.camera.pixel_to_ray(xy)


def grid_mappings(
    cameras: Sequence[CameraModel], box: Box, settings: IPRSettings
) -> list[GridMapping]:
    """The cameras interpolated on grids of ``settings.mapping_grid`` voxels over the
    volume and its margin, as :func:`ptv.reconstruct.reconstruct` builds them: built
    once, they reconstruct many exposures through a slow calibration.

    Parameters
    ----------
    cameras : sequence of C CameraModel
        The calibrations.
    box : Box
        The measurement volume, (lower, upper) corners, m.
    settings : IPRSettings
        ``mapping_grid`` (> 0) and ``margin``.

    Returns
    -------
    list of C GridMapping
    """
    if settings.mapping_grid <= 0:
        raise ValueError(f"mapping_grid must be > 0 voxels, got {settings.mapping_grid}")
    lower, upper = (np.asarray(v, dtype=np.float64) for v in check_box("box", box))
    voxel, _ = volume_voxel(cameras, box)
    outer = (lower - (settings.margin + 2) * voxel, upper + (settings.margin + 2) * voxel)
    return [GridMapping(c, outer, spacing=settings.mapping_grid * voxel) for c in cameras]


def volume_voxel(cameras: Sequence[CameraModel], box: Box) -> tuple[float, np.ndarray]:
    """:func:`voxel_size` at the volume's centre, through the cameras themselves (their
    grids unwrapped): the voxel (m) and the image motion per axis (px/m)."""
    lower, upper = (np.asarray(v, dtype=np.float64) for v in box)
    step = 1e-4 * float(np.max(upper - lower))
    exact = [c.camera if isinstance(c, GridMapping) else c for c in cameras]
    return voxel_size(Mappings(exact), 0.5 * (lower + upper), step=step)
