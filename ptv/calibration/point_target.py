"""One camera calibrated from one image of a 3-D target whose points are listed.

A stepped target (dots on two or more levels, as MyPTV's and OpenPTV's examples use)
gives a non-coplanar set of known points in a single image, enough for a pinhole camera
(:mod:`ptv.calibration.pinhole`). The points come as a text file (X Y Z, or id X Y Z,
one per line); which dot is which is fixed by a few **seed points**, target points a
user located on the image (OpenPTV's manual orientation, MyPTV's ``manualPoints``).

Steps of :func:`calibrate_point_target`:

1. **Dots.** :func:`ptv.calibration.blobs.find_blobs` on the image: every dot-like
   blob, specks and reflections included (they are sorted out in step 3).
2. **Seed camera.** From the seeds (four or more): a pinhole with square pixels, the
   principal point at the image centre and no distortion. Its pose is solved by
   ``cv2.solvePnP`` (SQPnP) for principal distances on a log grid of 320 px to 16 image
   widths (and the nominal one when the data sheet gives it); the best few are polished
   by Levenberg–Marquardt over the principal distance and the pose. Seeds that this
   camera cannot fit within :data:`SEED_TOLERANCE_PX` are refused (a wrong point or a
   mistyped pixel), naming the worst.
3. **Association.** Every target point is projected; it takes the nearest blob within
   the tolerance, and that blob must have no nearer projected point (mutual nearest:
   a blob serves one point).
4. **Fit.** :func:`ptv.calibration.pinhole_fit.calibrate_pinhole` on the associated pairs,
   with the model the target asks for (by default k1, k2, p1, p2 with free principal
   point and focal lengths), started from the previous camera's principal distance.
5. **Iterate** 3–4 until the associated set no longer changes. The tolerance starts at
   :data:`START_TOLERANCE` times the median spacing of the projected points (the seed
   camera errs far from the seeds) and shrinks after each fit to
   max(:data:`MIN_TOLERANCE_PX`, :data:`RESIDUAL_FACTOR` × the median residual), which
   drops the blobs that stood in for a hidden dot.

6. **Window** (when the camera has one): steps 3–4 again with the pinhole behind the
   flat glass wall (:mod:`ptv.calibration.refractive_pinhole`), started from the
   straight-ray fit.

Without a window the camera is a straight-ray pinhole. Behind a flat window into water
(air, glass, water) the rays bend; its distortion terms absorb part of that near the
target, but it errs away from it (docs/calibration.md §9).
"""

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
from scipy.optimize import least_squares
from scipy.spatial import cKDTree

from ptv.calibration.blobs import find_blobs
from ptv.calibration.observations import PlaneObservation
from ptv.calibration.pinhole import PinholeCalibration, PinholeModel, project_parameters
from ptv.calibration.pinhole_fit import calibrate_pinhole
from ptv.calibration.refractive_pinhole import (
    FlatWindow,
    RefractivePinholeCalibration,
    fit_refractive_pinhole,
)
from ptv.camera_model import on_image

__all__ = [
    "PointTarget",
    "PointTargetFit",
    "associate",
    "calibrate_point_target",
    "read_target_points",
    "seed_camera",
]

#: Units a target file may be written in, and their length in m.
UNITS = {"m": 1.0, "mm": 1e-3}
#: Fewest target points, and fewest associated points a fit needs.
MIN_POINTS = 12
#: Fewest seed points per image.
MIN_SEEDS = 4
#: Largest seed residual of the seed camera, px: a seed further off is a mistake.
SEED_TOLERANCE_PX = 15.0
#: First association tolerance, as a fraction of the projected points' spacing.
START_TOLERANCE = 0.4
#: The tolerance after a fit: this many median residuals ...
RESIDUAL_FACTOR = 5.0
#: ... but never below this, px.
MIN_TOLERANCE_PX = 1.0
#: Fits at most.
MAX_ITERATIONS = 15
#: Principal distances tried for the seed camera: this range times the image width, px.
_FOCAL_GRID = (0.25, 16.0, 31)
#: Candidates of the focal grid polished.
_POLISHED_STARTS = 3
#: The seed camera's principal distance, pose: indices in the full parameter vector.
_SEED_FREE = np.array([0, 11, 12, 13, 14, 15, 16])


