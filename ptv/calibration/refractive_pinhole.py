"""A pinhole camera looking into water through a flat window: Snell's law at both faces.

A camera in air behind the flat glass wall of a water tank sees a point through two
refractions. A straight-ray pinhole absorbs part of that into its focal length and
distortion near its calibration target and errs away from it (docs/calibration.md §9).
This model keeps the pinhole for the lens (:mod:`ptv.calibration.pinhole`: K, the
distortion, the pose, all in air) and traces the rays through the window exactly:

* **pixel → ray**: the pinhole's straight ray from the camera centre C meets the dry
  face of the glass, is refracted into the glass, meets the wet face and is refracted
  into the medium; the ray returned starts on the wet face.
* **point → pixel**: the ray from C to a point P lies in the plane holding C, P and the
  window's normal n̂. In that plane, with s = n_k sin θ_k the invariant of Snell's law
  (θ_k the angle to n̂ in medium k), the ray's sideways travel is

      ρ(s) = Σ_k h_k s / √(n_k² − s²),    k = air, glass, medium,

  h_k being the depth of each medium along n̂ (camera to dry face, the glass thickness,
  wet face to P). ρ(s) is increasing and convex, so Newton's method started at the s
  where the air alone would cover P's distance ρ_P from C's foot (right of the root)
  converges monotonically. The air ray's direction then goes through the pinhole.

The window is known (where the wet face is, the glass thickness and the indices, as a
lab measures them, like OpenPTV's multimedia parameters); :func:`fit_refractive_pinhole`
fits the pinhole's free parameters through it by Levenberg–Marquardt on the
reprojection errors.
"""

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from ptv.calibration.pinhole import (
    PinholeCalibration,
    PinholeModel,
    project_parameters,
    rodrigues,
)
from ptv.camera_model import on_image
from ptv.rays import Rays

__all__ = [
    "FlatWindow",
    "RefractivePinholeCalibration",
    "air_directions",
    "fit_refractive_pinhole",
    "window_rays",
]

#: Newton's stopping step in s (dimensionless), and its iteration cap.
_NEWTON_STEP = 1e-14
_NEWTON_ITERATIONS = 60
#: Evaluation cap of the Levenberg–Marquardt fit.
_LM_EVALUATIONS = 2000
#: Residual given to a point the trial camera cannot image, px.
_UNIMAGED_PX = 1e4
#: Fields of a window in experiment.json, and whether each is required.
WINDOW_FIELDS = {
    "normal": True,
    "distance": True,
    "thickness": True,
    "glass_index": True,
    "medium_index": True,
    "air_index": False,
}


