"""Lens and sensor: pinhole + Brown–Conrady distortion + tilted (Scheimpflug) sensor.

Normalized camera coordinates (x, y) = (X_c/Z_c, Y_c/Z_c) of a point in the camera
frame (OpenCV: x right, y down, z along the optical axis) map to pixels as in OpenCV
(docs/optics.md §2–3):

- distortion, with r² = x² + y²::

      x_d = x·(1 + k1 r² + k2 r⁴ + k3 r⁶) + 2 p1 x y + p2 (r² + 2x²)
      y_d = y·(1 + k1 r² + k2 r⁴ + k3 r⁶) + p1 (r² + 2y²) + 2 p2 x y

- tilted sensor: [x_t, y_t, w]ᵀ = M_τ [x_d, y_d, 1]ᵀ with
  M_τ = [[R33, 0, −R13], [0, R33, −R23], [0, 0, 1]] · R, R = R_y(τ_y) R_x(τ_x)
  (OpenCV ``computeTiltProjectionMatrix``). Geometrically, (x_t/w, y_t/w) is where the
  ray through (x_d, y_d, 1) meets the sensor plane through (0, 0, 1) whose normal in
  the camera frame is the third row of R, (sin τ_y, −cos τ_y sin τ_x, cos τ_y cos τ_x),
  in that plane's own axes and measured from the optical axis;
- pixels: u = f_x x_t/w + c_x, v = f_y y_t/w + c_y, with f_x = f_y = principal
  distance / pixel pitch.

The inverse undoes the tilt exactly (a homography) and inverts the distortion by a
vectorised 2-D Newton iteration to 1e-12 in normalized coordinates.
"""

import logging
from dataclasses import dataclass

import numpy as np

logger = logging.getLogger(__name__)

#: Newton tolerance of the undistortion, in normalized coordinates (1e-12 ≈ 1e-8 px).
UNDISTORT_TOLERANCE = 1e-12
#: Iteration cap of the undistortion; points not converged by then become NaN.
UNDISTORT_MAX_ITERATIONS = 50


def tilt_rotation(tau_x: float, tau_y: float) -> np.ndarray:
    """R(τ_x, τ_y) = R_y(τ_y)·R_x(τ_x) of OpenCV's tilted-sensor model, shape (3, 3)."""
    cx, sx = np.cos(tau_x), np.sin(tau_x)
    cy, sy = np.cos(tau_y), np.sin(tau_y)
    rot_x = np.array([[1.0, 0.0, 0.0], [0.0, cx, sx], [0.0, -sx, cx]])
    rot_y = np.array([[cy, 0.0, -sy], [0.0, 1.0, 0.0], [sy, 0.0, cy]])
    return rot_y @ rot_x


def tilt_matrix(tau_x: float, tau_y: float) -> np.ndarray:
    """M_τ, the (3, 3) tilted-sensor homography (OpenCV ``computeTiltProjectionMatrix``)."""
    rot = tilt_rotation(tau_x, tau_y)
    proj = np.array(
        [[rot[2, 2], 0.0, -rot[0, 2]], [0.0, rot[2, 2], -rot[1, 2]], [0.0, 0.0, 1.0]]
    )
    return proj @ rot


def sensor_normal(tau_x: float, tau_y: float) -> np.ndarray:
    """Unit normal (3,) of the tilted sensor plane in the camera frame (z component > 0)."""
    return tilt_rotation(tau_x, tau_y)[2].copy()


def tilt_from_normal(normal: np.ndarray) -> tuple[float, float]:
    """(τ_x, τ_y), rad, of the sensor whose camera-frame normal is ``normal`` (z > 0)."""
    n = np.asarray(normal, dtype=np.float64)
    n = n / np.linalg.norm(n)
    if n[2] <= 0:
        raise ValueError(f"sensor normal must point along +z of the camera; got {n.tolist()}")
    return float(np.arctan2(-n[1], n[2])), float(np.arcsin(n[0]))


def radial_fold(k1: float, k2: float, k3: float) -> float:
    """Largest r² below which r ↦ r(1 + k1 r² + k2 r⁴ + k3 r⁶) is increasing.

    The radial map folds where its derivative 1 + 3k1 q + 5k2 q² + 7k3 q³ (q = r²)
    first vanishes; beyond that radius two object directions share a pixel and the
    image is not physical. Returns ``inf`` when the derivative never vanishes.
    """
    coefficients = [1.0, 3.0 * k1, 5.0 * k2, 7.0 * k3]  # ascending powers of q
    while len(coefficients) > 1 and abs(coefficients[-1]) < 1e-250:  # (sub)normal → 0
        coefficients.pop()
    if len(coefficients) == 1:
        return float("inf")
    roots = np.polynomial.polynomial.polyroots(coefficients)
    real = [r.real for r in roots if abs(r.imag) <= 1e-12 * max(1.0, abs(r)) and r.real > 0]
    return float(min(real)) if real else float("inf")


