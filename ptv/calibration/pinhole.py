"""The full OpenCV pinhole camera: the strongest honest model-based baseline.

Model (OpenCV convention, docs/optics.md §2): camera coordinates X_c = R X + t, normalised
coordinates x = X_c/Z_c, y = Y_c/Z_c, Brown–Conrady distortion with k1, k2, k3 (radial)
and p1, p2 (tangential), optionally OpenCV's tilted sensor M_τ (``CALIB_TILTED_MODEL``),
then u = f_x x_t + c_x, v = f_y y_t + c_y. No skew (OpenCV has none). The principal
point and f_x ≠ f_y are free. The model has no refraction: its error through oblique
windows is what the paper measures (MLBAV Table 1).

Fit (docs/calibration.md §5, §8):

* all traverse planes form **one non-coplanar view** with the true (X, Y, Z_j), so a
  single pose keeps the known traverse; OpenCV then needs an intrinsic guess
  (``CALIB_USE_INTRINSIC_GUESS``): f/pitch and the image centre;
* ``cv2.calibrateCamera`` stops early on oblique views, so every start is polished by
  Levenberg–Marquardt (``scipy.optimize.least_squares``) on all reprojection errors;
* OpenCV refuses a principal point outside the image, which the best fit through an
  oblique window may need: such starts go straight to the scipy polish;
* the richer models have local minima, so several starts are polished and the best
  kept: OpenCV from the guess, a DLT with RQ decomposition, ``cv2.solvePnP`` with the
  guessed intrinsics, and the nested simpler models (k1 only, then the untilted model)
  used as starts for the richer one.

``pixel_to_ray`` undoes K and the tilt, inverts the distortion by a 2-D Newton
iteration (to 1e-13 in normalised coordinates) and returns the straight ray from the
camera centre C = −Rᵀt.
"""

import logging
from dataclasses import dataclass, field

import cv2
import numpy as np
from scipy.linalg import rq
from scipy.optimize import least_squares

from ptv.calibration.observations import PlaneObservation, stack_planes
from ptv.camera_model import on_image
from ptv.rays import Rays

log = logging.getLogger(__name__)

#: Distortion coefficients the model may fit, in OpenCV's naming.
DISTORTION_TERMS = ("k1", "k2", "p1", "p2", "k3")

# Layout of the full parameter vector.
_FX, _FY, _CX, _CY = 0, 1, 2, 3
_DIST_INDEX = {"k1": 4, "k2": 5, "p1": 6, "p2": 7, "k3": 8}
_TAU_X, _TAU_Y = 9, 10
_RVEC = slice(11, 14)
_TVEC = slice(14, 17)
_N_PARAMS = 17
PARAMETER_NAMES = (
    "fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3", "tau_x", "tau_y",
    "rx", "ry", "rz", "tx", "ty", "tz",
)  # fmt: skip