@dataclass(frozen=True, eq=False)
class FlatWindow:
    """A flat glass wall with parallel faces between a camera in air and the medium.

    Attributes
    ----------
    normal : ndarray, shape (3,)
        Unit normal of the faces, pointing from the medium toward the camera.
    distance : float
        Where the wet face is: {X : n̂·X = distance}, m (OpenPTV's glass vector is
        distance × n̂).
    thickness : float
        Glass thickness, m (≥ 0); the dry face is at n̂·X = distance + thickness.
    glass_index, medium_index : float
        Refractive indices of the glass and of the medium (water 1.33).
    air_index : float
        Refractive index on the camera's side (default 1); the glass and the medium
        must be at least as dense.
    """

    normal: np.ndarray
    distance: float
    thickness: float
    glass_index: float
    medium_index: float
    air_index: float = 1.0

    def __post_init__(self) -> None:
        normal = np.array(self.normal, dtype=float).reshape(-1)
        if normal.shape != (3,) or not np.isfinite(normal).all() or not normal.any():
            raise ValueError(f"normal must be a non-zero 3-vector, got {self.normal!r}")
        normal = normal / np.linalg.norm(normal)
        normal.setflags(write=False)
        object.__setattr__(self, "normal", normal)
        for name in ("distance", "thickness", "glass_index", "medium_index", "air_index"):
            value = getattr(self, name)
            if isinstance(value, bool) or not np.isfinite(value):
                raise ValueError(f"{name} must be a finite number, got {value!r}")
            object.__setattr__(self, name, float(value))
        if self.thickness < 0:
            raise ValueError(f"thickness must be >= 0 m, got {self.thickness!r}")
        if self.air_index <= 0:
            raise ValueError(f"air_index must be > 0, got {self.air_index!r}")
        for name in ("glass_index", "medium_index"):
            if getattr(self, name) < self.air_index:
                raise ValueError(
                    f"{name} {getattr(self, name)!r} is below air_index {self.air_index!r}: "
                    "the glass and the medium must be at least as dense as the air"
                )

    @classmethod
    def from_dict(cls, spec: Mapping, *, source: str) -> "FlatWindow":
        """A window from experiment.json's ``window`` object (SI units).

        Raises
        ------
        ValueError
            A missing or unknown field, or a bad value; the message starts with
            ``source`` and names the field.
        """
        unknown = sorted(set(spec) - set(WINDOW_FIELDS))
        if unknown:
            raise ValueError(
                f"{source}: unknown field(s) {', '.join(unknown)}; a window has "
                f"{', '.join(WINDOW_FIELDS)}"
            )
        missing = [name for name, needed in WINDOW_FIELDS.items() if needed and name not in spec]
        if missing:
            raise ValueError(f"{source}: missing field(s) {', '.join(missing)}")
        try:
            return cls(**spec)
        except (TypeError, ValueError) as err:
            raise ValueError(f"{source}: {err}") from None

    def as_dict(self) -> dict:
        """The window as experiment.json writes it (SI units)."""
        return {
            "normal": self.normal.tolist(),
            "distance": self.distance,
            "thickness": self.thickness,
            "glass_index": self.glass_index,
            "medium_index": self.medium_index,
            "air_index": self.air_index,
        }

    @property
    def indices(self) -> np.ndarray:
        """Refractive indices of air, glass and medium, shape (3,)."""
        return np.array([self.air_index, self.glass_index, self.medium_index])

    def air_depth(self, centre: np.ndarray) -> float:
        """Distance from a camera centre to the dry face along −n̂, m (> 0 outside)."""
        return float(self.normal @ np.asarray(centre, dtype=float) - self.distance - self.thickness)

    def medium_depth(self, points: np.ndarray) -> np.ndarray:
        """Depth of points beyond the wet face along −n̂, m, shape (N,) (> 0 in the medium)."""
        return self.distance - np.asarray(points, dtype=float) @ self.normal


def _refract(directions: np.ndarray, normal: np.ndarray, ratio: float) -> np.ndarray:
    """Unit directions (N, 3) after crossing a face whose unit ``normal`` faces the
    incoming rays, from index n₁ to n₂ with ``ratio`` = n₁/n₂ ≤ 1 (never total
    reflection)."""
    cos_in = -(directions @ normal)
    cos_out = np.sqrt(1.0 - ratio**2 * (1.0 - cos_in**2))
    return ratio * directions + (ratio * cos_in - cos_out)[:, None] * normal


def window_rays(centre: np.ndarray, directions: np.ndarray, window: FlatWindow) -> Rays:
    """Rays in the medium of air rays from a camera centre, refracted at both faces.

    Parameters
    ----------
    centre : ndarray, shape (3,)
        Camera centre, m (on the air side).
    directions : ndarray, shape (N, 3)
        Unit directions of the air rays; NaN rows stay NaN.
    window : FlatWindow
        The wall.

    Returns
    -------
    Rays
        Origins on the wet face, m, and unit directions in the medium; NaN where an
        air ray does not head for the window.
    """
    n = window.normal
    centre = np.asarray(centre, dtype=float)
    directions = np.asarray(directions, dtype=float)
    with np.errstate(invalid="ignore", divide="ignore"):
        toward = -(directions @ n)
        ok = toward > 0
        dry = centre + (window.air_depth(centre) / toward)[:, None] * directions
        glass = _refract(directions, n, window.air_index / window.glass_index)
        wet = dry + (window.thickness / -(glass @ n))[:, None] * glass
        medium = _refract(glass, n, window.glass_index / window.medium_index)
    ok &= np.isfinite(wet).all(axis=1) & np.isfinite(medium).all(axis=1)
    wet[~ok] = np.nan
    medium[~ok] = np.nan
    return Rays(wet, medium)