@dataclass(frozen=True, eq=False)
class PointTarget:
    """A calibration target of known 3-D points, and how a camera is fitted to it.

    Attributes
    ----------
    points : ndarray, shape (N, 3)
        The points, m, in the target's frame (the frame of the calibration).
    ids : ndarray of int, shape (N,)
        Their numbers in the target file (its first column, else 0 … N − 1).
    dots : {"bright", "dark"}
        Bright dots on a dark target, or dark on bright.
    min_dot_area : int
        Blobs of fewer pixels above the threshold are specks, px.
    model : PinholeModel
        The pinhole fitted (its distortion terms; principal point free or fixed at the
        image centre).
    units : {"m", "mm"}
        Units of the target file, which seed points are given in too.
    source : str
        The target file, for messages.
    """

    points: np.ndarray
    ids: np.ndarray
    dots: str = "bright"
    min_dot_area: int = 4
    model: PinholeModel = field(default_factory=PinholeModel)
    units: str = "m"
    source: str = "target"

    def __post_init__(self) -> None:
        points = np.asarray(self.points, dtype=float)
        if points.ndim != 2 or points.shape[1] != 3 or len(points) < MIN_POINTS:
            raise ValueError(
                f"{self.source}: a point target needs at least {MIN_POINTS} points (N, 3), "
                f"got shape {points.shape}"
            )
        if not np.isfinite(points).all():
            raise ValueError(f"{self.source}: target points must be finite")
        spread = np.linalg.svd(points - points.mean(axis=0), compute_uv=False)
        if spread[2] <= 1e-9 * spread[0]:
            raise ValueError(
                f"{self.source}: all target points lie in one plane; a single image of a "
                "plane cannot calibrate a pinhole (image it at several traverse positions "
                "and describe it as a plate)"
            )
        if self.units not in UNITS:
            raise ValueError(
                f"{self.source}: units must be one of {', '.join(UNITS)}, got {self.units!r}"
            )
        if self.dots not in ("bright", "dark"):
            raise ValueError(f"{self.source}: dots must be 'bright' or 'dark', got {self.dots!r}")
        if isinstance(self.min_dot_area, bool) or not (
            isinstance(self.min_dot_area, int) and self.min_dot_area >= 1
        ):
            raise ValueError(
                f"{self.source}: min_dot_area must be an integer >= 1 (px), got "
                f"{self.min_dot_area!r}"
            )
        object.__setattr__(self, "points", points)
        object.__setattr__(self, "ids", np.asarray(self.ids, dtype=np.int64))

    def __len__(self) -> int:
        return len(self.points)

    def row_of(self, xyz: np.ndarray, tolerance: float = 1e-6) -> int | None:
        """The row of the target point at ``xyz`` (3,), m, to within ``tolerance`` m,
        or None."""
        d = np.linalg.norm(self.points - np.asarray(xyz, dtype=float), axis=1)
        row = int(np.argmin(d))
        return row if d[row] <= tolerance else None

    @classmethod
    def from_dict(cls, spec: Mapping, folder: Path, *, source: str) -> "PointTarget":
        """The ``target`` of experiment.json for a point target (schema-checked).

        Fields: ``points`` (the file, relative to ``folder``), ``units`` (of its
        coordinates: "m" or "mm"), optional ``dots``, ``min_dot_area`` (px, default 4),
        ``distortion`` (terms of ``DISTORTION_TERMS``, default k1, k2, p1, p2) and
        ``principal_point`` ("free", the default, or "centre").

        Raises
        ------
        FileNotFoundError
            The points file is missing.
        ValueError
            A bad points file or field (naming ``source`` or the file and line).
        """
        path = Path(folder) / spec["points"]
        ids, points = read_target_points(path, spec["units"])
        distortion = tuple(spec.get("distortion", PinholeModel().distortion))
        try:
            model = PinholeModel(
                distortion, fixed_principal_point=spec.get("principal_point", "free") == "centre"
            )
        except ValueError as err:
            raise ValueError(f"{source}: distortion: {err}") from None
        return cls(
            points,
            ids,
            dots=spec.get("dots", "bright"),
            min_dot_area=spec.get("min_dot_area", 4),
            model=model,
            units=spec["units"],
            source=str(path),
        )


