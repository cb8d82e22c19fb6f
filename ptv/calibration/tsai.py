"""The classic Tsai (1987) camera model: the baseline the paper's calibration beats.

Model (docs/calibration.md §4), world point P (m) to pixel:

1. Camera coordinates (x, y, z) = R P + T; z is the depth along the optical axis.
2. Undistorted image: X_u = f x/z, Y_u = f y/z (m on the sensor).
3. Radial distortion goes distorted → undistorted: X_u = X_d (1 + κ₁ ρ_d²),
   Y_u = Y_d (1 + κ₁ ρ_d²), ρ_d² = X_d² + Y_d².
4. Pixels: X_f = s_x X_d/d′_x + C_x, Y_f = Y_d/d_y + C_y.

Parameters: R (3 angles), T, f, κ₁, s_x, with (C_x, C_y) fixed at the sensor centre (9);
optionally the centre is free too (11). The pixel pitches d′_x, d_y are nominal values
from the camera data sheet.

Fitting, as a careful experimentalist would: all traverse planes together form one
non-coplanar rig of world points (X, Y, Z_j).

* Stage 1: the radial alignment constraint (RAC), a linear least-squares problem in
  seven unknowns (s_x r₁:₃, s_x T_x, r₄:₆)/T_y, gives R, T_x, T_y and s_x. The sign of
  T_y comes from the requirement that (x, y) and (X_d, Y_d) point the same way (a vote
  over all points, dominated by those far from the centre, generalising Tsai's single
  far point). R is re-orthonormalised by SVD.
* The RAC divides by T_y, which is ill-conditioned when the world origin lies near the
  camera's y = 0 plane (docs/calibration.md §4; in a rig whose cameras sit in the XZ
  plane and look at the plate centre it lies exactly there). A scale-free version of the
  same equations first locates that plane, and the fit runs in an internal world frame
  shifted well away from it; the results are reported in the user's frame.
* Stage 2: with κ₁ = 0, f and T_z by linear least squares from
  f y_i − Y_d,i T_z = w_i Y_d,i (and the same for x), w_i = r₇:₉ · P_i.
* Where the linear stages fail (stage 2 finds no positive f even after Tsai's sign fix:
  the images are far from a pinhole's, e.g. through a window 35° off its normal in two
  directions at once), the start comes instead from a direct linear transform: the
  3 × 4 projective matrix by SVD on normalised coordinates, split into K [R | T] by an
  RQ decomposition (f = K₂₂, s_x = K₁₁/K₂₂).
* Levenberg–Marquardt (``scipy.optimize.least_squares``, ``method='lm'``) on all pixel
  reprojection errors: first f, T_z, κ₁ (Tsai's own nonlinear step), then every
  parameter, the rotation as a rotation vector. When it diverges from the linear
  stages' start (f or s_x ≤ 0, points behind the camera or past the distortion fold, as
  on an oblique Scheimpflug camera whose linear start is poor) or ends in a local
  minimum far above any model error, it starts again from the DLT and keeps the better
  fit; only when both diverge is the camera refused.

The model knows no refraction: a pixel's ray is a straight line from the camera centre
through the water. That is the model error the paper measures against the model-free
pixel → line calibration.
"""

import logging
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.linalg import rq
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from ptv.calibration.observations import PlaneObservation, stack_planes
from ptv.rays import Rays

log = logging.getLogger(__name__)

#: Fewest points stage 1 (seven unknowns) accepts.
MIN_POINTS = 7
#: Below this ratio of the smallest to the largest spread of the world points they count
#: as coplanar.
_COPLANAR_TOL = 1e-6
#: κ₁ ρ_u² below this has no distorted image (the distortion folds back).
_FOLD = -4.0 / 27.0
#: Newton steps and relative tolerance of the distortion inversion.
_NEWTON_STEPS = 60
_NEWTON_TOL = 1e-15
#: Step of the central-difference Jacobian, in normalised parameter units (about 1e-4 px).
_JAC_STEP = 1e-4
#: A fit ending above this reprojection RMS has not found the camera: it is tried again
#: from the DLT start. The model error of straight rays through our rigs' oblique windows
#: is 1-7 px; a fit lost in a local minimum ends at hundreds.
_LOST_RMS_PX = 20.0
#: Residual given to points that cannot be imaged at some trial parameters, px.
_UNIMAGED_RESIDUAL = 1e6