def _sideways(s: np.ndarray, heights: np.ndarray, indices: np.ndarray):
    """ρ(s) (N,) and dρ/ds (N,) for depths ``heights`` (3, N) and ``indices`` (3,)."""
    root = np.sqrt(indices[:, None] ** 2 - s**2)
    rho = np.sum(heights * s / root, axis=0)
    slope = np.sum(heights * indices[:, None] ** 2 / root**3, axis=0)
    return rho, slope


def air_directions(centre: np.ndarray, points: np.ndarray, window: FlatWindow) -> np.ndarray:
    """Directions in air from a camera centre to points seen through the window.

    Parameters
    ----------
    centre : ndarray, shape (3,)
        Camera centre, m, outside the window (beyond its dry face).
    points : ndarray, shape (N, 3)
        Points, m.
    window : FlatWindow
        The wall.

    Returns
    -------
    ndarray, shape (N, 3)
        Unit directions of the air rays that reach each point (module docstring); NaN
        for points not in the medium (not beyond the wet face), or for every point when
        the camera is not outside the window.
    """
    centre = np.asarray(centre, dtype=float)
    points = np.asarray(points, dtype=float)
    n = window.normal
    h_air = window.air_depth(centre)
    h_medium = window.medium_depth(points)
    relative = points - centre
    sideways = relative - (relative @ n)[:, None] * n
    rho = np.linalg.norm(sideways, axis=1)
    inside = np.isfinite(rho) & (h_medium > 0) & (h_air > 0)
    heights = np.vstack(
        [np.full(len(points), h_air), np.full(len(points), window.thickness), h_medium]
    )
    indices = window.indices
    # Start right of the root: where the air alone would cover ρ.
    s = indices[0] * rho / np.hypot(rho, h_air)
    s = np.where(inside, s, 0.0)
    heights[:, ~inside] = 0.0
    for _ in range(_NEWTON_ITERATIONS):
        value, slope = _sideways(s, heights, indices)
        with np.errstate(invalid="ignore", divide="ignore"):
            step = np.where(slope > 0, (value - rho) / slope, 0.0)
        s = np.clip(s - np.where(inside, step, 0.0), 0.0, None)
        if not np.any(np.abs(step[inside]) > _NEWTON_STEP):
            break
    sin_air = s / indices[0]
    with np.errstate(invalid="ignore", divide="ignore"):
        across = np.where(rho[:, None] > 0, sideways / rho[:, None], 0.0)
    out = sin_air[:, None] * across - np.sqrt(1.0 - sin_air**2)[:, None] * n
    out[~inside] = np.nan
    return out


def _centre(params: np.ndarray) -> np.ndarray:
    """Camera centre −Rᵀt of a full pinhole parameter vector, m."""
    return -rodrigues(params[11:14]).T @ params[14:17]


def _project(params: np.ndarray, points: np.ndarray, window: FlatWindow) -> np.ndarray:
    """Pixels (N, 2) of points through the window under pinhole ``params``; NaN where
    not imaged (not in the medium, camera not outside, behind the lens or beyond the
    distortion's fold); image bounds not checked."""
    centre = _centre(params)
    directions = air_directions(centre, points, window)
    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
        xy, valid = project_parameters(params, centre + np.nan_to_num(directions))
    xy[~(valid & np.isfinite(directions).all(axis=1))] = np.nan
    return xy


