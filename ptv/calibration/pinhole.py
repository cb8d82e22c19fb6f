"""The full OpenCV pinhole camera: the strongest honest model-based baseline.

Model (OpenCV convention, docs/optics.md §2): camera coordinates X_c = R X + t, normalised
coordinates x = X_c/Z_c, y = Y_c/Z_c, Brown–Conrady distortion with k1, k2, k3 (radial)
and p1, p2 (tangential), optionally OpenCV's tilted sensor M_τ (``CALIB_TILTED_MODEL``),
then u = f_x x_t + c_x, v = f_y y_t + c_y. No skew (OpenCV has none). The principal
point and f_x ≠ f_y are free. The model has no refraction: its error through oblique
windows is what the paper measures (MLBAV Table 1).

The fit is :mod:`ptv.calibration.pinhole_fit`.

``pixel_to_ray`` undoes K and the tilt, inverts the distortion by a 2-D Newton
iteration (to 1e-13 in normalised coordinates) and returns the straight ray from the
camera centre C = −Rᵀt.
"""

from dataclasses import dataclass, field

import cv2
import numpy as np

from ptv.camera_model import on_image
from ptv.rays import Rays

#: Distortion coefficients the model may fit, in OpenCV's naming.
DISTORTION_TERMS = ("k1", "k2", "p1", "p2", "k3")

#: Layout of the full parameter vector (:data:`PARAMETER_NAMES`): indices and slices.
FX, FY, CX, CY = 0, 1, 2, 3
DIST_INDEX = {"k1": 4, "k2": 5, "p1": 6, "p2": 7, "k3": 8}
TAU_X, TAU_Y = 9, 10
RVEC = slice(11, 14)
TVEC = slice(14, 17)
N_PARAMS = 17
PARAMETER_NAMES = (
    "fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3", "tau_x", "tau_y",
    "rx", "ry", "rz", "tx", "ty", "tz",
)  # fmt: skip

#: Newton tolerance (normalised units) and iteration cap of the undistortion.
_UNDISTORT_TOL = 1e-13
_UNDISTORT_STEPS = 50


@dataclass(frozen=True)
class PinholeModel:
    """Which parameters of the OpenCV pinhole a calibration fits.

    Parameters
    ----------
    distortion : tuple of str
        Free distortion coefficients, a subset of ``DISTORTION_TERMS`` (p1 and p2 come
        together: OpenCV cannot free one alone). The others are zero.
    tilted : bool
        Fit OpenCV's tilted-sensor angles τ_x, τ_y (``CALIB_TILTED_MODEL``).
    fixed_principal_point : bool
        Keep (c_x, c_y) at its guess (``CALIB_FIX_PRINCIPAL_POINT``): for one view of a
        shallow target, where the principal point trades off against the rotation.
    """

    distortion: tuple[str, ...] = ("k1", "k2", "p1", "p2")
    tilted: bool = False
    fixed_principal_point: bool = False

    def __post_init__(self) -> None:
        terms = tuple(self.distortion)
        unknown = sorted(set(terms) - set(DISTORTION_TERMS))
        if unknown or len(set(terms)) != len(terms):
            raise ValueError(
                f"distortion terms must be distinct names from {DISTORTION_TERMS}, got {terms!r}"
            )
        if ("p1" in terms) != ("p2" in terms):
            raise ValueError(f"p1 and p2 must be free together, got {terms!r}")
        ordered = tuple(t for t in DISTORTION_TERMS if t in terms)
        object.__setattr__(self, "distortion", ordered)
        object.__setattr__(self, "tilted", bool(self.tilted))
        object.__setattr__(self, "fixed_principal_point", bool(self.fixed_principal_point))

    @property
    def name(self) -> str:
        """Short description, e.g. ``'k1,k2,p1,p2'``, ``'k1+tilt'`` or ``'k1+fixed pp'``."""
        name = ",".join(self.distortion) or "no distortion"
        name += "+tilt" if self.tilted else ""
        return name + ("+fixed pp" if self.fixed_principal_point else "")

    @property
    def free(self) -> np.ndarray:
        """Indices of the free entries of the full parameter vector (``PARAMETER_NAMES``)."""
        centre = [] if self.fixed_principal_point else [CX, CY]
        idx = [FX, FY, *centre, *(DIST_INDEX[t] for t in self.distortion)]
        if self.tilted:
            idx += [TAU_X, TAU_Y]
        idx += list(range(RVEC.start, TVEC.stop))
        return np.array(idx)

    def opencv_flags(self) -> int:
        """``cv2.calibrateCamera`` flags fitting exactly this model from a guess."""
        flags = cv2.CALIB_USE_INTRINSIC_GUESS
        for term, flag in (("k1", cv2.CALIB_FIX_K1), ("k2", cv2.CALIB_FIX_K2)):
            if term not in self.distortion:
                flags |= flag
        if "k3" not in self.distortion:
            flags |= cv2.CALIB_FIX_K3
        if "p1" not in self.distortion:
            flags |= cv2.CALIB_ZERO_TANGENT_DIST
        if self.tilted:
            flags |= cv2.CALIB_TILTED_MODEL
        if self.fixed_principal_point:
            flags |= cv2.CALIB_FIX_PRINCIPAL_POINT
        return flags

    def restrict(self, params: np.ndarray) -> np.ndarray:
        """A copy of a full parameter vector with this model's fixed terms set to zero."""
        out = np.array(params, dtype=float)
        for term, i in DIST_INDEX.items():
            if term not in self.distortion:
                out[i] = 0.0
        if not self.tilted:
            out[[TAU_X, TAU_Y]] = 0.0
        return out