def distort(
    xn: np.ndarray, k1: float, k2: float, k3: float, p1: float, p2: float
) -> tuple[np.ndarray, np.ndarray]:
    """Brown–Conrady distortion of normalized coordinates and its Jacobian.

    Parameters
    ----------
    xn : ndarray, shape (N, 2)
        Undistorted normalized coordinates (x, y).
    k1, k2, k3, p1, p2 : float
        Radial and tangential coefficients (OpenCV convention).

    Returns
    -------
    xd : ndarray, shape (N, 2)
        Distorted normalized coordinates.
    jac : ndarray, shape (N, 2, 2)
        ∂(x_d, y_d)/∂(x, y).
    """
    x, y = xn[:, 0], xn[:, 1]
    r2 = x * x + y * y
    radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    g = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2)  # d radial / d r²
    xy = x * y
    xd = np.empty_like(xn)
    xd[:, 0] = x * radial + 2.0 * p1 * xy + p2 * (r2 + 2.0 * x * x)
    xd[:, 1] = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * xy
    jac = np.empty((len(xn), 2, 2))
    off = 2.0 * xy * g + 2.0 * p1 * x + 2.0 * p2 * y
    jac[:, 0, 0] = radial + 2.0 * x * x * g + 2.0 * p1 * y + 6.0 * p2 * x
    jac[:, 0, 1] = off
    jac[:, 1, 0] = off
    jac[:, 1, 1] = radial + 2.0 * y * y * g + 6.0 * p1 * y + 2.0 * p2 * x
    return xd, jac


def undistort(
    xd: np.ndarray, k1: float, k2: float, k3: float, p1: float, p2: float
) -> np.ndarray:
    """Invert :func:`distort` by Newton's method to 1e-12 (normalized units).

    Parameters
    ----------
    xd : ndarray, shape (N, 2)
        Distorted normalized coordinates (NaN rows pass through).

    Returns
    -------
    ndarray, shape (N, 2)
        Undistorted normalized coordinates; NaN where the iteration did not converge
        or converged beyond the fold of the distortion (a non-invertible region).
    """
    if k1 == k2 == k3 == p1 == p2 == 0.0:
        return xd.copy()
    x = xd.copy()
    active = np.isfinite(x).all(axis=1)
    converged = ~active
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        for _ in range(UNDISTORT_MAX_ITERATIONS):
            idx = np.flatnonzero(~converged)
            if idx.size == 0:
                break
            cur = x[idx]
            value, jac = distort(cur, k1, k2, k3, p1, p2)
            res = value - xd[idx]
            det = jac[:, 0, 0] * jac[:, 1, 1] - jac[:, 0, 1] * jac[:, 1, 0]
            dx = (jac[:, 1, 1] * res[:, 0] - jac[:, 0, 1] * res[:, 1]) / det
            dy = (jac[:, 0, 0] * res[:, 1] - jac[:, 1, 0] * res[:, 0]) / det
            cur[:, 0] -= dx
            cur[:, 1] -= dy
            x[idx] = cur
            step = np.maximum(np.abs(dx), np.abs(dy))
            done = (step <= UNDISTORT_TOLERANCE) | ~np.isfinite(step)
            converged[idx[done]] = True
    failed = ~converged | ~np.isfinite(x).all(axis=1)
    x[failed] = np.nan
    # Reject roots on the far side of a fold: not the physical (monotone) branch.
    ok = np.isfinite(x[:, 0])
    if ok.any():
        _, jac = distort(x[ok], k1, k2, k3, p1, p2)
        det = jac[:, 0, 0] * jac[:, 1, 1] - jac[:, 0, 1] * jac[:, 1, 0]
        r2 = np.einsum("ij,ij->i", x[ok], x[ok])
        bad = np.flatnonzero(ok)[(det <= 0) | (r2 >= radial_fold(k1, k2, k3))]
        x[bad] = np.nan
    n_failed = int((~np.isfinite(x[:, 0]) & active).sum())
    if n_failed:
        logger.debug("undistortion: %d of %d points have no physical solution", n_failed, len(x))
    return x


