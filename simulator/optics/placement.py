"""Place a camera looking at a target point, optionally through a flat window.

Conventions
-----------
The camera sits at T + D·u with u = (cos ψ sin φ, sin ψ, cos ψ cos φ): azimuth φ
rotates about the world Y axis from +Z toward +X, elevation ψ tilts toward +Y. With
φ = ψ = 0 the camera is on the +Z axis looking toward −Z, its image x along +X and
its image y (rows, downward) along −Y. The image y axis is always the projection of
−Y on the image plane, so sensor rows stay parallel to world Y as closely as the
viewing direction allows.

The window is built around the nominal line of sight a = −u: its normal (toward
the water) is a tilted by the obliquity angle toward cos χ x̂ + sin χ ŷ, where x̂, ŷ
are the image axes and χ the obliquity direction (χ = 0: tilt in the horizontal
plane of the camera, e.g. the plane of two cameras in XZ; χ = π/4: about a
diagonal). Its wet face passes through T − w·a (w = water path along the line of
sight), its dry face lies a glass thickness closer to the camera. The optical axis
is then aimed along the refracted chief ray to T, so T images at the principal
point exactly, with or without obliquity. A window may instead be given fixed in the
world (a tank wall, :class:`~simulator.optics.interfaces.FlatInterfaces`).

A roll ρ then turns the camera about its optical axis: the image axes become
x' = cos ρ x + sin ρ y and y' = −sin ρ x + cos ρ y (ρ = 90°: image x along −Y for a
camera at φ = ψ = 0). The window's obliquity direction stays measured in the unrolled
axes.
"""

from dataclasses import dataclass

import numpy as np

from simulator.optics.camera import Camera
from simulator.optics.forward import solve_chief_rays
from simulator.optics.interfaces import N_AIR, N_PMMA, N_WATER, FlatInterfaces, flat_window
from simulator.optics.lens import Lens

WORLD_UP = np.array([0.0, 1.0, 0.0])


@dataclass(frozen=True)
class WindowSpec:
    """A flat window in front of a camera, defined relative to its line of sight.

    Attributes
    ----------
    water_path : float
        Distance from the target to the wet (glass–water) face along the nominal
        line of sight, m (> 0).
    glass_thickness : float
        Glass thickness, m (≥ 0).
    obliquity : float
        Angle between the window normal and the line of sight, rad (|·| < π/2).
    obliquity_direction : float
        Direction χ in the image plane toward which the normal is tilted, rad,
        from the image x axis toward the image y axis (0: horizontal, π/4: diagonal).
    n_air, n_glass, n_water : float
        Refractive indices.

    Examples
    --------
    15 mm of PMMA 0.1 m of water from the aim point, tilted 8° about a diagonal of the
    image (as the windows of the paper-stereo rig are):

    >>> import numpy as np
    >>> import simulator
    >>> window = simulator.WindowSpec(water_path=0.1, glass_thickness=0.015,
    ...                               obliquity=np.radians(8), obliquity_direction=np.radians(45))
    >>> lens = simulator.Lens(focal_length=0.05, pixel_pitch=10e-6, sensor_size=(640, 480))
    >>> camera = simulator.look_at_camera([0.0, 0.0, 0.0], lens, distance=0.5,
    ...                                   azimuth=np.radians(30), window=window)
    >>> camera.interfaces.indices  # air, PMMA, water
    array([1.   , 1.49 , 1.333])
    >>> camera.project([[0.0, 0.0, 0.0]])  # the aim point images at the principal point, px
    array([[319.5, 239.5]])
    """

    water_path: float
    glass_thickness: float = 0.015
    obliquity: float = 0.0
    obliquity_direction: float = 0.0
    n_air: float = N_AIR
    n_glass: float = N_PMMA
    n_water: float = N_WATER

    def __post_init__(self) -> None:
        if not (np.isfinite(self.water_path) and self.water_path > 0):
            raise ValueError(
                f"WindowSpec.water_path must be finite and > 0 m; got {self.water_path!r}"
            )
        if not (np.isfinite(self.obliquity) and abs(self.obliquity) < np.pi / 2):
            raise ValueError(
                f"WindowSpec.obliquity must be finite and below 90° in rad; got {self.obliquity!r}"
            )
        if not np.isfinite(self.obliquity_direction):
            raise ValueError(
                "WindowSpec.obliquity_direction must be finite (rad); "
                f"got {self.obliquity_direction!r}"
            )


def look_rotation(forward: np.ndarray, *, up: np.ndarray = WORLD_UP) -> np.ndarray:
    """World→camera rotation (3, 3) with optical axis ``forward`` and image y along −``up``.

    Raises ``ValueError`` when ``forward`` is (nearly) parallel to ``up``.
    """
    z = np.asarray(forward, dtype=np.float64)
    z = z / np.linalg.norm(z)
    down = -(up - (up @ z) * z)
    norm = np.linalg.norm(down)
    if norm < 1e-6:
        raise ValueError(
            f"viewing direction {z.tolist()} is parallel to the up vector "
            f"{np.asarray(up).tolist()}; the image orientation is undefined"
        )
    y = down / norm
    x = np.cross(y, z)
    return np.array([x, y, z])