#: Newton tolerance (normalised units) and iteration cap of the undistortion.
_UNDISTORT_TOL = 1e-13
_UNDISTORT_STEPS = 50
#: Evaluation cap of one Levenberg–Marquardt polish.
_LM_EVALUATIONS = 400


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
        centre = [] if self.fixed_principal_point else [_CX, _CY]
        idx = [_FX, _FY, *centre, *(_DIST_INDEX[t] for t in self.distortion)]
        if self.tilted:
            idx += [_TAU_X, _TAU_Y]
        idx += list(range(_RVEC.start, _TVEC.stop))
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
        for term, i in _DIST_INDEX.items():
            if term not in self.distortion:
                out[i] = 0.0
        if not self.tilted:
            out[[_TAU_X, _TAU_Y]] = 0.0
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
    rot, drot = cv2.Rodrigues(p[_RVEC].reshape(3, 1))
    cam = points @ rot.T + p[_TVEC]
    z = cam[:, 2]
    ahead = z > 0
    z = np.where(np.abs(z) > 1e-300, z, 1e-300)
    x, y = cam[:, 0] / z, cam[:, 1] / z
    xd, yd, (j00, j01, j10, j11) = _distort(x, y, p)
    valid = ahead & (j00 * j11 - j01 * j10 > 0) & (x * x + y * y < radial_fold(p[4], p[5], p[8]))
    tilted = p[_TAU_X] != 0.0 or p[_TAU_Y] != 0.0 or jacobian
    if tilted:
        m = tilt_matrix(p[_TAU_X], p[_TAU_Y])
        w = m[2, 0] * xd + m[2, 1] * yd + m[2, 2]
        valid &= w > 0
        w = np.where(np.abs(w) > 1e-300, w, 1e-300)
        xt = (m[0, 0] * xd + m[0, 1] * yd + m[0, 2]) / w
        yt = (m[1, 0] * xd + m[1, 1] * yd + m[1, 2]) / w
    else:
        xt, yt = xd, yd
    xy = np.column_stack([p[_FX] * xt + p[_CX], p[_FY] * yt + p[_CY]])
    if not jacobian:
        return xy, valid
    n = len(points)
    jac = np.zeros((n, 2, _N_PARAMS))
    jac[:, 0, _FX] = xt
    jac[:, 1, _FY] = yt
    jac[:, 0, _CX] = 1.0
    jac[:, 1, _CY] = 1.0
    focal = np.array([p[_FX], p[_FY]])
    # tilt: ∂(xt, yt)/∂(xd, yd) and ∂(xt, yt)/∂τ (central differences of M_τ, exact to ~1e-10)
    dt = np.empty((n, 2, 2))
    dt[:, 0, 0] = (m[0, 0] - xt * m[2, 0]) / w
    dt[:, 0, 1] = (m[0, 1] - xt * m[2, 1]) / w
    dt[:, 1, 0] = (m[1, 0] - yt * m[2, 0]) / w
    dt[:, 1, 1] = (m[1, 1] - yt * m[2, 1]) / w
    h = 1e-6
    for col, (ex, ey) in ((_TAU_X, (h, 0.0)), (_TAU_Y, (0.0, h))):
        dm = (
            tilt_matrix(p[_TAU_X] + ex, p[_TAU_Y] + ey)
            - tilt_matrix(p[_TAU_X] - ex, p[_TAU_Y] - ey)
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
    jac[:, :, _RVEC] = to_cam @ dcam_dr
    jac[:, :, _TVEC] = to_cam
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
        return np.array([[p[_FX], 0.0, p[_CX]], [0.0, p[_FY], p[_CY]], [0.0, 0.0, 1.0]])

    @property
    def dist_coeffs(self) -> np.ndarray:
        """OpenCV distortion vector (14,): k1, k2, p1, p2, k3, k4–k6, s1–s4, τ_x, τ_y."""
        p = self.params
        out = np.zeros(14)
        out[:5] = p[[4, 5, 6, 7, 8]]
        out[12:] = p[[_TAU_X, _TAU_Y]]
        return out

    @property
    def rvec(self) -> np.ndarray:
        """Rotation vector world → camera (3,), rad."""
        return self.params[_RVEC].copy()

    @property
    def tvec(self) -> np.ndarray:
        """Translation world → camera (3,), m."""
        return self.params[_TVEC].copy()

    @property
    def rotation(self) -> np.ndarray:
        """R (3, 3): X_c = R X + t."""
        return rodrigues(self.params[_RVEC])

    @property
    def centre(self) -> np.ndarray:
        """Projection centre C = −Rᵀt in the world frame (3,), m."""
        return -self.rotation.T @ self.params[_TVEC]

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
        u = (xy[:, 0] - p[_CX]) / p[_FX]
        v = (xy[:, 1] - p[_CY]) / p[_FY]
        if self.model.tilted:
            inv = np.linalg.inv(tilt_matrix(p[_TAU_X], p[_TAU_Y]))
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


# -- fitting ------------------------------------------------------------------------


def _params(fx, fy, cx, cy, rvec, tvec, dist=None) -> np.ndarray:
    p = np.zeros(_N_PARAMS)
    p[[_FX, _FY, _CX, _CY]] = fx, fy, cx, cy
    if dist is not None:
        d = np.ravel(dist)
        d = np.concatenate([d, np.zeros(14 - len(d))])
        p[[4, 5, 6, 7, 8]] = d[:5]
        p[[_TAU_X, _TAU_Y]] = d[12:14]
    p[_RVEC] = np.ravel(rvec)
    p[_TVEC] = np.ravel(tvec)
    return p


def _rms(params: np.ndarray, obj: np.ndarray, img: np.ndarray) -> float:
    with np.errstate(invalid="ignore", over="ignore"):
        xy, _ = project_parameters(params, obj)
    value = float(np.sqrt(np.mean(np.sum((xy - img) ** 2, axis=1))))
    return value if np.isfinite(value) else float("inf")


def _dlt(obj: np.ndarray, img: np.ndarray) -> np.ndarray | None:
    """Start from a normalised DLT and its RQ decomposition (skew dropped, no distortion)."""
    c3, c2 = obj.mean(axis=0), img.mean(axis=0)
    s3 = np.sqrt(3.0) / np.mean(np.linalg.norm(obj - c3, axis=1))
    s2 = np.sqrt(2.0) / np.mean(np.linalg.norm(img - c2, axis=1))
    t3 = np.diag([s3, s3, s3, 1.0])
    t3[:3, 3] = -s3 * c3
    t2 = np.diag([s2, s2, 1.0])
    t2[:2, 2] = -s2 * c2
    xw = np.column_stack([obj, np.ones(len(obj))]) @ t3.T
    xi = (img - c2) * s2
    a = np.zeros((2 * len(obj), 12))
    a[0::2, 0:4] = xw
    a[0::2, 8:12] = -xi[:, :1] * xw
    a[1::2, 4:8] = xw
    a[1::2, 8:12] = -xi[:, 1:] * xw
    proj = np.linalg.inv(t2) @ np.linalg.svd(a, full_matrices=False)[2][-1].reshape(3, 4) @ t3
    if np.linalg.det(proj[:, :3]) < 0:
        proj = -proj
    k, r = rq(proj[:, :3])
    signs = np.sign(np.diag(k))
    if np.any(signs == 0):
        return None
    k, r = k * signs, signs[:, None] * r
    t = np.linalg.solve(k, proj[:, 3])
    k = k / k[2, 2]
    rvec = cv2.Rodrigues(r)[0]
    return _params(k[0, 0], k[1, 1], k[0, 2], k[1, 2], rvec, t)


def _pnp(obj: np.ndarray, img: np.ndarray, k0: np.ndarray) -> np.ndarray | None:
    """Start from ``cv2.solvePnP`` with the guessed intrinsics and no distortion."""
    try:
        ok, rvec, tvec = cv2.solvePnP(obj, img, k0, None, flags=cv2.SOLVEPNP_ITERATIVE)
    except cv2.error as exc:  # pragma: no cover - OpenCV's own failure
        log.info("solvePnP start failed: %s", exc)
        return None
    if not ok:
        return None
    return _params(k0[0, 0], k0[1, 1], k0[0, 2], k0[1, 2], rvec, tvec)


def _opencv(
    obj: np.ndarray,
    img: np.ndarray,
    image_size: tuple[int, int],
    start: np.ndarray,
    model: PinholeModel,
) -> np.ndarray | None:
    """``cv2.calibrateCamera`` on one non-coplanar view, warm-started from ``start``."""
    width, height = image_size
    cx, cy = start[_CX], start[_CY]
    if not (0 <= cx < width and 0 <= cy < height):
        # OpenCV: "Principal point must be within the image"; the scipy polish takes it.
        log.info("OpenCV start skipped: principal point (%.0f, %.0f) off the image", cx, cy)
        return None
    k0 = np.array([[start[_FX], 0.0, cx], [0.0, start[_FY], cy], [0.0, 0.0, 1.0]])
    d0 = np.zeros(14 if model.tilted else 5)
    d0[:5] = start[[4, 5, 6, 7, 8]]
    if model.tilted:
        d0[12:] = start[[_TAU_X, _TAU_Y]]
    criteria = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 200, 1e-15)
    try:
        _, k, dist, rvecs, tvecs = cv2.calibrateCamera(
            [obj.astype(np.float32)],
            [img.astype(np.float32)],
            (int(width), int(height)),
            k0,
            d0,
            flags=model.opencv_flags(),
            criteria=criteria,
        )
    except cv2.error as exc:
        log.info("OpenCV start failed: %s", exc)
        return None
    return model.restrict(_params(k[0, 0], k[1, 1], k[0, 2], k[1, 2], rvecs[0], tvecs[0], dist))


