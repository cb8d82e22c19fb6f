"""Stacks of flat, parallel refractive interfaces and exact ray tracing through them.

A stack is L parallel planes n̂·X = d_k (k = 0 … L−1, d non-decreasing) separating
L + 1 media of refractive indices n_0 (the camera's side, air) … n_L (the far side,
water). n̂ is a unit normal pointing from the camera toward the last medium. The
default window is air | glass | water.

Refraction uses the vector form of Snell's law (docs/optics.md §4.1): for a unit incident
direction d and a unit normal N facing the incident side (N·d < 0), with η = n₁/n₂,
c₁ = −N·d and c₂² = 1 − η²(1 − c₁²),

    t = η d + (η c₁ − c₂) N,

and the ray is totally internally reflected when c₂² < 0.
"""

import logging
from dataclasses import dataclass

import numpy as np

from simulator.optics.rays import UNIT_TOLERANCE, Rays

logger = logging.getLogger(__name__)

#: Refractive indices used by default (at ~532 nm, room temperature).
N_AIR = 1.0
N_PMMA = 1.49
N_GLASS = 1.52
N_WATER = 1.333


def _unit_normal(normal: object, name: str) -> np.ndarray:
    n = np.array(normal, dtype=np.float64)
    if n.shape != (3,) or not np.isfinite(n).all():
        raise ValueError(f"{name} must be a finite 3-vector; got {normal!r}")
    norm = float(np.linalg.norm(n))
    if norm == 0.0:
        raise ValueError(f"{name} must be a unit vector; got the zero vector {n.tolist()}")
    if abs(norm - 1.0) > UNIT_TOLERANCE:
        raise ValueError(f"{name} must be a unit vector; got {n.tolist()} with norm {norm!r}")
    return n / norm


@dataclass(frozen=True, eq=False)
class FlatInterfaces:
    """L parallel refractive planes n̂·X = d_k between L + 1 media.

    Attributes
    ----------
    normal : ndarray, shape (3,)
        Unit normal of the planes, pointing from the camera side toward the last
        medium (water), world frame.
    offsets : ndarray, shape (L,)
        d_k, m: plane k is {X : n̂·X = d_k}; non-decreasing, so d_{k+1} − d_k ≥ 0 is
        the thickness of medium k + 1.
    indices : ndarray, shape (L + 1,)
        Refractive indices n_0 (camera side) … n_L (far side), all > 0.
    """

    normal: np.ndarray
    offsets: np.ndarray
    indices: np.ndarray

    def __post_init__(self) -> None:
        normal = _unit_normal(self.normal, "FlatInterfaces.normal")
        offsets = np.array(self.offsets, dtype=np.float64).reshape(-1)
        indices = np.array(self.indices, dtype=np.float64).reshape(-1)
        if offsets.size < 1 or not np.isfinite(offsets).all():
            raise ValueError(
                f"FlatInterfaces.offsets must be one or more finite distances in m; "
                f"got {self.offsets!r}"
            )
        if np.any(np.diff(offsets) < 0):
            raise ValueError(
                "FlatInterfaces.offsets must be non-decreasing (layer thicknesses >= 0); "
                f"got {offsets.tolist()}"
            )
        if indices.size != offsets.size + 1:
            raise ValueError(
                f"FlatInterfaces.indices must hold {offsets.size + 1} refractive indices "
                f"for {offsets.size} interface(s); got {indices.tolist()}"
            )
        if not np.isfinite(indices).all() or np.any(indices <= 0):
            raise ValueError(
                f"FlatInterfaces.indices must be finite and > 0; got {indices.tolist()}"
            )
        for name, value in (("normal", normal), ("offsets", offsets), ("indices", indices)):
            value.setflags(write=False)
            object.__setattr__(self, name, value)

    @property
    def n_interfaces(self) -> int:
        """Number of planes L."""
        return len(self.offsets)

    @property
    def thicknesses(self) -> np.ndarray:
        """Thicknesses (L − 1,) of the media between the first and last plane, m."""
        return np.diff(self.offsets)

    def camera_height(self, center: np.ndarray) -> float:
        """Distance h_0 = d_0 − n̂·C from a camera centre to the first plane, m."""
        return float(self.offsets[0] - self.normal @ np.asarray(center, dtype=np.float64))


def flat_window(
    normal: object,
    distance: float,
    thickness: float,
    *,
    n_air: float = N_AIR,
    n_glass: float = N_PMMA,
    n_water: float = N_WATER,
) -> FlatInterfaces:
    """An air | glass | water window with parallel faces.

    Parameters
    ----------
    normal : array_like, shape (3,)
        Unit normal pointing from the air toward the water.
    distance : float
        Offset of the air–glass face: the face is {X : n̂·X = distance}, m.
    thickness : float
        Glass thickness t_g ≥ 0, m.
    n_air, n_glass, n_water : float
        Refractive indices (> 0).

    Returns
    -------
    FlatInterfaces
        Planes at ``distance`` and ``distance + thickness``.

    Examples
    --------
    A 10 mm PMMA window across Z = 0.1 m seen from +Z, water beyond it: the normal
    points toward −Z, so its faces are at n̂·X = −0.1 and −0.09 m.

    >>> import simulator
    >>> window = simulator.flat_window([0.0, 0.0, -1.0], -0.1, 0.01)
    >>> window.offsets, window.indices  # m; air, PMMA, water
    (array([-0.1 , -0.09]), array([1.   , 1.49 , 1.333]))
    >>> window.camera_height([0.0, 0.0, 0.5])  # a camera at Z = 0.5 m: 0.4 m of air, m
    0.4
    """
    if not np.isfinite(thickness) or thickness < 0:
        raise ValueError(f"glass thickness must be finite and >= 0 m; got {thickness!r}")
    if not np.isfinite(distance):
        raise ValueError(f"window distance must be finite (m); got {distance!r}")
    for name, value in (("n_air", n_air), ("n_glass", n_glass), ("n_water", n_water)):
        if not (np.isfinite(value) and value > 0):
            raise ValueError(f"refractive index {name} must be finite and > 0; got {value!r}")
    return FlatInterfaces(
        normal=normal,
        offsets=[distance, distance + thickness],
        indices=[n_air, n_glass, n_water],
    )


