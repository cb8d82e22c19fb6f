"""The paper's model-free calibration: every pixel is a straight line in the water.

Steps (docs/calibration.md §3; MLBAV §2):

1. For each traverse plane Z_j, fit T_j: pixel → (X, Y) on the plane, a 2-D polynomial
   (cubic by default), and its separate inverse T_j⁻¹: (X, Y) → pixel.
2. On a grid of pixels, evaluate (X_j, Y_j) = T_j(x, y) for every plane and fit by
   least squares X = X₀ + a (Z − Z̄), Y = Y₀ + b (Z − Z̄) (Z_j are exact: regression on Z).
3. Interpolate X₀, Y₀, a, b over the sensor with bicubic splines; a pixel's ray is
   O = (X₀, Y₀, Z̄), V = (a, b, 1)/√(1 + a² + b²).
4. Pixels outside the area where dots were seen (the union of the planes' convex hulls)
   are invalid (NaN rays), never extrapolated. Near the edge of that area some planes'
   T_j are evaluated slightly beyond their own dots (the plate's image shifts with Z in
   an oblique view); ``line_rms`` shows where this bends the fitted lines.
5. ``project`` (world → pixel) solves "the ray of pixel (x, y) passes through P" by a
   2-D Newton iteration started from T_j⁻¹ of the nearest plane.

No optical model is assumed; refraction by flat windows maps each pixel to an exact
line in the water, so the straight-line model is exact for such rigs.
"""

import logging
from dataclasses import dataclass, field

import cv2
import numpy as np
from scipy.interpolate import RectBivariateSpline
from scipy.spatial import Delaunay

from ptv.calibration.observations import PlaneObservation
from ptv.calibration.polynomial import Polynomial2D, fit_polynomial2d
from ptv.rays import Rays

log = logging.getLogger(__name__)

#: Newton iterations and tolerance (px) of ``project``.
_NEWTON_STEPS = 20
_NEWTON_TOL = 1e-10
#: Fractional bits of the hull vertices when rasterising the calibrated area.
_SUBPIXEL_BITS = 4


@dataclass(frozen=True, eq=False)
class PlaneFit:
    """The fitted transforms of one plane and their residuals.

    Attributes
    ----------
    z : float
        Z_j, m.
    to_world : Polynomial2D
        T_j: pixel → (X, Y), m.
    to_pixel : Polynomial2D
        T_j⁻¹: (X, Y) → pixel (a separate fit, not an exact inverse).
    residual_px : ndarray, shape (N,)
        |T_j⁻¹(X, Y) − pixel| of each dot, px.
    residual_m : ndarray, shape (N,)
        |T_j(pixel) − (X, Y)| of each dot, m.
    hull : Delaunay
        Triangulation of the dots' pixels: the area this plane calibrates.
    """

    z: float
    to_world: Polynomial2D
    to_pixel: Polynomial2D
    residual_px: np.ndarray
    residual_m: np.ndarray
    hull: Delaunay = field(repr=False)


def fit_plane(observation: PlaneObservation, *, degree: int = 3) -> PlaneFit:
    """Fit T_j and T_j⁻¹ for one plane (docs/calibration.md §2)."""
    px = np.asarray(observation.pixels, dtype=float)
    xy = np.asarray(observation.world_xy, dtype=float)
    to_world = fit_polynomial2d(px, xy, degree=degree)
    to_pixel = fit_polynomial2d(xy, px, degree=degree)
    return PlaneFit(
        z=float(observation.z),
        to_world=to_world,
        to_pixel=to_pixel,
        residual_px=np.linalg.norm(to_pixel(xy) - px, axis=1),
        residual_m=np.linalg.norm(to_world(px) - xy, axis=1),
        hull=Delaunay(px),
    )