def read_target_points(path: Path, units: str) -> tuple[np.ndarray, np.ndarray]:
    """The points of a target file: one per line, ``X Y Z`` or ``id X Y Z``.

    Numbers are separated by blanks or tabs; empty lines and lines starting with ``#``
    are skipped. Every line has the same number of columns.

    Parameters
    ----------
    path : Path
        The file.
    units : {"m", "mm"}
        Units of its coordinates.

    Returns
    -------
    ids : ndarray of int, shape (N,)
        The first column of a four-column file, else 0 … N − 1.
    points : ndarray, shape (N, 3)
        m.

    Raises
    ------
    FileNotFoundError
        No such file.
    ValueError
        Unknown units, a line that is not 3 or 4 numbers (or not as many as the first),
        ids that are not integers or repeat, or two points at one place (naming the file
        and the line).
    """
    if units not in UNITS:
        raise ValueError(f"{path}: units must be one of {', '.join(UNITS)}, got {units!r}")
    if not path.is_file():
        raise FileNotFoundError(f"target points file {path} is missing")
    rows, lines = [], []
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as err:
        raise ValueError(f"{path}: not a readable text file ({err})") from None
    for number, line in enumerate(text.splitlines(), start=1):
        words = line.split()
        if not words or words[0].startswith("#"):
            continue
        try:
            values = [float(w) for w in words]
        except ValueError:
            values = []
        width = len(rows[0]) if rows else None
        if len(values) not in (3, 4) or (width is not None and len(values) != width):
            expected = "3 numbers (X Y Z) or 4 (id X Y Z)" if width is None else f"{width}"
            raise ValueError(f"{path}: line {number}: expected {expected}, got {line.strip()!r}")
        if not np.isfinite(values).all():
            raise ValueError(f"{path}: line {number}: numbers must be finite")
        if len(values) == 4 and not float(values[0]).is_integer():
            raise ValueError(f"{path}: line {number}: the id {words[0]!r} is not an integer")
        rows.append(values)
        lines.append(number)
    if not rows:
        raise ValueError(f"{path}: no target points")
    table = np.array(rows)
    ids = table[:, 0].astype(np.int64) if table.shape[1] == 4 else np.arange(len(table))
    points = table[:, -3:] * UNITS[units]
    _, first, counts = np.unique(ids, return_index=True, return_counts=True)
    if (counts > 1).any():
        again = int(first[np.argmax(counts > 1)])
        raise ValueError(f"{path}: line {lines[again]}: id {ids[again]} appears again later")
    _, first, counts = np.unique(points, axis=0, return_index=True, return_counts=True)
    if (counts > 1).any():
        again = int(first[np.argmax(counts > 1)])
        raise ValueError(f"{path}: line {lines[again]}: the same point appears again later")
    return ids, points


@dataclass(frozen=True, eq=False)
class PointTargetFit:
    """A camera calibrated from one image of a point target.

    Attributes
    ----------
    calibration : PinholeCalibration or RefractivePinholeCalibration
        The camera (behind its window when it has one).
    rows : ndarray of int, shape (M,)
        The target points used (rows of :attr:`PointTarget.points`).
    pixels : ndarray, shape (M, 2)
        The blob centre each was associated with, px.
    residuals : ndarray, shape (M,)
        |projection − blob centre| of each, px.
    blobs : int
        Dot-like blobs found on the image.
    seeds : int
        Seed points given.
    iterations : int
        Fits made (steps 3–4 of the module docstring).
    tolerance : float
        The last association tolerance, px.
    """

    calibration: PinholeCalibration | RefractivePinholeCalibration
    rows: np.ndarray
    pixels: np.ndarray
    residuals: np.ndarray
    blobs: int
    seeds: int
    iterations: int
    tolerance: float

    @property
    def rms(self) -> float:
        """Reprojection RMS over the points used, px."""
        return float(np.sqrt(np.mean(self.residuals**2)))

    def summary(self) -> dict:
        """Reprojection RMS (px), points used, blobs, seeds, iterations, the fitted
        principal distance and point (px), the centre (m) and the window (when the
        camera has one), for tables and JSON."""
        p = self.calibration.params
        window = getattr(self.calibration, "window", None)
        return {
            "rms_px": self.rms,
            "points": len(self.rows),
            "blobs": self.blobs,
            "seeds": self.seeds,
            "iterations": self.iterations,
            "tolerance_px": float(self.tolerance),
            "model": self.calibration.model.name,
            "focal_px": [float(p[0]), float(p[1])],
            "principal_point_px": [float(p[2]), float(p[3])],
            "centre_m": self.calibration.centre.tolist(),
            **({} if window is None else {"window": window.as_dict()}),
        }