def refract(
    directions: np.ndarray, normal: np.ndarray, n1: float, n2: float
) -> tuple[np.ndarray, np.ndarray]:
    """Refract unit directions at a plane by the vector form of Snell's law.

    Parameters
    ----------
    directions : ndarray, shape (N, 3)
        Unit incident directions.
    normal : ndarray, shape (3,)
        Unit normal of the plane, either orientation (it is flipped to face the
        incident side, N·d < 0, per ray).
    n1, n2 : float
        Refractive indices of the incident and transmitting media.

    Returns
    -------
    transmitted : ndarray, shape (N, 3)
        Unit refracted directions; NaN where totally internally reflected.
    tir : ndarray of bool, shape (N,)
        True where total internal reflection occurs.
    """
    cos_in = directions @ normal
    facing = np.where(cos_in > 0, -1.0, 1.0)  # sign making N face the incident side
    c1 = -cos_in * facing  # = −N·d ≥ 0
    eta = n1 / n2
    c2sq = 1.0 - eta * eta * (1.0 - c1 * c1)
    tir = c2sq < 0
    c2 = np.sqrt(np.where(tir, np.nan, c2sq))
    transmitted = eta * directions + ((eta * c1 - c2) * facing)[:, None] * normal[None, :]
    return transmitted, tir


@dataclass(frozen=True, eq=False)
class RayPath:
    """A ray traced through a stack, segment by segment.

    Attributes
    ----------
    points : ndarray, shape (L + 1, N, 3)
        The start point (camera centre) and the hit point on each of the L planes, m.
    directions : ndarray, shape (L + 1, N, 3)
        Unit direction in each medium 0 … L (after refraction at each plane).
    tir : ndarray of bool, shape (N,)
        True where a ray was totally internally reflected (its later entries NaN).
    """

    points: np.ndarray
    directions: np.ndarray
    tir: np.ndarray


def trace(origins: np.ndarray, directions: np.ndarray, stack: FlatInterfaces) -> RayPath:
    """Trace rays from the camera side through every plane of ``stack``.

    Parameters
    ----------
    origins : ndarray, shape (N, 3)
        Start points in medium 0 (n̂·O < d_0), m.
    directions : ndarray, shape (N, 3)
        Unit directions in medium 0.
    stack : FlatInterfaces
        The planes.

    Returns
    -------
    RayPath
        Hit points and directions; rays that move away from the planes (n̂·d ≤ 0),
        start beyond the first plane, or are totally internally reflected are NaN
        from the first plane they fail to cross.
    """
    n = stack.normal
    n_rays = len(origins)
    points = np.full((stack.n_interfaces + 1, n_rays, 3), np.nan)
    dirs = np.full((stack.n_interfaces + 1, n_rays, 3), np.nan)
    points[0], dirs[0] = origins, directions
    tir_any = np.zeros(n_rays, dtype=bool)
    with np.errstate(invalid="ignore", divide="ignore"):
        toward = directions @ n
        behind = origins @ n < stack.offsets[0]
        ok = (toward > 0) & behind
        current, d = np.where(ok[:, None], origins, np.nan), directions
        for k, offset in enumerate(stack.offsets):
            along = d @ n
            step = (offset - current @ n) / along
            current = current + step[:, None] * d
            d, tir = refract(d, n, stack.indices[k], stack.indices[k + 1])
            tir_any |= tir & np.isfinite(current[:, 0])
            d = np.where(np.isfinite(current[:, :1]), d, np.nan)
            points[k + 1], dirs[k + 1] = current, d
    return RayPath(points=points, directions=dirs, tir=tir_any)


def back_project(origins: np.ndarray, directions: np.ndarray, stack: FlatInterfaces) -> Rays:
    """Rays in the camera's medium → the same rays in the last medium (water).

    Parameters
    ----------
    origins : ndarray, shape (N, 3)
        Points on the rays in medium 0, m.
    directions : ndarray, shape (N, 3)
        Unit directions in medium 0.
    stack : FlatInterfaces
        The planes.

    Returns
    -------
    Rays
        Origin on the last plane (where the ray enters the last medium) and unit
        direction in that medium; NaN for rays that never get there.
    """
    path = trace(origins, directions, stack)
    if path.tir.any():
        logger.debug("back-projection: %d ray(s) totally internally reflected", path.tir.sum())
    return Rays(origins=path.points[-1], directions=path.directions[-1])