def _coverage_mask(planes: tuple[PlaneFit, ...], image_size: tuple[int, int]) -> np.ndarray:
    """Boolean (height, width) mask of the union of the planes' dot hulls."""
    width, height = image_size
    mask = np.zeros((height, width), dtype=np.uint8)
    for plane in planes:
        hull = cv2.convexHull(plane.hull.points.astype(np.float32))[:, 0]
        vertices = np.rint(hull * (1 << _SUBPIXEL_BITS)).astype(np.int32)
        cv2.fillConvexPoly(mask, vertices, 1, lineType=cv2.LINE_8, shift=_SUBPIXEL_BITS)
    # One pixel of dilation keeps the dots on the hull itself inside after rounding.
    return cv2.dilate(mask, np.ones((3, 3), np.uint8)).astype(bool)


@dataclass(frozen=True, eq=False)
class ModelFreeCalibration:
    """Pixel → line calibration of one camera.

    Attributes
    ----------
    image_size : tuple of int
        (width, height), px.
    planes : tuple of PlaneFit
        The per-plane transforms (at least two planes).
    z_ref : float
        Z̄, the mean of the plane positions, m: ray origins lie on Z = Z̄.
    grid_x, grid_y : ndarray
        Pixel grid of the line fits, px.
    line_parameters : ndarray, shape (2 (q + 1), ny, nx)
        Coefficients of X and Y as polynomials of degree q in (Z − Z̄) on the grid:
        X₀, Y₀ (m), a, b (straight rays, q = 1), then a₂, b₂ (1/m, curved rays, q = 2).
    line_rms : ndarray, shape (ny, nx)
        RMS distance of the plane points from the fitted ray, m (curvature, noise).
    """

    image_size: tuple[int, int]
    planes: tuple[PlaneFit, ...]
    z_ref: float
    grid_x: np.ndarray
    grid_y: np.ndarray
    line_parameters: np.ndarray
    line_rms: np.ndarray
    _splines: tuple[RectBivariateSpline, ...] = field(init=False, repr=False)
    _coverage: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        splines = tuple(
            RectBivariateSpline(self.grid_y, self.grid_x, p, kx=3, ky=3)
            for p in self.line_parameters
        )
        object.__setattr__(self, "_splines", splines)
        object.__setattr__(self, "_coverage", _coverage_mask(self.planes, self.image_size))

    def covered(self, xy: np.ndarray) -> np.ndarray:
        """Pixels inside the area where dots were seen on some plane, shape (N,).

        The area is the union of the planes' convex hulls, rasterised once on the pixel
        grid and grown by one pixel: nothing beyond one pixel of the dots is calibrated.
        """
        xy = np.asarray(xy, dtype=float)
        width, height = self.image_size
        col = np.rint(np.where(np.isfinite(xy[:, 0]), xy[:, 0], -1.0))
        row = np.rint(np.where(np.isfinite(xy[:, 1]), xy[:, 1], -1.0))
        inside = (col >= 0) & (col < width) & (row >= 0) & (row < height)
        out = np.zeros(len(xy), dtype=bool)
        out[inside] = self._coverage[row[inside].astype(int), col[inside].astype(int)]
        return out

    @property
    def ray_degree(self) -> int:
        """q: 1 for straight rays, 2 for rays curved quadratically in Z."""
        return len(self.line_parameters) // 2 - 1

    def line_at(self, xy: np.ndarray, *, dx: int = 0, dy: int = 0) -> np.ndarray:
        """Ray coefficients (or their pixel derivatives) at pixels xy (N, 2); (N, 2 (q + 1))."""
        xy = np.asarray(xy, dtype=float)
        return np.stack([s.ev(xy[:, 1], xy[:, 0], dx=dy, dy=dx) for s in self._splines], axis=1)

    def _along(self, coefficients: np.ndarray, dz: np.ndarray) -> np.ndarray:
        """Σ_n c_n dz^n for the X and Y coefficient pairs, shape (N, 2)."""
        powers = dz[:, None] ** np.arange(self.ray_degree + 1)
        return np.einsum("nkc,nk->nc", coefficients.reshape(len(dz), -1, 2), powers)

    def position_at(self, xy: np.ndarray, z: np.ndarray) -> np.ndarray:
        """Where the (possibly curved) ray of each pixel crosses depth z: (N, 3), m."""
        xy = np.asarray(xy, dtype=float)
        z = np.broadcast_to(np.asarray(z, dtype=float), (len(xy),))
        ok = self.covered(xy)
        out = np.column_stack([self._along(self.line_at(xy), z - self.z_ref), z])
        out[~ok] = np.nan
        return out

    def pixel_to_ray(self, xy: np.ndarray) -> Rays:
        """Rays in the water of pixels xy (N, 2); NaN rows outside the calibrated area.

        For curved rays this is the tangent at Z = Z̄; :meth:`position_at` follows the
        curve exactly.
        """
        xy = np.asarray(xy, dtype=float)
        if xy.ndim != 2 or xy.shape[1] != 2:
            raise ValueError(f"pixels must have shape (N, 2), got {xy.shape}")
        ok = self.covered(xy)
        p = self.line_at(np.where(ok[:, None], xy, 0.0))
        origins = np.column_stack([p[:, 0], p[:, 1], np.full(len(p), self.z_ref)])
        directions = np.column_stack([p[:, 2], p[:, 3], np.ones(len(p))])
        directions /= np.linalg.norm(directions, axis=1, keepdims=True)
        origins[~ok] = np.nan
        directions[~ok] = np.nan
        return Rays(origins, directions)

    def project(self, points: np.ndarray) -> np.ndarray:
        """Pixels (N, 2) whose rays pass through world points (N, 3); NaN if uncalibrated."""
        points = np.asarray(points, dtype=float)
        if points.ndim != 2 or points.shape[1] != 3:
            raise ValueError(f"points must have shape (N, 3), got {points.shape}")
        finite = np.isfinite(points).all(axis=1)
        p = np.where(finite[:, None], points, 0.0)
        z_planes = np.array([plane.z for plane in self.planes])
        nearest = np.argmin(np.abs(p[:, 2:3] - z_planes[None]), axis=1)
        xy = np.empty((len(p), 2))
        for j, plane in enumerate(self.planes):
            sel = nearest == j
            if sel.any():
                xy[sel] = plane.to_pixel(p[sel, :2])
        dz = p[:, 2] - self.z_ref
        for _ in range(_NEWTON_STEPS):
            residual = self._along(self.line_at(xy), dz) - p[:, :2]
            jac = np.stack(
                [self._along(self.line_at(xy, dx=1), dz), self._along(self.line_at(xy, dy=1), dz)],
                axis=-1,
            )
            step = np.linalg.solve(jac, residual[..., None])[..., 0]
            xy -= step
            if np.nanmax(np.abs(step), initial=0.0) < _NEWTON_TOL:
                break
        ok = finite & self.covered(xy)
        xy[~ok] = np.nan
        return xy