def principal_point_warning(camera: str, fit: PointTargetFit) -> str | None:
    """A warning when the fitted principal point lies off the sensor, None otherwise.

    A pinhole fitted to a target whose points lie nearly in one plane, or that fills
    little of the image, can trade the principal point for the camera's rotation: the
    reprojection stays small while the point wanders off the sensor.
    """
    cx, cy = (float(v) for v in fit.calibration.params[2:4])
    width, height = fit.calibration.image_size
    if -0.5 <= cx <= width - 0.5 and -0.5 <= cy <= height - 0.5:
        return None
    return (
        f"{camera}: the fitted principal point ({cx:.0f}, {cy:.0f}) px lies off the "
        f"{width} × {height} px sensor: the fit traded it for the camera's rotation (target "
        "points nearly in one plane, or filling little of the image); check the target "
        'points triangulated back, or set target.principal_point = "centre"'
    )


def _seed_residuals(params: np.ndarray, world: np.ndarray, pixels: np.ndarray) -> np.ndarray:
    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
        xy, valid = project_parameters(params, world)
    r = np.where(valid[:, None], xy - pixels, 1e6)
    return r.ravel()


def seed_camera(
    world: np.ndarray,
    pixels: np.ndarray,
    image_size: tuple[int, int],
    *,
    focal_px: float | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """A pinhole with square pixels, centred principal point and no distortion fitted to
    a few seed points (step 2 of the module docstring).

    Parameters
    ----------
    world : ndarray, shape (S, 3)
        Seed points, m (S >= 4, not all on one line).
    pixels : ndarray, shape (S, 2)
        Where they are on the image, px.
    image_size : (int, int)
        (width, height), px.
    focal_px : float, optional
        Nominal principal distance, px (focal length / pixel pitch), tried besides the
        grid.

    Returns
    -------
    params : ndarray, shape (17,)
        The camera as a full parameter vector of :mod:`ptv.calibration.pinhole`.
    residuals : ndarray, shape (S,)
        |projection − pixel| of each seed, px.

    Raises
    ------
    ValueError
        Fewer than four seeds, or no pose puts them all in front of the camera.
    """
    world = np.asarray(world, dtype=float)
    pixels = np.asarray(pixels, dtype=float)
    if len(world) < MIN_SEEDS or world.shape != (len(pixels), 3) or pixels.shape[1:] != (2,):
        raise ValueError(
            f"need at least {MIN_SEEDS} seed points (S, 3) with pixels (S, 2), got "
            f"{world.shape} and {pixels.shape}"
        )
    width, height = image_size
    cx, cy = (width - 1) / 2.0, (height - 1) / 2.0
    focals = list(np.geomspace(*_FOCAL_GRID) * width)
    if focal_px is not None:
        focals.append(float(focal_px))
    candidates = []
    for f in focals:
        k = np.array([[f, 0.0, cx], [0.0, f, cy], [0.0, 0.0, 1.0]])
        try:
            ok, rvec, tvec = cv2.solvePnP(world, pixels, k, None, flags=cv2.SOLVEPNP_SQPNP)
        except cv2.error:
            continue
        if not ok:
            continue
        params = np.zeros(17)
        params[[0, 1, 2, 3]] = f, f, cx, cy
        params[11:14], params[14:17] = np.ravel(rvec), np.ravel(tvec)
        candidates.append((float(np.sum(_seed_residuals(params, world, pixels) ** 2)), params))
    if not candidates:
        raise ValueError("no camera pose puts the seed points in front of the camera")
    candidates.sort(key=lambda c: c[0])
    best = None
    for _, start in candidates[:_POLISHED_STARTS]:

        def residual(q: np.ndarray, start=start) -> np.ndarray:
            p = start.copy()
            p[_SEED_FREE] = q
            p[1] = q[0]
            return _seed_residuals(p, world, pixels)

        fit = least_squares(residual, start[_SEED_FREE], method="lm", x_scale="jac")
        cost = float(np.sum(fit.fun**2))
        if best is None or cost < best[0]:
            params = start.copy()
            params[_SEED_FREE] = fit.x
            params[1] = fit.x[0]
            best = (cost, params)
    params = best[1]
    return params, np.linalg.norm(_seed_residuals(params, world, pixels).reshape(-1, 2), axis=1)


def associate(
    predicted: np.ndarray, blobs: np.ndarray, tolerance: float
) -> tuple[np.ndarray, np.ndarray]:
    """Pair projected target points with blobs: mutual nearest neighbours within
    ``tolerance``.

    Parameters
    ----------
    predicted : ndarray, shape (N, 2)
        Projected target points, px; NaN rows are not imaged.
    blobs : ndarray, shape (B, 2)
        Blob centres, px.
    tolerance : float
        Largest distance of a pair, px.

    Returns
    -------
    rows : ndarray of int, shape (M,)
        The target points paired, increasing.
    blob_rows : ndarray of int, shape (M,)
        Their blobs.
    """
    seen = np.flatnonzero(np.isfinite(predicted).all(axis=1))
    if len(seen) == 0 or len(blobs) == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    distance, nearest = cKDTree(blobs).query(predicted[seen], distance_upper_bound=tolerance)
    hit = np.isfinite(distance)
    back = cKDTree(predicted[seen]).query(blobs)[1]  # the projected point nearest each blob
    mutual = hit.copy()
    mutual[hit] = back[nearest[hit]] == np.flatnonzero(hit)
    return seen[mutual], nearest[mutual]


def _observations(world: np.ndarray, pixels: np.ndarray) -> list[PlaneObservation]:
    """Point pairs as planes of one Z each (what the pinhole fit stacks back)."""
    return [
        PlaneObservation(float(z), pixels[world[:, 2] == z], world[world[:, 2] == z, :2])
        for z in np.unique(world[:, 2])
    ]


def _projected(
    params: np.ndarray, points: np.ndarray, image_size: tuple[int, int] | None = None
) -> np.ndarray:
    """Pixels (N, 2) of points under a parameter vector; NaN where not imaged (behind
    the camera, beyond the distortion's fold, or off an image of ``image_size``)."""
    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
        xy, valid = project_parameters(params, points)
    if image_size is not None:
        valid &= on_image(xy, image_size)
    xy[~valid] = np.nan
    return xy


def calibrate_point_target(
    image: np.ndarray,
    target: PointTarget,
    seeds: Mapping[int, tuple[float, float]],
    *,
    focal_px: float | None = None,
    window: FlatWindow | None = None,
    source: str = "image",
) -> PointTargetFit:
    """Calibrate one camera from one image of a point target (module docstring).

    Parameters
    ----------
    image : ndarray, shape (H, W)
        The calibration image (grey levels).
    target : PointTarget
        The target and the model to fit.
    seeds : mapping of int to (float, float)
        Target row → approximate pixel (x, y) of four or more points.
    focal_px : float, optional
        Nominal principal distance, px (focal length / pixel pitch).
    window : FlatWindow, optional
        The flat wall the camera looks through into the medium the target is in: the
        pinhole is then fitted with the rays refracted at both faces (step 6).
    source : str
        The image's name, for messages.

    Returns
    -------
    PointTargetFit

    Raises
    ------
    ValueError
        Too few seeds, seeds that no camera fits, or fewer than ``MIN_POINTS`` target
        points found (the message names ``source``); errors of :func:`find_blobs`.
    """
    height, width = np.shape(image)
    size = (int(width), int(height))
    if len(seeds) < MIN_SEEDS:
        raise ValueError(f"{source}: {len(seeds)} seed point(s); give at least {MIN_SEEDS}")
    seed_rows = np.array(list(seeds), dtype=np.int64)
    seed_pixels = np.array([seeds[r] for r in seed_rows], dtype=float)
    params, seed_residual = seed_camera(
        target.points[seed_rows], seed_pixels, size, focal_px=focal_px
    )
    if seed_residual.max() > SEED_TOLERANCE_PX:
        worst = int(np.argmax(seed_residual))
        x, y, z = target.points[seed_rows[worst]] / UNITS["mm"]
        raise ValueError(
            f"{source}: the seed points do not fit one camera: the seed of target point "
            f"{target.ids[seed_rows[worst]]} ({x:g}, {y:g}, {z:g}) mm is "
            f"{seed_residual[worst]:.1f} px off (largest allowed {SEED_TOLERANCE_PX:g} px): "
            "a wrong point or pixel?"
        )
    blobs = find_blobs(image, dots=target.dots, source=source, min_area=target.min_dot_area)
    predicted = _projected(params, target.points, size)
    seen = predicted[np.isfinite(predicted).all(axis=1)]
    if len(seen) < 2:
        raise ValueError(f"{source}: the seed camera images fewer than two target points")
    spacing = float(np.median(cKDTree(seen).query(seen, k=2)[0][:, 1]))
    tolerance = START_TOLERANCE * spacing
    previous, fit = None, None
    model = PinholeModel((), fixed_principal_point=target.model.fixed_principal_point)
    for iteration in range(1, MAX_ITERATIONS + 1):
        rows, blob_rows = associate(predicted, blobs.pixels, tolerance)
        if len(rows) < MIN_POINTS:
            raise ValueError(
                f"{source}: only {len(rows)} target points have a dot within "
                f"{tolerance:.1f} px of where the camera puts them (need {MIN_POINTS}; "
                f"{len(blobs)} blobs found)"
            )
        if fit is not None and fit.calibration.model == target.model and previous is not None:
            if np.array_equal(rows, previous[0]) and np.array_equal(blob_rows, previous[1]):
                break
        pixels = blobs.pixels[blob_rows]
        world = target.points[rows]
        calibration = calibrate_pinhole(
            _observations(world, pixels),
            size,
            model=model,
            focal_px=float(np.sqrt(params[0] * params[1])),
        )
        params = calibration.params
        residuals = np.linalg.norm(_projected(params, world) - pixels, axis=1)
        fit = PointTargetFit(
            calibration,
            rows,
            pixels,
            residuals,
            len(blobs),
            len(seeds),
            iteration,
            float(tolerance),
        )
        tolerance = min(tolerance, max(MIN_TOLERANCE_PX, RESIDUAL_FACTOR * np.median(residuals)))
        predicted = _projected(params, target.points, size)
        previous, model = (rows, blob_rows), target.model
    if window is None:
        return fit
    try:
        return _refit_through_window(fit, target, window, blobs.pixels)
    except ValueError as err:
        raise ValueError(f"{source}: {err}") from None


def _refit_through_window(
    fit: PointTargetFit,
    target: PointTarget,
    window: FlatWindow,
    blobs: np.ndarray,
) -> PointTargetFit:
    """Steps 3–4 again with the pinhole behind ``window`` (module docstring, step 6),
    started from the straight-ray ``fit``; ``blobs`` (B, 2) are the image's blob
    centres, px."""
    rows, pixels, tolerance = fit.rows, fit.pixels, fit.tolerance
    start = fit.calibration
    for iteration in range(1, MAX_ITERATIONS + 1):
        camera = fit_refractive_pinhole(start, window, target.points[rows], pixels)
        predicted = camera.project(target.points)
        residuals = np.linalg.norm(predicted[rows] - pixels, axis=1)
        out = PointTargetFit(
            camera,
            rows,
            pixels,
            residuals,
            fit.blobs,
            fit.seeds,
            fit.iterations + iteration,
            float(tolerance),
        )
        tolerance = min(tolerance, max(MIN_TOLERANCE_PX, RESIDUAL_FACTOR * np.median(residuals)))
        again, blob_rows = associate(predicted, blobs, tolerance)
        if len(again) < MIN_POINTS:
            raise ValueError(
                f"through the window only {len(again)} target points have a dot within "
                f"{tolerance:.1f} px of where the camera puts them (need {MIN_POINTS})"
            )
        if np.array_equal(again, rows) and np.array_equal(blobs[blob_rows], pixels):
            break
        rows, pixels, start = again, blobs[blob_rows], camera.pinhole
    return out