# -- the camera model ---------------------------------------------------------------


def rodrigues(rvec: np.ndarray) -> np.ndarray:
    """Rotation matrix (3, 3) of a rotation vector (axis × angle, rad), as ``cv2.Rodrigues``."""
    return cv2.Rodrigues(np.asarray(rvec, dtype=float).reshape(3, 1))[0]


def tilt_matrix(tau_x: float, tau_y: float) -> np.ndarray:
    """OpenCV's tilted-sensor homography M_τ (``computeTiltProjectionMatrix``), (3, 3)."""
    cx, sx = np.cos(tau_x), np.sin(tau_x)
    cy, sy = np.cos(tau_y), np.sin(tau_y)
    rot = np.array([[cy, 0.0, -sy], [0.0, 1.0, 0.0], [sy, 0.0, cy]]) @ np.array(
        [[1.0, 0.0, 0.0], [0.0, cx, sx], [0.0, -sx, cx]]
    )
    proj = np.array([[rot[2, 2], 0.0, -rot[0, 2]], [0.0, rot[2, 2], -rot[1, 2]], [0.0, 0.0, 1.0]])
    return proj @ rot


def _distort(x: np.ndarray, y: np.ndarray, p: np.ndarray):
    """Distorted normalised coordinates and the Jacobian entries (j00, j01, j10, j11)."""
    k1, k2, p1, p2, k3 = p[4], p[5], p[6], p[7], p[8]
    r2 = x * x + y * y
    radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    g = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2)  # d radial / d r²
    xy = x * y
    xd = x * radial + 2.0 * p1 * xy + p2 * (r2 + 2.0 * x * x)
    yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * xy
    off = 2.0 * xy * g + 2.0 * p1 * x + 2.0 * p2 * y
    j00 = radial + 2.0 * x * x * g + 2.0 * p1 * y + 6.0 * p2 * x
    j11 = radial + 2.0 * y * y * g + 6.0 * p1 * y + 2.0 * p2 * x
    return xd, yd, (j00, off, off, j11)


def radial_fold(k1: float, k2: float, k3: float) -> float:
    """Largest r² below which r ↦ r(1 + k1 r² + k2 r⁴ + k3 r⁶) increases (inf if always)."""
    coefficients = np.trim_zeros(np.array([1.0, 3.0 * k1, 5.0 * k2, 7.0 * k3]), "b")
    if len(coefficients) == 1:
        return float("inf")
    roots = np.polynomial.polynomial.polyroots(coefficients)
    real = roots.real[
        (np.abs(roots.imag) <= 1e-12 * np.maximum(1.0, np.abs(roots))) & (roots.real > 0)
    ]
    return float(real.min()) if real.size else float("inf")