@dataclass(frozen=True, eq=False)
class TsaiCalibration:
    """A Tsai camera: pinhole in the water with one radial distortion term.

    Attributes
    ----------
    rotation : ndarray, shape (3, 3)
        R, world → camera (proper rotation).
    translation : ndarray, shape (3,)
        T, m: camera coordinates are R P + T.
    focal_length : float
        Effective focal length f (principal distance), m.
    kappa1 : float
        Radial distortion κ₁, m⁻² (distorted → undistorted, on the sensor).
    sx : float
        Horizontal uncertainty scale factor s_x.
    principal_point : tuple of float
        (C_x, C_y), px.
    pixel_size : tuple of float
        (d′_x, d_y), m: nominal pixel pitches.
    reprojection_rms : float
        RMS of the fit's pixel residuals per image coordinate, px (equals σ for
        isotropic dot-centre noise of σ px per coordinate); NaN if not fitted.
    n_points : int
        Number of calibration points fitted (0 if not fitted).
    free_principal_point : bool
        Whether (C_x, C_y) were fitted (11 parameters) or fixed (9).

    Examples
    --------
    A camera of known parameters: 0.5 m from the origin, turned 20° about Y, a 50 mm
    lens on 10 µm pixels, no distortion. The origin is imaged at the principal point,
    and the ray of a pixel passes through the point it images:

    >>> import numpy as np
    >>> import ptv
    >>> from scipy.spatial.transform import Rotation
    >>> turn = Rotation.from_euler("y", 20, degrees=True).as_matrix()
    >>> camera = ptv.TsaiCalibration(turn, [0, 0, 0.5], focal_length=0.05, kappa1=0.0,
    ...                              sx=1.0, principal_point=(319.5, 239.5),
    ...                              pixel_size=(1e-5, 1e-5))
    >>> camera.camera_centre.round(6)  # m
    array([ 0.17101 ,  0.      , -0.469846])
    >>> points = np.array([[0.0, 0.0, 0.0], [1e-3, 0.0, 0.0]])  # m
    >>> camera.project(points).round(3)  # px
    array([[319.5  , 239.5  ],
           [328.903, 239.5  ]])
    >>> rays = camera.pixel_to_ray(camera.project(points))
    >>> along = np.sum((points - rays.origins) * rays.directions, axis=1, keepdims=True)
    >>> bool(np.allclose(rays.origins + along * rays.directions, points, atol=1e-12))
    True
    """

    rotation: np.ndarray
    translation: np.ndarray
    focal_length: float
    kappa1: float
    sx: float
    principal_point: tuple[float, float]
    pixel_size: tuple[float, float]
    reprojection_rms: float = float("nan")
    n_points: int = 0
    free_principal_point: bool = False

    def __post_init__(self) -> None:
        rot = np.asarray(self.rotation, dtype=float)
        if rot.shape != (3, 3) or not np.allclose(rot @ rot.T, np.eye(3), atol=1e-9):
            raise ValueError(f"rotation must be an orthonormal 3×3 matrix, got {rot!r}")
        if np.linalg.det(rot) < 0:
            raise ValueError("rotation must be proper (det +1), got a reflection")
        t = np.asarray(self.translation, dtype=float)
        if t.shape != (3,) or not np.isfinite(t).all():
            raise ValueError(f"translation must be 3 finite values, got {self.translation!r}")
        for name in ("focal_length", "sx"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be finite and > 0, got {value!r}")
        if not np.isfinite(self.kappa1):
            raise ValueError(f"kappa1 must be finite, got {self.kappa1!r}")
        pitch = _pitches(self.pixel_size)
        centre = np.asarray(self.principal_point, dtype=float)
        if centre.shape != (2,) or not np.isfinite(centre).all():
            raise ValueError(f"principal_point must be 2 finite values, got {centre!r}")
        object.__setattr__(self, "rotation", rot)
        object.__setattr__(self, "translation", t)
        object.__setattr__(self, "focal_length", float(self.focal_length))
        object.__setattr__(self, "kappa1", float(self.kappa1))
        object.__setattr__(self, "sx", float(self.sx))
        object.__setattr__(self, "principal_point", (float(centre[0]), float(centre[1])))
        object.__setattr__(self, "pixel_size", (float(pitch[0]), float(pitch[1])))

    # -- derived ------------------------------------------------------------------
    @property
    def rotation_vector(self) -> np.ndarray:
        """R as a rotation vector (axis × angle, rad), shape (3,)."""
        return Rotation.from_matrix(self.rotation).as_rotvec()

    @property
    def camera_centre(self) -> np.ndarray:
        """Projection centre −Rᵀ T in the world, m, shape (3,)."""
        return -self.rotation.T @ self.translation

    @property
    def parameters(self) -> dict[str, float]:
        """The fitted parameters by name (SI units; rotation vector in rad; centre in px)."""
        rv = self.rotation_vector
        out = {f"rotvec_{a}": float(v) for a, v in zip("xyz", rv, strict=True)}
        out |= {f"T_{a}": float(v) for a, v in zip("xyz", self.translation, strict=True)}
        out |= {"f": self.focal_length, "kappa1": self.kappa1, "sx": self.sx}
        out |= {"C_x": self.principal_point[0], "C_y": self.principal_point[1]}
        return out

    # -- the camera protocol ------------------------------------------------------
    def pixel_to_ray(self, xy: np.ndarray) -> Rays:
        """Straight rays from the camera centre through pixels xy (N, 2).

        Rows are NaN for NaN pixels and where 1 + κ₁ ρ_d² ≤ 0 (no ray).
        """
        xy = np.asarray(xy, dtype=float)
        if xy.ndim != 2 or xy.shape[1] != 2:
            raise ValueError(f"pixels must have shape (N, 2), got {xy.shape}")
        xd, yd = _pixels_to_sensor(xy, self.principal_point, self.pixel_size, self.sx)
        factor = 1.0 + self.kappa1 * (xd**2 + yd**2)
        cam = np.column_stack([xd * factor, yd * factor, np.full(len(xy), self.focal_length)])
        directions = cam @ self.rotation  # Rᵀ d for each row
        directions /= np.linalg.norm(directions, axis=1, keepdims=True)
        origins = np.broadcast_to(self.camera_centre, directions.shape).copy()
        bad = ~(np.isfinite(directions).all(axis=1) & (factor > 0))
        origins[bad] = np.nan
        directions[bad] = np.nan
        return Rays(origins, directions)

    def project(self, points: np.ndarray) -> np.ndarray:
        """Pixels (N, 2) of world points (N, 3), m.

        NaN for points on or behind the camera's z = 0 plane and where the distortion
        folds back (no distorted image). The model is analytic: pixels outside the
        sensor are returned as they are.
        """
        points = np.asarray(points, dtype=float)
        if points.ndim != 2 or points.shape[1] != 3:
            raise ValueError(f"points must have shape (N, 3), got {points.shape}")
        return _project(
            self.rotation,
            self.translation,
            self.focal_length,
            self.kappa1,
            self.sx,
            self.principal_point,
            self.pixel_size,
            points,
        )


# -- the forward model ------------------------------------------------------------------
def _pitches(pixel_pitch: float | Sequence[float]) -> np.ndarray:
    pitch = np.broadcast_to(np.asarray(pixel_pitch, dtype=float), (2,)).copy()
    if not (np.isfinite(pitch).all() and (pitch > 0).all()):
        raise ValueError(f"pixel pitch must be finite and > 0 (m), got {pixel_pitch!r}")
    return pitch


def _pixels_to_sensor(xy, centre, pitch, sx):
    """Distorted sensor coordinates (X_d, Y_d), m."""
    xd = (xy[:, 0] - centre[0]) * pitch[0] / sx
    yd = (xy[:, 1] - centre[1]) * pitch[1]
    return xd, yd


def distortion_scale(c: np.ndarray) -> np.ndarray:
    """The root s of c s³ + s − 1 = 0 that continues s = 1 at c = 0 (X_d = s X_u).

    With c = κ₁ ρ_u², s is the factor that takes undistorted to distorted sensor
    coordinates. Newton from s = 1 converges monotonically (g = c s³ + s is convex and
    increasing for c ≥ 0; concave and increasing up to the root for −4/27 ≤ c < 0).
    NaN where c < −4/27: the distortion folds back and no distorted point exists.
    """
    c = np.asarray(c, dtype=float)
    ok = np.isfinite(c) & (c >= _FOLD)
    cc = np.where(ok, c, 0.0)
    s = np.ones_like(cc)
    for _ in range(_NEWTON_STEPS):
        g = cc * s**3 + s - 1.0
        step = g / (3.0 * cc * s**2 + 1.0)
        s = s - step
        if np.max(np.abs(step), initial=0.0) <= _NEWTON_TOL:
            break
    return np.where(ok, s, np.nan)


def _project(rotation, translation, f, kappa1, sx, centre, pitch, points):
    cam = points @ rotation.T + translation
    z = cam[:, 2]
    in_front = z > 0
    z = np.where(in_front, z, np.nan)
    xu = f * cam[:, 0] / z
    yu = f * cam[:, 1] / z
    s = distortion_scale(kappa1 * (xu**2 + yu**2))
    xf = sx * s * xu / pitch[0] + centre[0]
    yf = s * yu / pitch[1] + centre[1]
    return np.column_stack([xf, yf])


# -- fitting ------------------------------------------------------------------------------
def _check_inputs(world: np.ndarray, pixels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    world = np.asarray(world, dtype=float)
    pixels = np.asarray(pixels, dtype=float)
    if world.ndim != 2 or world.shape[1] != 3:
        raise ValueError(f"world points must have shape (N, 3), got {world.shape}")
    if pixels.shape != (len(world), 2):
        raise ValueError(
            f"pixels must have shape (N, 2) matching {len(world)} world points, got {pixels.shape}"
        )
    bad = ~(np.isfinite(world).all(axis=1) & np.isfinite(pixels).all(axis=1))
    if bad.any():
        raise ValueError(
            f"calibration points contain NaN or inf: {bad.sum()} of {len(world)} "
            f"(first at row {int(np.argmax(bad))}); drop unseen dots before fitting"
        )
    if len(world) < MIN_POINTS:
        raise ValueError(f"Tsai's stage 1 needs at least {MIN_POINTS} points, got {len(world)}")
    spread = np.linalg.svd(world - world.mean(axis=0), compute_uv=False)
    if spread[0] == 0 or spread[2] < _COPLANAR_TOL * spread[0]:
        raise ValueError(
            "the world points are coplanar (or collinear): the non-coplanar Tsai "
            "calibration needs points on at least two planes Z_j; spreads "
            f"{spread.tolist()} m·√N"
        )
    return world, pixels


def _rac_homogeneous(world, xd_s, yd):
    """Scale-free RAC: v ∝ (s_x r₁:₃, s_x T_x, r₄:₆, T_y), from the smallest singular vector."""
    centroid = world.mean(axis=0)
    length = np.sqrt(np.mean(np.sum((world - centroid) ** 2, axis=1)))
    p = (world - centroid) / length
    scale = np.sqrt(np.mean(xd_s**2 + yd**2))
    x, y = xd_s / scale, yd / scale
    m = np.column_stack([y[:, None] * p, y, -x[:, None] * p, -x])
    v = np.linalg.svd(m, full_matrices=False)[2][-1]
    r_hat = v[4:7] / np.linalg.norm(v[4:7])
    # camera y ∝ r₄:₆·(P − centroid)/length + v₈  ⇒  T_y (centroid frame) ∝ v₈ length/|v₅:₇|
    ty = v[7] * length / np.linalg.norm(v[4:7])
    return centroid, length, r_hat, ty


def _internal_origin(world, xd_s, yd):
    """World point W0 to use as the internal origin: well away from the camera's y = 0 plane."""
    centroid, length, r_hat, ty = _rac_homogeneous(world, xd_s, yd)
    margin = 2.0 * length
    if abs(ty) >= margin:
        return centroid
    # With W0 = centroid + α r̂, y_cam = r̂·(P − W0) + (ty + α): make |T_y| = margin.
    alpha = np.copysign(margin, ty if ty != 0 else 1.0) - ty
    return centroid + alpha * r_hat


def _stage1(world, xd_s, yd):
    """Tsai's RAC linear least squares (non-coplanar): R, T_x, T_y, s_x."""
    m = np.column_stack([yd[:, None] * world, yd, -xd_s[:, None] * world])
    norms = np.linalg.norm(m, axis=0)
    a = np.linalg.lstsq(m / norms, xd_s, rcond=None)[0] / norms
    ty = 1.0 / np.linalg.norm(a[4:7])
    sx = ty * np.linalg.norm(a[0:3])
    # Sign of T_y: (x, y) must point the way (X_d, Y_d) do; far points dominate the vote.
    x = (world @ a[0:3] + a[3]) * ty
    y = (world @ a[4:7] + 1.0) * ty
    if np.sum(x * xd_s + y * yd) < 0:
        ty = -ty
    r1 = a[0:3] * ty / sx
    r2 = a[4:7] * ty
    tx = a[3] * ty / sx
    rot = np.vstack([r1, r2, np.cross(r1, r2)])
    u, _, vt = np.linalg.svd(rot)  # det(rot) = |r₁ × r₂|² > 0, so U Vᵀ is proper
    return u @ vt, tx, ty, sx


def _stage2(world, xd, yd, rot, tx, ty):
    """f and T_z by linear least squares with κ₁ = 0, from both image coordinates."""
    x = world @ rot[0] + tx
    y = world @ rot[1] + ty
    w = world @ rot[2]
    m = np.vstack([np.column_stack([y, -yd]), np.column_stack([x, -xd])])
    rhs = np.concatenate([w * yd, w * xd])
    f, tz = np.linalg.lstsq(m, rhs, rcond=None)[0]
    return f, tz


@dataclass(frozen=True)
class _Packing:
    """Normalised LM parameters u: p = p0 + scale·u, one unit ≈ one pixel of effect."""

    p0: np.ndarray
    scale: np.ndarray
    free: np.ndarray

    def unpack(self, u: np.ndarray) -> np.ndarray:
        p = self.p0.copy()
        p[self.free] += self.scale[self.free] * u
        return p


def _residuals_fn(world, pixels, pitch, packing: _Packing):
    def residuals(u):
        p = packing.unpack(u)
        rot = Rotation.from_rotvec(p[0:3]).as_matrix()
        xy = _project(rot, p[3:6], p[6], p[7], p[8], p[9:11], pitch, world)
        r = (xy - pixels).ravel()
        return np.where(np.isfinite(r), r, _UNIMAGED_RESIDUAL)

    def jacobian(u):
        cols = []
        for k in range(len(u)):
            du = np.zeros_like(u)
            du[k] = _JAC_STEP
            cols.append((residuals(u + du) - residuals(u - du)) / (2 * _JAC_STEP))
        return np.column_stack(cols)

    return residuals, jacobian


def _levenberg_marquardt(world, pixels, pitch, p0, scale, free):
    packing = _Packing(p0=p0, scale=scale, free=free)
    fun, jac = _residuals_fn(world, pixels, pitch, packing)
    result = least_squares(
        fun,
        np.zeros(int(free.sum())),
        jac=jac,
        method="lm",
        ftol=1e-14,
        xtol=1e-14,
        gtol=1e-14,
        max_nfev=2000,
    )
    if result.status <= 0:
        log.warning("Tsai LM did not converge: %s", result.message)
    return packing.unpack(result.x), result


def _normalising(points: np.ndarray) -> np.ndarray:
    """Similarity (D+1, D+1) moving ``points`` (N, D) to their centroid, mean norm √D."""
    centroid = points.mean(axis=0)
    scale = np.sqrt(points.shape[1]) / np.mean(np.linalg.norm(points - centroid, axis=1))
    t = np.eye(points.shape[1] + 1)
    t[:-1, :-1] *= scale
    t[:-1, -1] = -scale * centroid
    return t


def _dlt_start(local: np.ndarray, xd_s: np.ndarray, yd: np.ndarray) -> tuple:
    """(R, T_x, T_y, T_z, f, s_x) from a direct linear transform (module docstring)."""
    image = np.column_stack([xd_s, yd])
    t_world, t_image = _normalising(local), _normalising(image)
    p = np.column_stack([local, np.ones(len(local))]) @ t_world.T
    q = np.column_stack([image, np.ones(len(image))]) @ t_image.T
    zeros = np.zeros_like(p)
    rows = np.vstack(
        [
            np.hstack([p, zeros, -q[:, :1] * p]),
            np.hstack([zeros, p, -q[:, 1:2] * p]),
        ]
    )
    projection = np.linalg.inv(t_image) @ np.linalg.svd(rows)[2][-1].reshape(3, 4) @ t_world
    k, rot = rq(projection[:, :3])
    signs = np.diag(np.sign(np.diag(k)))  # K with a positive diagonal
    k, rot = k @ signs, signs @ rot
    translation = np.linalg.solve(k, projection[:, 3])
    if np.linalg.det(rot) < 0:  # P is known up to sign: the one with a proper rotation
        rot, translation = -rot, -translation
    k = k / k[2, 2]
    return rot, *translation, k[1, 1], k[0, 0] / k[1, 1]


def _linear_stages(local: np.ndarray, xd_s: np.ndarray, yd: np.ndarray) -> tuple:
    """Tsai's stages 1 and 2 in the internal frame: (R, T_x, T_y, T_z, f, s_x), with
    Tsai's sign fix when stage 2 finds f < 0, and a DLT start when that fails too."""
    rot, tx, ty, sx = _stage1(local, xd_s, yd)
    xd = xd_s / sx
    f, tz = _stage2(local, xd, yd, rot, tx, ty)
    if f < 0:
        # Tsai's sign fix: flip r₃, r₆, r₇, r₈ (R → D R D, D = diag(1, 1, −1)) and redo.
        d = np.diag([1.0, 1.0, -1.0])
        rot = d @ rot @ d
        f, tz = _stage2(local, xd, yd, rot, tx, ty)
    if not f > 0:
        rot, tx, ty, tz, f, sx = _dlt_start(local, xd_s, yd)
        log.warning(
            "Tsai stage 2 found no positive focal length (the images are far from a "
            "pinhole's): starting from a direct linear transform, f = %.4g m",
            f,
        )
    if not (f > 0 and tz > 0):
        raise ValueError(
            f"Tsai: no start with the points in front of the camera (f = {f:.3g} m, "
            f"T_z = {tz:.3g} m): the pixels do not look like a camera image of the points "
            "(mirrored image?)"
        )
    log.info(
        "Tsai stages 1-2: f = %.5g m, T = (%.4g, %.4g, %.4g) m (internal frame), s_x = %.5f",
        f,
        tx,
        ty,
        tz,
        sx,
    )
    return rot, tx, ty, tz, f, sx


def _refined(local, pixels, pitch, centre, start, free_principal_point):
    """Levenberg–Marquardt from a start (R, T_x, T_y, T_z, f, s_x) in the internal frame:
    first Tsai's own step (T_z, f, κ₁), then every parameter, in pixel-effect units (one
    unit ≈ one pixel at the image edge). Returns (p, result), p None when the fit
    diverged (f or s_x ≤ 0, or points left unimaged)."""
    rot, tx, ty, tz, f, sx = start
    cam = local @ rot.T + np.array([tx, ty, tz])
    depth = float(np.mean(cam[:, 2]))
    if depth <= 0 or not f > 0:
        raise ValueError("Tsai's start puts the calibration points behind the camera")
    rho_px = max(float(np.max(np.hypot(*(pixels - centre).T))), 1.0)
    rho_m = rho_px * float(pitch.mean())
    f_px = f / float(pitch.mean())
    p0 = np.concatenate([Rotation.from_matrix(rot).as_rotvec(), [tx, ty, tz, f, 0.0, sx], centre])
    scale = np.array(
        [1 / f_px] * 3
        + [depth / f_px] * 2
        + [depth / rho_px, f / rho_px, 1 / (rho_m**2 * rho_px), 1 / rho_px, 1.0, 1.0]
    )
    tsai_step = np.zeros(11, dtype=bool)
    tsai_step[[5, 6, 7]] = True  # T_z, f, κ₁: Tsai's nonlinear step
    p, _ = _levenberg_marquardt(local, pixels, pitch, p0, scale, tsai_step)
    everything = np.ones(11, dtype=bool)
    everything[9:11] = free_principal_point
    p, result = _levenberg_marquardt(local, pixels, pitch, p, scale, everything)
    if p[6] <= 0 or p[8] <= 0 or np.any(np.abs(result.fun) >= _UNIMAGED_RESIDUAL):
        return None, result
    return p, result


def fit_tsai(
    world: np.ndarray,
    pixels: np.ndarray,
    *,
    pixel_pitch: float | Sequence[float],
    sensor_size: tuple[int, int],
    free_principal_point: bool = False,
) -> TsaiCalibration:
    """Fit the classic Tsai model to non-coplanar calibration points of one camera.

    Parameters
    ----------
    world : ndarray, shape (N, 3)
        Calibration points (X, Y, Z), m, not all on one plane; N ≥ 7.
    pixels : ndarray, shape (N, 2)
        Their image positions, px (x = column, y = row, OpenCV convention).
    pixel_pitch : float or (float, float)
        Nominal pixel pitch (d′_x, d_y) from the camera data sheet, m.
    sensor_size : tuple of int
        (width, height), px; the principal point is fixed at (or, when free,
        starts from) the sensor centre ((width − 1)/2, (height − 1)/2).
    free_principal_point : bool
        Fit (C_x, C_y) too (11 parameters instead of 9).

    Returns
    -------
    TsaiCalibration

    Raises
    ------
    ValueError
        Fewer than seven points, coplanar points, NaNs, mismatched shapes, a bad pitch
        or sensor size, or a fit that finds the camera looking away from the points.
    """
    world, pixels = _check_inputs(world, pixels)
    pitch = _pitches(pixel_pitch)
    width, height = sensor_size
    if not (int(width) == width and int(height) == height and width > 0 and height > 0):
        raise ValueError(f"sensor_size must be two positive integers (px), got {sensor_size!r}")
    centre = np.array([(width - 1) / 2.0, (height - 1) / 2.0])

    # Stage 1 and 2 in an internal frame whose origin is away from the camera's y = 0 plane.
    xd_s, yd = _pixels_to_sensor(pixels, centre, pitch, 1.0)  # X'_d = s_x X_d, Y_d
    origin = _internal_origin(world, xd_s, yd)
    local = world - origin
    rot, tx, ty, tz, f, sx = _linear_stages(local, xd_s, yd)

    start = (rot, tx, ty, tz, f, sx)
    p, result = _refined(local, pixels, pitch, centre, start, free_principal_point)
    rms = float(np.sqrt(np.mean(result.fun**2)))
    if p is None or rms > _LOST_RMS_PX:
        # A start from the linear stages that Levenberg–Marquardt cannot bring home (a
        # camera far from a pinhole's); a careful experimentalist starts again from a DLT
        # and keeps the better fit.
        log.warning(
            "Tsai LM %s from the linear stages' start: starting from a DLT",
            "diverged" if p is None else f"ended at {rms:.3g} px RMS",
        )
        p_dlt, result_dlt = _refined(
            local, pixels, pitch, centre, _dlt_start(local, xd_s, yd), free_principal_point
        )
        rms_dlt = float(np.sqrt(np.mean(result_dlt.fun**2)))
        if p_dlt is not None and (p is None or rms_dlt < rms):
            p, rms = p_dlt, rms_dlt
    if p is None:
        raise ValueError(
            f"Tsai LM diverged from the linear stages' start and from a DLT start (RMS "
            f"{rms:.3g} px): some calibration points fell behind the camera or past the "
            "distortion fold"
        )
    rot = Rotation.from_rotvec(p[0:3]).as_matrix()
    translation = p[3:6] - rot @ origin  # R (P − W0) + T' = R P + (T' − R W0)
    log.info("Tsai fit: %d points, RMS %.3g px per coordinate", len(world), rms)
    return TsaiCalibration(
        rotation=rot,
        translation=translation,
        focal_length=p[6],
        kappa1=p[7],
        sx=p[8],
        principal_point=(p[9], p[10]),
        pixel_size=(pitch[0], pitch[1]),
        reprojection_rms=rms,
        n_points=len(world),
        free_principal_point=free_principal_point,
    )


def calibrate_tsai(
    observations: Sequence[PlaneObservation],
    *,
    pixel_pitch: float | Sequence[float],
    sensor_size: tuple[int, int],
    free_principal_point: bool = False,
) -> TsaiCalibration:
    """Fit the Tsai model to a traverse: every plane's dots at (X, Y, Z_j) as one rig.

    Parameters
    ----------
    observations : sequence of PlaneObservation
        The identified dots of each plane (at least two distinct Z_j).
    pixel_pitch, sensor_size, free_principal_point
        As in :func:`fit_tsai`.

    Returns
    -------
    TsaiCalibration

    Examples
    --------
    The dots of a known Tsai camera (turned 20° about Y) on three planes give it back:

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
    >>> fit = ptv.calibrate_tsai(planes, pixel_pitch=1e-5, sensor_size=(640, 480))
    >>> round(fit.focal_length * 1e3, 6), bool(fit.reprojection_rms < 1e-6)  # mm, px
    (50.0, True)
    >>> bool(np.allclose(fit.camera_centre, truth.camera_centre, atol=1e-9))  # m
    True
    """
    world, pixels = stack_planes(observations)
    return fit_tsai(
        world,
        pixels,
        pixel_pitch=pixel_pitch,
        sensor_size=sensor_size,
        free_principal_point=free_principal_point,
    )