def polish(params: np.ndarray, model: PinholeModel, obj: np.ndarray, img: np.ndarray) -> np.ndarray:
    """Levenberg–Marquardt on all reprojection errors over the model's free parameters.

    Parameters
    ----------
    params : ndarray, shape (17,)
        Start (any entries the model fixes are set to zero).
    model : PinholeModel
        Free parameters.
    obj : ndarray, shape (N, 3)
        World points, m.
    img : ndarray, shape (N, 2)
        Their observed pixels, px.

    Returns
    -------
    ndarray, shape (17,)
        The polished parameter vector.
    """
    base = model.restrict(params)
    free = model.free

    def residual(q: np.ndarray) -> np.ndarray:
        p = base.copy()
        p[free] = q
        with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
            xy, _ = project_parameters(p, obj)
        r = (xy - img).ravel()
        return np.where(np.isfinite(r), r, 1e10)

    def jacobian(q: np.ndarray) -> np.ndarray:
        p = base.copy()
        p[free] = q
        with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
            jac = project_parameters(p, obj, jacobian=True)[2][:, :, free]
        jac = jac.reshape(-1, len(free))
        return np.where(np.isfinite(jac), jac, 0.0)

    if not np.all(np.isfinite(residual(base[free]))):  # pragma: no cover - guarded above
        return base
    fit = least_squares(
        residual,
        base[free],
        jac=jacobian,
        method="lm",
        x_scale="jac",
        ftol=1e-15,
        xtol=1e-15,
        gtol=1e-15,
        max_nfev=_LM_EVALUATIONS,
    )
    out = base.copy()
    out[free] = fit.x
    return out