@dataclass(frozen=True, eq=False)
class RefractivePinholeCalibration:
    """A pinhole camera in air behind a flat window into the medium.

    Attributes
    ----------
    pinhole : PinholeCalibration
        The lens and pose in air; its ``rms`` is the reprojection RMS through the
        window, px.
    window : FlatWindow
        The wall the camera looks through.
    """

    pinhole: PinholeCalibration
    window: FlatWindow

    def __post_init__(self) -> None:
        if self.window.air_depth(self.pinhole.centre) <= 0:
            raise ValueError(
                "the camera centre is not outside the window (not beyond its dry face)"
            )

    @property
    def image_size(self) -> tuple[int, int]:
        """(width, height), px."""
        return self.pinhole.image_size

    @property
    def params(self) -> np.ndarray:
        """The pinhole's full parameter vector (17,)."""
        return self.pinhole.params

    @property
    def model(self) -> PinholeModel:
        """The pinhole's fitted parameter set."""
        return self.pinhole.model

    @property
    def centre(self) -> np.ndarray:
        """Camera centre in the world frame (3,), m."""
        return self.pinhole.centre

    @property
    def rms(self) -> float:
        """Reprojection RMS through the window, px."""
        return self.pinhole.rms

    def project(self, points: np.ndarray) -> np.ndarray:
        """Pixels (N, 2) of world points (N, 3), m; NaN where not imaged (not in the
        medium, behind the lens, beyond the distortion's fold, or off the image)."""
        points = np.asarray(points, dtype=float)
        if points.ndim != 2 or points.shape[1] != 3:
            raise ValueError(f"points must have shape (N, 3), got {points.shape}")
        xy = _project(self.params, points, self.window)
        xy[~on_image(xy, self.image_size)] = np.nan
        return xy

    def pixel_to_ray(self, xy: np.ndarray) -> Rays:
        """Rays in the medium (origins on the wet face) of pixels xy (N, 2); NaN off
        the image or where the distortion cannot be inverted."""
        straight = self.pinhole.pixel_to_ray(xy)
        return window_rays(self.centre, straight.directions, self.window)


def fit_refractive_pinhole(
    start: PinholeCalibration, window: FlatWindow, world: np.ndarray, pixels: np.ndarray
) -> RefractivePinholeCalibration:
    """Fit a pinhole's free parameters through a known window to point pairs.

    Parameters
    ----------
    start : PinholeCalibration
        Start and parameter set (its ``model``): typically the straight-ray pinhole
        fitted to the same points.
    window : FlatWindow
        The wall, known.
    world : ndarray, shape (N, 3)
        Target points in the medium, m.
    pixels : ndarray, shape (N, 2)
        Where each is imaged, px.

    Returns
    -------
    RefractivePinholeCalibration
        Levenberg–Marquardt on all reprojection errors; ``pinhole.rms`` is the RMS
        through the window.

    Raises
    ------
    ValueError
        The start's centre is not outside the window, or target points are not beyond
        its wet face.
    """
    world = np.asarray(world, dtype=float)
    pixels = np.asarray(pixels, dtype=float)
    if window.air_depth(start.centre) <= 0:
        raise ValueError(
            f"the camera (centre {np.round(start.centre, 4).tolist()} m) is not outside "
            "its window: check the window's normal (toward the camera) and distance"
        )
    dry = np.flatnonzero(window.medium_depth(world) <= 0)
    if len(dry):
        raise ValueError(
            f"{len(dry)} target point(s) are not beyond the window's wet face, e.g. "
            f"{np.round(world[dry[0]], 4).tolist()} m: check the window's normal and distance"
        )
    base = start.model.restrict(start.params)
    free = start.model.free

    def residual(q: np.ndarray) -> np.ndarray:
        p = base.copy()
        p[free] = q
        r = (_project(p, world, window) - pixels).ravel()
        return np.where(np.isfinite(r), r, _UNIMAGED_PX)

    fit = least_squares(residual, base[free], method="lm", x_scale="jac", max_nfev=_LM_EVALUATIONS)
    params = base.copy()
    params[free] = fit.x
    errors = np.linalg.norm(_project(params, world, window) - pixels, axis=1)
    pinhole = PinholeCalibration(
        image_size=start.image_size,
        model=start.model,
        params=params,
        rms=float(np.sqrt(np.mean(errors**2))),
        start="through the window, from the straight-ray fit",
        n_points=len(world),
    )
    return RefractivePinholeCalibration(pinhole, window)