@dataclass(frozen=True, eq=False)
class Lens:
    """A thin lens, its distortion and a (possibly tilted) pixel sensor.

    Attributes
    ----------
    focal_length : float
        Thin-lens focal length f, m.
    pixel_pitch : float
        Pixel size (square pixels), m.
    sensor_size : tuple of int
        (width, height), px. Default 2048 × 1088 (CMV2000-class sensor).
    principal_point : tuple of float or None
        (c_x, c_y), px: where the optical axis meets the sensor. Default: the sensor
        centre ((width − 1)/2, (height − 1)/2).
    k1, k2, k3, p1, p2 : float
        Brown–Conrady radial and tangential coefficients (OpenCV convention).
    tau_x, tau_y : float
        Sensor tilt, rad, |τ| < 45° (OpenCV tilted model: R = R_y(τ_y) R_x(τ_x)).
    image_distance : float or None
        Principal distance: distance from the lens (entrance pupil) to the sensor
        along the axis, m. It sets f_x = f_y = image_distance / pixel_pitch. Default:
        ``focal_length`` (focused at infinity). A lens focused at object distance s_o
        has image_distance = f s_o/(s_o − f) (see ``simulator.optics.scheimpflug``).
    f_number : float
        Aperture f-number N (aperture diameter f/N); used only for defocus blur.

    Examples
    --------
    A 50 mm lens on a 640 × 480 sensor of 10 µm pixels, focused at infinity: 5000 px
    of principal distance, the principal point at the sensor's centre.

    >>> import simulator
    >>> lens = simulator.Lens(focal_length=0.05, pixel_pitch=10e-6, sensor_size=(640, 480))
    >>> lens.fx, lens.principal_point  # px
    (5000.0, (319.5, 239.5))

    With barrel distortion (OpenCV's k1 < 0) a direction near the sensor's edge images
    closer to the centre:

    >>> import numpy as np
    >>> barrel = simulator.Lens(focal_length=0.05, pixel_pitch=10e-6, sensor_size=(640, 480),
    ...                         k1=-0.1)
    >>> direction = np.array([[0.06, 0.0]])  # normalised camera coordinates X_c/Z_c, Y_c/Z_c
    >>> xy, valid = lens.normalized_to_pixel(direction)
    >>> xy_barrel, _ = barrel.normalized_to_pixel(direction)
    >>> xy.round(2), xy_barrel.round(2)  # px
    (array([[619.5, 239.5]]), array([[619.39, 239.5 ]]))
    """

    focal_length: float
    pixel_pitch: float
    sensor_size: tuple[int, int] = (2048, 1088)
    principal_point: tuple[float, float] | None = None
    k1: float = 0.0
    k2: float = 0.0
    k3: float = 0.0
    p1: float = 0.0
    p2: float = 0.0
    tau_x: float = 0.0
    tau_y: float = 0.0
    image_distance: float | None = None
    f_number: float = 8.0

    def __post_init__(self) -> None:
        for name in ("focal_length", "pixel_pitch", "f_number"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"Lens.{name} must be finite and > 0; got {value!r}")
        width, height = self.sensor_size
        if int(width) != width or int(height) != height or width < 1 or height < 1:
            raise ValueError(
                f"Lens.sensor_size must be two positive integers (width, height) in px; "
                f"got {self.sensor_size!r}"
            )
        object.__setattr__(self, "sensor_size", (int(width), int(height)))
        if self.principal_point is None:
            centre = ((width - 1) / 2.0, (height - 1) / 2.0)
            object.__setattr__(self, "principal_point", centre)
        cx, cy = self.principal_point
        if not (np.isfinite(cx) and np.isfinite(cy)):
            raise ValueError(f"Lens.principal_point must be finite; got {self.principal_point!r}")
        object.__setattr__(self, "principal_point", (float(cx), float(cy)))
        for name in ("k1", "k2", "k3", "p1", "p2"):
            if not np.isfinite(getattr(self, name)):
                raise ValueError(f"Lens.{name} must be finite; got {getattr(self, name)!r}")
        for name in ("tau_x", "tau_y"):
            value = getattr(self, name)
            if not (np.isfinite(value) and abs(value) < np.pi / 4):
                raise ValueError(
                    f"Lens.{name} must be a finite tilt below 45° in rad; got {value!r}"
                )
        if self.image_distance is None:
            object.__setattr__(self, "image_distance", float(self.focal_length))
        elif not (np.isfinite(self.image_distance) and self.image_distance > 0):
            raise ValueError(
                f"Lens.image_distance must be finite and > 0; got {self.image_distance!r}"
            )

    # -- derived quantities -------------------------------------------------------
    @property
    def fx(self) -> float:
        """Principal distance in pixels (= f_y), px."""
        return self.image_distance / self.pixel_pitch

    @property
    def distortion(self) -> tuple[float, float, float, float, float]:
        """(k1, k2, k3, p1, p2)."""
        return (self.k1, self.k2, self.k3, self.p1, self.p2)

    @property
    def focus_distance(self) -> float:
        """Object-side in-focus distance s_o = f s_i/(s_i − f) along the axis, m (inf if none).

        For a camera behind a window this is an apparent (air-equivalent) distance.
        """
        if self.image_distance <= self.focal_length:
            return float("inf")
        f, si = self.focal_length, self.image_distance
        return f * si / (si - f)

    @property
    def aperture_diameter(self) -> float:
        """Entrance-pupil diameter f/N, m."""
        return self.focal_length / self.f_number

    def camera_matrix(self) -> np.ndarray:
        """OpenCV camera matrix K (3, 3), px."""
        cx, cy = self.principal_point
        return np.array([[self.fx, 0.0, cx], [0.0, self.fx, cy], [0.0, 0.0, 1.0]])

    def opencv_dist_coeffs(self) -> np.ndarray:
        """OpenCV 14-element distortion vector (k1, k2, p1, p2, k3, k4–k6, s1–s4, τx, τy)."""
        coeffs = np.zeros(14)
        coeffs[[0, 1, 2, 3, 4]] = (self.k1, self.k2, self.p1, self.p2, self.k3)
        coeffs[[12, 13]] = (self.tau_x, self.tau_y)
        return coeffs

    # -- mappings -----------------------------------------------------------------
    def normalized_to_pixel(self, xn: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pixel positions of normalized camera coordinates (distortion, tilt, K).

        Parameters
        ----------
        xn : ndarray, shape (N, 2)
            (X_c/Z_c, Y_c/Z_c); NaN rows pass through.

        Returns
        -------
        xy : ndarray, shape (N, 2)
            Pixel coordinates (x = column, y = row), px; NaN where invalid.
        valid : ndarray of bool, shape (N,)
            False where the direction lies beyond the fold of the distortion or never
            meets the tilted sensor plane. The sensor bounds are not checked here
            (see :meth:`on_sensor`).
        """
        xd, jac = distort(xn, *self.distortion)
        valid = np.isfinite(xd).all(axis=1)
        if self.k1 or self.k2 or self.k3 or self.p1 or self.p2:
            det = jac[:, 0, 0] * jac[:, 1, 1] - jac[:, 0, 1] * jac[:, 1, 0]
            r2 = xn[:, 0] ** 2 + xn[:, 1] ** 2
            valid &= (det > 0) & (r2 < radial_fold(self.k1, self.k2, self.k3))
        cx, cy = self.principal_point
        xy = np.empty_like(xd)
        if self.tau_x == 0.0 and self.tau_y == 0.0:
            xy[:, 0] = self.fx * xd[:, 0] + cx
            xy[:, 1] = self.fx * xd[:, 1] + cy
        else:
            m = tilt_matrix(self.tau_x, self.tau_y)
            w = m[2, 0] * xd[:, 0] + m[2, 1] * xd[:, 1] + m[2, 2]
            valid &= w > 0
            with np.errstate(divide="ignore", invalid="ignore"):
                scale = self.fx / w
            xy[:, 0] = (m[0, 0] * xd[:, 0] + m[0, 1] * xd[:, 1] + m[0, 2]) * scale + cx
            xy[:, 1] = (m[1, 0] * xd[:, 0] + m[1, 1] * xd[:, 1] + m[1, 2]) * scale + cy
        xy[~valid] = np.nan
        return xy, valid

    def pixel_to_normalized(self, xy: np.ndarray) -> np.ndarray:
        """Normalized camera coordinates of pixels (exact inverse tilt, Newton undistortion).

        Parameters
        ----------
        xy : ndarray, shape (N, 2)
            Pixel coordinates, px (any position, on or off the sensor).

        Returns
        -------
        ndarray, shape (N, 2)
            (X_c/Z_c, Y_c/Z_c) of the direction imaged at each pixel; NaN where no
            physical direction maps there.
        """
        cx, cy = self.principal_point
        xt = (xy[:, 0] - cx) / self.fx
        yt = (xy[:, 1] - cy) / self.fx
        xd = np.empty_like(xy)
        if self.tau_x == 0.0 and self.tau_y == 0.0:
            xd[:, 0], xd[:, 1] = xt, yt
        else:
            inv = np.linalg.inv(tilt_matrix(self.tau_x, self.tau_y))
            w = inv[2, 0] * xt + inv[2, 1] * yt + inv[2, 2]
            with np.errstate(divide="ignore", invalid="ignore"):
                xd[:, 0] = (inv[0, 0] * xt + inv[0, 1] * yt + inv[0, 2]) / w
                xd[:, 1] = (inv[1, 0] * xt + inv[1, 1] * yt + inv[1, 2]) / w
            xd[~(w > 0)] = np.nan
        return undistort(xd, *self.distortion)

    def on_sensor(self, xy: np.ndarray) -> np.ndarray:
        """True (N,) where a pixel position lies on the sensor area [−½, W−½] × [−½, H−½]."""
        width, height = self.sensor_size
        with np.errstate(invalid="ignore"):
            return (
                (xy[:, 0] >= -0.5)
                & (xy[:, 0] <= width - 0.5)
                & (xy[:, 1] >= -0.5)
                & (xy[:, 1] <= height - 0.5)
            )