def viewing_direction(azimuth: float, elevation: float) -> np.ndarray:
    """Unit vector u (3,) from the target toward the camera (see module docstring)."""
    return np.array(
        [
            np.cos(elevation) * np.sin(azimuth),
            np.sin(elevation),
            np.cos(elevation) * np.cos(azimuth),
        ]
    )


def window_for(center: np.ndarray, target: np.ndarray, spec: WindowSpec) -> FlatInterfaces:
    """The window of ``spec`` between a camera centre and a target (see module docstring)."""
    line = np.asarray(target, dtype=np.float64) - np.asarray(center, dtype=np.float64)
    a = line / np.linalg.norm(line)
    frame = look_rotation(a)
    tilt = np.cos(spec.obliquity_direction) * frame[0] + np.sin(spec.obliquity_direction) * frame[1]
    normal = np.cos(spec.obliquity) * a + np.sin(spec.obliquity) * tilt
    normal /= np.linalg.norm(normal)
    wet = float(normal @ (np.asarray(target, dtype=np.float64) - spec.water_path * a))
    return flat_window(
        normal,
        wet - spec.glass_thickness,
        spec.glass_thickness,
        n_air=spec.n_air,
        n_glass=spec.n_glass,
        n_water=spec.n_water,
    )


def roll_rotation(roll: float) -> np.ndarray:
    """Rotation (3, 3) of camera coordinates by ``roll`` (rad) about the optical axis."""
    c, s = np.cos(roll), np.sin(roll)
    return np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])


def look_at_camera(
    target: object,
    lens: Lens,
    *,
    distance: float,
    azimuth: float,
    elevation: float = 0.0,
    roll: float = 0.0,
    window: WindowSpec | FlatInterfaces | None = None,
) -> Camera:
    """A camera at ``distance`` from ``target``, aimed so that it images at the principal point.

    Parameters
    ----------
    target : array_like, shape (3,)
        Point looked at, m (world frame).
    lens : Lens
        Lens and sensor.
    distance : float
        Straight-line distance from the entrance pupil to the target, m.
    azimuth, elevation : float
        Direction of the camera seen from the target, rad (module docstring).
    roll : float
        Turn of the camera about its optical axis, rad (module docstring).
    window : WindowSpec, FlatInterfaces or None
        Flat window between camera and target, relative to the line of sight
        (WindowSpec) or fixed in the world (FlatInterfaces); None for no refraction.

    Returns
    -------
    Camera

    Examples
    --------
    A camera 0.5 m from the origin, 30° from +Z toward +X, first in air, then behind a
    window 0.1 m of water from the origin:

    >>> import numpy as np
    >>> import simulator
    >>> lens = simulator.Lens(focal_length=0.05, pixel_pitch=10e-6, sensor_size=(640, 480))
    >>> dry = simulator.look_at_camera([0.0, 0.0, 0.0], lens, distance=0.5,
    ...                                azimuth=np.radians(30))
    >>> dry.center.round(4)  # m
    array([0.25 , 0.   , 0.433])
    >>> window = simulator.WindowSpec(water_path=0.1, glass_thickness=0.01)
    >>> wet = simulator.look_at_camera([0.0, 0.0, 0.0], lens, distance=0.5,
    ...                                azimuth=np.radians(30), window=window)
    >>> points = [[0.0, 0.0, 0.0], [1e-3, 0.0, 0.0]]  # m
    >>> dry.project(points).round(2)  # px
    array([[319.5 , 239.5 ],
           [328.17, 239.5 ]])
    >>> wet.project(points).round(2)  # the refraction magnifies, px
    array([[319.5 , 239.5 ],
           [328.69, 239.5 ]])
    """
    target = np.asarray(target, dtype=np.float64)
    if target.shape != (3,) or not np.isfinite(target).all():
        raise ValueError(f"target must be a finite 3-vector in m; got {target!r}")
    if not (np.isfinite(distance) and distance > 0):
        raise ValueError(f"distance must be finite and > 0 m; got {distance!r}")
    if not np.isfinite(roll):
        raise ValueError(f"roll must be finite (rad); got {roll!r}")
    center = target + distance * viewing_direction(azimuth, elevation)
    if window is None:
        return Camera(center, roll_rotation(roll) @ look_rotation(target - center), lens)
    if isinstance(window, FlatInterfaces):
        stack = window
        if not stack.camera_height(center) > 0:
            raise ValueError("the camera is not on the air side of its window")
    else:
        stack = window_for(center, target, window)
        if not stack.camera_height(center) > 0:
            raise ValueError(
                f"the window (water path {window.water_path:g} m, glass "
                f"{window.glass_thickness:g} m, obliquity {np.rad2deg(window.obliquity):g}°) "
                f"does not fit between the camera and the target at distance {distance:g} m"
            )
    forward = solve_chief_rays(center, target[None, :], stack).directions[0]
    return Camera(center, roll_rotation(roll) @ look_rotation(forward), lens, stack)
