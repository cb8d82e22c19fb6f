"""Fitting the full OpenCV pinhole (:mod:`ptv.calibration.pinhole`) to plate dots.

The fit (docs/calibration.md §5, §8):

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
"""

import logging

import cv2
import numpy as np
from scipy.linalg import rq
from scipy.optimize import least_squares

from ptv.calibration.observations import PlaneObservation, stack_planes
from ptv.calibration.pinhole import (
    CX,
    CY,
    FX,
    FY,
    N_PARAMS,
    RVEC,
    TAU_X,
    TAU_Y,
    TVEC,
    PinholeCalibration,
    PinholeModel,
    project_parameters,
)

log = logging.getLogger(__name__)

#: Evaluation cap of one Levenberg–Marquardt polish.
_LM_EVALUATIONS = 400


def _params(fx, fy, cx, cy, rvec, tvec, dist=None) -> np.ndarray:
    p = np.zeros(N_PARAMS)
    p[[FX, FY, CX, CY]] = fx, fy, cx, cy
    if dist is not None:
        d = np.ravel(dist)
        d = np.concatenate([d, np.zeros(14 - len(d))])
        p[[4, 5, 6, 7, 8]] = d[:5]
        p[[TAU_X, TAU_Y]] = d[12:14]
    p[RVEC] = np.ravel(rvec)
    p[TVEC] = np.ravel(tvec)
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
    cx, cy = start[CX], start[CY]
    if not (0 <= cx < width and 0 <= cy < height):
        # OpenCV: "Principal point must be within the image"; the scipy polish takes it.
        log.info("OpenCV start skipped: principal point (%.0f, %.0f) off the image", cx, cy)
        return None
    k0 = np.array([[start[FX], 0.0, cx], [0.0, start[FY], cy], [0.0, 0.0, 1.0]])
    d0 = np.zeros(14 if model.tilted else 5)
    d0[:5] = start[[4, 5, 6, 7, 8]]
    if model.tilted:
        d0[12:] = start[[TAU_X, TAU_Y]]
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

    Examples
    --------
    The dots of a known camera (a Tsai camera turned 20° about Y, no distortion) on
    three planes:

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
    >>> fit = ptv.calibrate_pinhole(planes, (640, 480), focal_px=5000.0)
    >>> bool(fit.rms < 1e-6)  # px
    True
    >>> k = fit.camera_matrix
    >>> k[[0, 1, 0, 1], [0, 1, 2, 2]].round(6)  # f_x, f_y and the principal point, px
    array([5000. , 5000. ,  319.5,  239.5])
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
        focal_px = float(np.sqrt(abs(dlt[FX] * dlt[FY])))
    if not (np.isfinite(focal_px) and focal_px > 0):
        raise ValueError(f"focal_px must be > 0, got {focal_px!r}")
    k0 = np.array([[focal_px, 0.0, cx0], [0.0, focal_px, cy0], [0.0, 0.0, 1.0]])
    guess = _params(focal_px, focal_px, cx0, cy0, np.zeros(3), np.zeros(3))
    if dlt is not None and model.fixed_principal_point:
        dlt[[CX, CY]] = cx0, cy0  # the polish keeps the guess
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