def _chain(model: PinholeModel) -> list[PinholeModel]:
    """The nested models, simplest first, ending with ``model``."""
    chain = []
    fixed = model.fixed_principal_point
    if "k1" in model.distortion and (len(model.distortion) > 1 or model.tilted):
        chain.append(PinholeModel(("k1",), fixed_principal_point=fixed))
    if model.tilted and len(model.distortion) > 1:
        chain.append(PinholeModel(model.distortion, fixed_principal_point=fixed))
    chain.append(model)
    return chain


def calibrate_pinhole(
    observations: list[PlaneObservation],
    image_size: tuple[int, int],
    *,
    model: PinholeModel | None = None,
    focal_px: float | None = None,
    principal_point: tuple[float, float] | None = None,
) -> PinholeCalibration:
    """Fit an OpenCV pinhole camera to all calibration planes as one non-coplanar view.

    Parameters
    ----------
    observations : list of PlaneObservation
        Identified dots per traverse plane; the world points are (X, Y, Z_j).
    image_size : tuple of int
        (width, height) of the images, px.
    model : PinholeModel, optional
        Free parameters; default k1, k2, p1, p2 with free principal point and f_x, f_y.
    focal_px : float, optional
        Guess of the principal distance in pixels (focal length / pixel pitch); default
        from the DLT.
    principal_point : tuple of float, optional
        Guess of (c_x, c_y), px; default the image centre (where a model with
        ``fixed_principal_point`` keeps it).

    Returns
    -------
    PinholeCalibration
        The best of the polished starts (lowest reprojection RMS).
    """
    model = PinholeModel() if model is None else model
    if not observations:
        raise ValueError("need calibration planes, got none")
    obj, img = stack_planes(observations)
    if len(obj) < 12:
        raise ValueError(f"need at least 12 identified dots, got {len(obj)}")
    if np.ptp(obj[:, 2]) == 0:
        raise ValueError(
            "a pinhole fit from one view needs non-coplanar points: "
            f"all planes are at Z = {obj[0, 2]}"
        )
    width, height = image_size
    centre = ((width - 1) / 2.0, (height - 1) / 2.0)
    cx0, cy0 = centre if principal_point is None else principal_point

    dlt = _dlt(obj, img)
    if focal_px is None:
        if dlt is None:
            raise ValueError("the DLT failed; give a focal_px guess")
        focal_px = float(np.sqrt(abs(dlt[_FX] * dlt[_FY])))
    if not (np.isfinite(focal_px) and focal_px > 0):
        raise ValueError(f"focal_px must be > 0, got {focal_px!r}")
    k0 = np.array([[focal_px, 0.0, cx0], [0.0, focal_px, cy0], [0.0, 0.0, 1.0]])
    guess = _params(focal_px, focal_px, cx0, cy0, np.zeros(3), np.zeros(3))
    if dlt is not None and model.fixed_principal_point:
        dlt[[_CX, _CY]] = cx0, cy0  # the polish keeps the guess
    independent = {"dlt": dlt, "pnp": _pnp(obj, img, k0)}

    best_of_level: dict[str, np.ndarray] = {}
    results: dict[str, tuple[np.ndarray, float]] = {}
    for level in _chain(model):
        starts: dict[str, np.ndarray | None] = {
            "opencv": _opencv(obj, img, image_size, guess, level)
        }
        starts.update(independent)
        for name, previous in best_of_level.items():
            starts[f"nested {name}"] = previous
            starts[f"opencv from {name}"] = _opencv(obj, img, image_size, previous, level)
        results = {}
        for name, start in starts.items():
            if start is None or _rms(level.restrict(start), obj, img) == float("inf"):
                continue
            polished = polish(start, level, obj, img)
            results[name] = (polished, _rms(polished, obj, img))
            log.debug("pinhole %s, start %s: rms %.4g px", level.name, name, results[name][1])
        if not results:
            raise RuntimeError(f"every start of the pinhole fit ({level.name}) failed")
        winner = min(results, key=lambda n: results[n][1])
        best_of_level = {level.name: results[winner][0]}
        log.info("pinhole %s: best start %s, rms %.4g px", level.name, winner, results[winner][1])
    params, rms = results[winner]
    return PinholeCalibration(
        image_size=(int(width), int(height)),
        model=model,
        params=params,
        rms=rms,
        start=winner,
        start_rms={n: r for n, (_, r) in results.items()},
        n_points=len(obj),
    )