def calibrate_model_free(
    observations: list[PlaneObservation],
    image_size: tuple[int, int],
    *,
    degree: int = 3,
    grid_step: int = 16,
    curved: bool = False,
) -> ModelFreeCalibration:
    """Build the pixel → line calibration of one camera from its plane observations.

    Parameters
    ----------
    observations : list of PlaneObservation
        One per traverse plane, at least two with distinct Z.
    image_size : tuple of int
        (width, height) of the images, px.
    degree : int
        Degree of the plane transforms T_j (1 to 3; the paper uses 3).
    grid_step : int
        Spacing of the pixel grid on which lines are fitted, px.
    curved : bool
        Fit rays quadratic in Z (stratified media, index gradients); needs ≥ 3 planes.

    Returns
    -------
    ModelFreeCalibration

    Examples
    --------
    The dots of a known camera (a Tsai camera turned 20° about Y) on three planes:

    >>> import numpy as np
    >>> import ptv
    >>> from scipy.spatial.transform import Rotation
    >>> turn = Rotation.from_euler("y", 20, degrees=True).as_matrix()
    >>> truth = ptv.TsaiCalibration(turn, [0, 0, 0.5], focal_length=0.05, kappa1=0.0,
    ...                             sx=1.0, principal_point=(319.5, 239.5),
    ...                             pixel_size=(1e-5, 1e-5))
    >>> ij = np.stack(np.meshgrid(np.arange(-4, 5), np.arange(-4, 5)), axis=-1).reshape(-1, 2)
    >>> xy = 4e-3 * ij  # a 9 × 9 dot plate, 4 mm pitch
    >>> planes = [
    ...     ptv.PlaneObservation(z, truth.project(np.column_stack([xy, np.full(81, z)])), xy)
    ...     for z in (-2e-3, 0.0, 2e-3)
    ... ]
    >>> calibration = ptv.calibrate_model_free(planes, (640, 480))
    >>> point = np.array([[3e-3, -2e-3, 1e-3]])  # m, between the planes
    >>> pixel = truth.project(point)
    >>> bool(np.abs(calibration.project(point) - pixel).max() < 1e-4)  # px
    True
    >>> ray = calibration.pixel_to_ray(pixel)  # passes through the point
    >>> offset = point - ray.origins
    >>> miss = offset - (offset @ ray.directions.T) * ray.directions
    >>> bool(np.linalg.norm(miss) < 1e-8)  # m
    True
    >>> calibration.pixel_to_ray(np.array([[5.0, 5.0]])).valid  # no dot near: no ray
    array([False])
    """
    if len(observations) < 2:
        raise ValueError(f"need at least two calibration planes, got {len(observations)}")
    z = np.array([o.z for o in observations], dtype=float)
    if len(np.unique(z)) != len(z) or not np.isfinite(z).all():
        raise ValueError(f"calibration planes need distinct finite Z, got {z.tolist()}")
    if curved and len(z) < 3:
        raise ValueError(f"curved rays need at least three calibration planes, got {len(z)}")
    width, height = image_size
    if width < 2 * grid_step or height < 2 * grid_step:
        raise ValueError(f"image size {image_size} too small for grid step {grid_step}")
    planes = tuple(fit_plane(o, degree=degree) for o in observations)
    for plane in planes:
        log.info(
            "plane Z = %.4g m: max residual %.3g px (%d dots)",
            plane.z,
            plane.residual_px.max(),
            len(plane.residual_px),
        )
    grid_x = np.unique(np.append(np.arange(0, width, grid_step, dtype=float), width - 1.0))
    grid_y = np.unique(np.append(np.arange(0, height, grid_step, dtype=float), height - 1.0))
    gx, gy = np.meshgrid(grid_x, grid_y)
    pixels = np.column_stack([gx.ravel(), gy.ravel()])
    world = np.stack([plane.to_world(pixels) for plane in planes])  # (N_Z, G, 2)
    z_ref = float(z.mean())
    # Regress X and Y on Z (exact) per grid pixel: X = Σ_n c_n (Z − Z̄)^n, n ≤ q.
    powers = np.vander(z - z_ref, 3 if curved else 2, increasing=True)  # (N_Z, q + 1)
    coefficients = np.linalg.lstsq(powers, world.reshape(len(z), -1), rcond=None)[0]
    fitted = (powers @ coefficients).reshape(world.shape)
    rms = np.sqrt(np.mean(np.sum((world - fitted) ** 2, axis=-1), axis=0))
    shape = gx.shape
    # (q + 1, G, 2) → rows X₀, Y₀, a, b[, a₂, b₂]
    params = coefficients.reshape(len(powers[0]), -1, 2).transpose(0, 2, 1).reshape(-1, *shape)
    return ModelFreeCalibration(
        image_size=(int(width), int(height)),
        planes=planes,
        z_ref=z_ref,
        grid_x=grid_x,
        grid_y=grid_y,
        line_parameters=params,
        line_rms=rms.reshape(shape),
    )