def project_parameters(
    params: np.ndarray, points: np.ndarray, *, jacobian: bool = False
) -> tuple[np.ndarray, np.ndarray] | tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pixels of world points under a full parameter vector (``PARAMETER_NAMES``).

    Parameters
    ----------
    params : ndarray, shape (17,)
        fx, fy, cx, cy (px), k1, k2, p1, p2, k3, τ_x, τ_y (rad), rotation vector, t (m).
    points : ndarray, shape (N, 3)
        World points, m.
    jacobian : bool
        Also return ∂xy/∂params.

    Returns
    -------
    xy : ndarray, shape (N, 2)
        Pixels, px, computed for every point (also where not valid).
    valid : ndarray of bool, shape (N,)
        In front of the camera, inside the distortion's monotone domain and meeting the
        tilted sensor; the image bounds are not checked.
    jac : ndarray, shape (N, 2, 17)
        Only with ``jacobian``: ∂(u, v)/∂params (rotation columns through
        ``cv2.Rodrigues``' derivative).
    """
    p = np.asarray(params, dtype=float)
    rot, drot = cv2.Rodrigues(p[RVEC].reshape(3, 1))
    cam = points @ rot.T + p[TVEC]
    z = cam[:, 2]
    ahead = z > 0
    z = np.where(np.abs(z) > 1e-300, z, 1e-300)
    x, y = cam[:, 0] / z, cam[:, 1] / z
    xd, yd, (j00, j01, j10, j11) = _distort(x, y, p)
    valid = ahead & (j00 * j11 - j01 * j10 > 0) & (x * x + y * y < radial_fold(p[4], p[5], p[8]))
    tilted = p[TAU_X] != 0.0 or p[TAU_Y] != 0.0 or jacobian
    if tilted:
        m = tilt_matrix(p[TAU_X], p[TAU_Y])
        w = m[2, 0] * xd + m[2, 1] * yd + m[2, 2]
        valid &= w > 0
        w = np.where(np.abs(w) > 1e-300, w, 1e-300)
        xt = (m[0, 0] * xd + m[0, 1] * yd + m[0, 2]) / w
        yt = (m[1, 0] * xd + m[1, 1] * yd + m[1, 2]) / w
    else:
        xt, yt = xd, yd
    xy = np.column_stack([p[FX] * xt + p[CX], p[FY] * yt + p[CY]])
    if not jacobian:
        return xy, valid
    n = len(points)
    jac = np.zeros((n, 2, N_PARAMS))
    jac[:, 0, FX] = xt
    jac[:, 1, FY] = yt
    jac[:, 0, CX] = 1.0
    jac[:, 1, CY] = 1.0
    focal = np.array([p[FX], p[FY]])
    # tilt: ∂(xt, yt)/∂(xd, yd) and ∂(xt, yt)/∂τ (central differences of M_τ, exact to ~1e-10)
    dt = np.empty((n, 2, 2))
    dt[:, 0, 0] = (m[0, 0] - xt * m[2, 0]) / w
    dt[:, 0, 1] = (m[0, 1] - xt * m[2, 1]) / w
    dt[:, 1, 0] = (m[1, 0] - yt * m[2, 0]) / w
    dt[:, 1, 1] = (m[1, 1] - yt * m[2, 1]) / w
    h = 1e-6
    for col, (ex, ey) in ((TAU_X, (h, 0.0)), (TAU_Y, (0.0, h))):
        dm = (
            tilt_matrix(p[TAU_X] + ex, p[TAU_Y] + ey) - tilt_matrix(p[TAU_X] - ex, p[TAU_Y] - ey)
        ) / (2 * h)
        dw = dm[2, 0] * xd + dm[2, 1] * yd + dm[2, 2]
        jac[:, 0, col] = focal[0] * ((dm[0, 0] * xd + dm[0, 1] * yd + dm[0, 2]) - xt * dw) / w
        jac[:, 1, col] = focal[1] * ((dm[1, 0] * xd + dm[1, 1] * yd + dm[1, 2]) - yt * dw) / w
    # distortion coefficients: ∂(xd, yd)/∂(k1, k2, p1, p2, k3)
    r2 = x * x + y * y
    ddist = np.empty((n, 2, 5))
    ddist[:, 0, 0], ddist[:, 1, 0] = x * r2, y * r2
    ddist[:, 0, 1], ddist[:, 1, 1] = x * r2**2, y * r2**2
    ddist[:, 0, 2], ddist[:, 1, 2] = 2.0 * x * y, r2 + 2.0 * y * y
    ddist[:, 0, 3], ddist[:, 1, 3] = r2 + 2.0 * x * x, 2.0 * x * y
    ddist[:, 0, 4], ddist[:, 1, 4] = x * r2**3, y * r2**3
    chain = focal[None, :, None] * dt  # ∂(u, v)/∂(xd, yd)
    jac[:, :, 4:9] = chain @ ddist
    # pose: ∂(x, y)/∂cam, ∂cam/∂rvec = dR/dr · X, ∂cam/∂t = I
    dd = np.empty((n, 2, 2))
    dd[:, 0, 0], dd[:, 0, 1], dd[:, 1, 0], dd[:, 1, 1] = j00, j01, j10, j11
    dproj = np.zeros((n, 2, 3))
    dproj[:, 0, 0] = 1.0 / z
    dproj[:, 1, 1] = 1.0 / z
    dproj[:, 0, 2] = -x / z
    dproj[:, 1, 2] = -y / z
    to_cam = chain @ dd @ dproj  # ∂(u, v)/∂cam, (N, 2, 3)
    dcam_dr = np.einsum("kij,nj->nik", drot.reshape(3, 3, 3), points)  # (N, 3, 3)
    jac[:, :, RVEC] = to_cam @ dcam_dr
    jac[:, :, TVEC] = to_cam
    return xy, valid, jac


def undistort_normalized(xd: np.ndarray, params: np.ndarray) -> np.ndarray:
    """Invert the distortion of a parameter vector by Newton's method.

    Parameters
    ----------
    xd : ndarray, shape (N, 2)
        Distorted normalised coordinates (after undoing K and the tilt).
    params : ndarray, shape (17,)
        Full parameter vector.

    Returns
    -------
    ndarray, shape (N, 2)
        Undistorted normalised coordinates; NaN where the iteration did not converge or
        converged beyond the fold of the distortion.
    """
    p = np.asarray(params, dtype=float)
    xd = np.asarray(xd, dtype=float)
    x = xd.copy()
    if not np.any(p[4:9]):
        return x
    todo = np.flatnonzero(np.isfinite(x).all(axis=1))
    converged = np.zeros(len(x), dtype=bool)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        for _ in range(_UNDISTORT_STEPS):
            if todo.size == 0:
                break
            cur = x[todo]
            ux, uy, (j00, j01, j10, j11) = _distort(cur[:, 0], cur[:, 1], p)
            rx, ry = ux - xd[todo, 0], uy - xd[todo, 1]
            det = j00 * j11 - j01 * j10
            dx = (j11 * rx - j01 * ry) / det
            dy = (j00 * ry - j10 * rx) / det
            x[todo, 0] -= dx
            x[todo, 1] -= dy
            done = (np.maximum(np.abs(dx), np.abs(dy)) <= _UNDISTORT_TOL) | ~np.isfinite(dx + dy)
            converged[todo[done]] = True
            todo = todo[~done]
    ok = converged & np.isfinite(x).all(axis=1)
    if ok.any():
        _, _, (j00, j01, j10, j11) = _distort(x[ok, 0], x[ok, 1], p)
        r2 = np.sum(x[ok] ** 2, axis=1)
        fine = (j00 * j11 - j01 * j10 > 0) & (r2 < radial_fold(p[4], p[5], p[8]))
        ok[np.flatnonzero(ok)[~fine]] = False
    x[~ok] = np.nan
    return x


@dataclass(frozen=True, eq=False)
class PinholeCalibration:
    """An OpenCV pinhole camera fitted to calibration planes.

    Attributes
    ----------
    image_size : tuple of int
        (width, height), px; pixels off [−½, W−½] × [−½, H−½] are not imaged.
    model : PinholeModel
        The fitted parameter set.
    params : ndarray, shape (17,)
        Full parameter vector (``PARAMETER_NAMES``); fixed terms are zero.
    rms : float
        Root-mean-square reprojection error over all dots, px (√mean |Δxy|²).
    start : str
        The start whose polished fit was kept.
    start_rms : dict of str to float
        Reprojection RMS of every polished start of the final model, px.
    n_points : int
        Number of dots fitted.
    """

    image_size: tuple[int, int]
    model: PinholeModel
    params: np.ndarray
    rms: float
    start: str
    start_rms: dict[str, float] = field(default_factory=dict)
    n_points: int = 0

    @property
    def camera_matrix(self) -> np.ndarray:
        """OpenCV K (3, 3), px."""
        p = self.params
        return np.array([[p[FX], 0.0, p[CX]], [0.0, p[FY], p[CY]], [0.0, 0.0, 1.0]])

    @property
    def dist_coeffs(self) -> np.ndarray:
        """OpenCV distortion vector (14,): k1, k2, p1, p2, k3, k4–k6, s1–s4, τ_x, τ_y."""
        p = self.params
        out = np.zeros(14)
        out[:5] = p[[4, 5, 6, 7, 8]]
        out[12:] = p[[TAU_X, TAU_Y]]
        return out

    @property
    def rvec(self) -> np.ndarray:
        """Rotation vector world → camera (3,), rad."""
        return self.params[RVEC].copy()

    @property
    def tvec(self) -> np.ndarray:
        """Translation world → camera (3,), m."""
        return self.params[TVEC].copy()

    @property
    def rotation(self) -> np.ndarray:
        """R (3, 3): X_c = R X + t."""
        return rodrigues(self.params[RVEC])

    @property
    def centre(self) -> np.ndarray:
        """Projection centre C = −Rᵀt in the world frame (3,), m."""
        return -self.rotation.T @ self.params[TVEC]

    def parameters(self) -> dict[str, float]:
        """The free parameters by name (``PARAMETER_NAMES``)."""
        return {PARAMETER_NAMES[i]: float(self.params[i]) for i in self.model.free}

    def project(self, points: np.ndarray) -> np.ndarray:
        """Pixels (N, 2) of world points (N, 3), m; NaN where not imaged.

        Not imaged: behind the camera, beyond the fold of the distortion, or off the
        image.
        """
        points = np.asarray(points, dtype=float)
        if points.ndim != 2 or points.shape[1] != 3:
            raise ValueError(f"points must have shape (N, 3), got {points.shape}")
        finite = np.isfinite(points).all(axis=1)
        with np.errstate(invalid="ignore", over="ignore"):
            xy, valid = project_parameters(self.params, np.where(finite[:, None], points, 0.0))
        xy[~(finite & valid & on_image(xy, self.image_size))] = np.nan
        return xy

    def normalized(self, xy: np.ndarray) -> np.ndarray:
        """Undistorted normalised coordinates (X_c/Z_c, Y_c/Z_c) of pixels, shape (N, 2)."""
        p = self.params
        xy = np.asarray(xy, dtype=float)
        u = (xy[:, 0] - p[CX]) / p[FX]
        v = (xy[:, 1] - p[CY]) / p[FY]
        if self.model.tilted:
            inv = np.linalg.inv(tilt_matrix(p[TAU_X], p[TAU_Y]))
            w = inv[2, 0] * u + inv[2, 1] * v + inv[2, 2]
            with np.errstate(invalid="ignore", divide="ignore"):
                w = np.where(w > 0, w, np.nan)
                u, v = (
                    (inv[0, 0] * u + inv[0, 1] * v + inv[0, 2]) / w,
                    (inv[1, 0] * u + inv[1, 1] * v + inv[1, 2]) / w,
                )
        return undistort_normalized(np.column_stack([u, v]), p)

    def pixel_to_ray(self, xy: np.ndarray) -> Rays:
        """Straight rays from the camera centre for pixels xy (N, 2); NaN off the image.

        Rows are NaN also where the distortion cannot be inverted (beyond its fold).
        """
        xy = np.asarray(xy, dtype=float)
        if xy.ndim != 2 or xy.shape[1] != 2:
            raise ValueError(f"pixels must have shape (N, 2), got {xy.shape}")
        ok = np.isfinite(xy).all(axis=1) & on_image(xy, self.image_size)
        xn = self.normalized(np.where(ok[:, None], xy, 0.0))
        ok &= np.isfinite(xn).all(axis=1)
        cam = np.column_stack([xn, np.ones(len(xn))])
        cam /= np.linalg.norm(cam, axis=1, keepdims=True)
        directions = cam @ self.rotation  # Rᵀ d for each row
        origins = np.broadcast_to(self.centre, directions.shape).copy()
        origins[~ok] = np.nan
        directions[~ok] = np.nan
        return Rays(origins, directions)
