"""The physical camera: pose + lens/sensor + optional flat refractive interfaces.

World → camera: X_c = R (X − C), with C the entrance-pupil centre and R a rotation
(rows = the camera's x (right), y (down) and z (optical axis) axes in the world
frame, OpenCV convention). ``pixel_to_ray`` is exact (undistortion to 1e-12, exact
Snell tracing); ``project`` solves the refraction by Newton (``forward.py``) to
1e-12 in sin θ, i.e. far below 1e-6 px.
"""

import logging
from dataclasses import dataclass

import numpy as np

from simulator.optics.forward import solve_chief_rays
from simulator.optics.interfaces import FlatInterfaces, trace
from simulator.optics.lens import Lens
from simulator.optics.rays import Rays, as_points

logger = logging.getLogger(__name__)

#: Points processed per block in ``project`` (keeps temporaries in cache).
BLOCK = 16384


@dataclass(frozen=True, eq=False)
class Camera:
    """A camera looking into water through flat windows (or straight into air).

    Attributes
    ----------
    center : ndarray, shape (3,)
        Entrance-pupil centre C in the world frame, m.
    rotation : ndarray, shape (3, 3)
        Proper rotation R from world to camera coordinates (X_c = R (X − C)).
    lens : Lens
        Intrinsics, distortion and sensor tilt.
    interfaces : FlatInterfaces or None
        Refractive planes between the camera and the measurement volume; None for a
        camera in the same medium as the points.

    Examples
    --------
    A camera 0.5 m up the Z axis looking toward −Z (image x along +X, rows along −Y),
    in air, then behind a 10 mm PMMA window whose wet face is at Z = 0.09 m:

    >>> import numpy as np
    >>> import simulator
    >>> lens = simulator.Lens(focal_length=0.05, pixel_pitch=10e-6, sensor_size=(640, 480))
    >>> facing = np.diag([1.0, -1.0, -1.0])  # rows: the camera's x, y, z in the world
    >>> in_air = simulator.Camera([0.0, 0.0, 0.5], facing, lens)
    >>> window = simulator.flat_window([0.0, 0.0, -1.0], -0.1, 0.01)  # normal toward the water
    >>> behind_glass = simulator.Camera([0.0, 0.0, 0.5], facing, lens, window)
    >>> point = np.array([[1e-3, 1e-3, 0.0]])  # m
    >>> in_air.project(point), behind_glass.project(point).round(3)  # px
    (array([[329.5, 229.5]]), array([[330.043, 228.957]]))

    The ray of that pixel, in the water, passes through the point:

    >>> ray = behind_glass.pixel_to_ray(behind_glass.project(point))
    >>> ray.origins.round(5)  # where it leaves the glass, m
    array([[0.00086, 0.00086, 0.09   ]])
    >>> bool(np.linalg.norm(np.cross(point - ray.origins, ray.directions)) < 1e-12)
    True

    A point on the camera's side of the window is not imaged:

    >>> behind_glass.project([[0.0, 0.0, 0.2]])
    array([[nan, nan]])
    """

    center: np.ndarray
    rotation: np.ndarray
    lens: Lens
    interfaces: FlatInterfaces | None = None

    def __post_init__(self) -> None:
        center = np.array(self.center, dtype=np.float64)
        if center.shape != (3,) or not np.isfinite(center).all():
            raise ValueError(f"Camera.center must be a finite 3-vector in m; got {self.center!r}")
        rotation = np.array(self.rotation, dtype=np.float64)
        if rotation.shape != (3, 3) or not np.isfinite(rotation).all():
            raise ValueError(f"Camera.rotation must be a finite 3x3 matrix; got {self.rotation!r}")
        error = np.max(np.abs(rotation @ rotation.T - np.eye(3)))
        if error > 1e-9 or np.linalg.det(rotation) <= 0:
            raise ValueError(
                "Camera.rotation must be a proper rotation (R Rᵀ = I, det R = +1); "
                f"got |R Rᵀ − I| = {error:.3g}, det R = {np.linalg.det(rotation):.6g}"
            )
        if not isinstance(self.lens, Lens):
            raise ValueError(f"Camera.lens must be a Lens; got {type(self.lens).__name__}")
        if self.interfaces is not None:
            if not isinstance(self.interfaces, FlatInterfaces):
                raise ValueError(
                    "Camera.interfaces must be FlatInterfaces or None; "
                    f"got {type(self.interfaces).__name__}"
                )
            h0 = self.interfaces.camera_height(center)
            if not h0 > 0:
                raise ValueError(
                    f"Camera.center {center.tolist()} must lie on the camera side of the first "
                    f"interface; its signed distance to it is {h0!r} m"
                )
        center.setflags(write=False)
        rotation.setflags(write=False)
        object.__setattr__(self, "center", center)
        object.__setattr__(self, "rotation", rotation)

    @property
    def axis(self) -> np.ndarray:
        """Optical axis (unit, world frame), shape (3,)."""
        return self.rotation[2].copy()

    def directions_to_pixels(self, directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pixels of world-frame directions from the pupil (not necessarily unit).

        Parameters
        ----------
        directions : ndarray, shape (N, 3)
            Directions of rays leaving C in medium 0; NaN rows are invalid.

        Returns
        -------
        xy : ndarray, shape (N, 2)
            Pixel coordinates, px; NaN where not visible.
        visible : ndarray of bool, shape (N,)
            In front of the camera, inside the distortion's physical domain and on
            the sensor.
        """
        cam = directions @ self.rotation.T
        depth = cam[:, 2]
        ahead = depth > 0
        with np.errstate(divide="ignore", invalid="ignore"):
            xn = cam[:, :2] / np.where(ahead, depth, np.nan)[:, None]
        xy, valid = self.lens.normalized_to_pixel(xn)
        visible = ahead & valid & self.lens.on_sensor(xy)
        xy[~visible] = np.nan
        return xy, visible

    def project(self, points: np.ndarray) -> np.ndarray:
        """Pixel positions of world points (exact refraction, Newton to 1e-12).

        The camera protocol of docs/conventions.md §6: a NaN row wherever the point is not imaged.

        Parameters
        ----------
        points : array_like, shape (N, 3)
            World points, m (finite).

        Returns
        -------
        ndarray, shape (N, 2)
            Pixel coordinates (x = column, y = row), px; NaN rows for points behind
            the camera, on the camera's side of the last interface (in the air or
            inside the glass), beyond the fold of the distortion, or off the sensor.
        """
        return self.project_visible(points)[0]

    def project_visible(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`project` together with the visibility mask.

        Parameters
        ----------
        points : array_like, shape (N, 3)
            World points, m (finite).

        Returns
        -------
        xy : ndarray, shape (N, 2)
            Pixel coordinates (x = column, y = row), px; NaN where not visible.
        visible : ndarray of bool, shape (N,)
            False for points behind the camera, on the camera's side of the last
            interface (in the air or inside the glass), beyond the fold of the
            distortion, or off the sensor; equal to ``isfinite(xy).all(axis=1)``.
        """
        points = as_points(points, 3, "points")
        xy = np.empty((len(points), 2))
        visible = np.empty(len(points), dtype=bool)
        for lo in range(0, len(points), BLOCK):
            block = points[lo : lo + BLOCK]
            if self.interfaces is None:
                directions = block - self.center
            else:
                directions = solve_chief_rays(self.center, block, self.interfaces).directions
            xy[lo : lo + BLOCK], visible[lo : lo + BLOCK] = self.directions_to_pixels(directions)
        return xy, visible

    def pixel_directions(self, xy: np.ndarray) -> np.ndarray:
        """Unit world-frame directions (N, 3) of the rays leaving C for pixels ``xy``."""
        xn = self.lens.pixel_to_normalized(xy)
        cam = np.empty((len(xy), 3))
        cam[:, :2] = xn
        cam[:, 2] = 1.0
        cam /= np.sqrt(np.einsum("ij,ij->i", cam, cam))[:, None]
        return cam @ self.rotation

    def pixel_to_ray(self, xy: np.ndarray) -> Rays:
        """The exact ray imaged at each pixel, in the last medium.

        Parameters
        ----------
        xy : array_like, shape (N, 2)
            Pixel coordinates, px (finite; positions off the sensor are allowed).

        Returns
        -------
        Rays
            With a window: origin where the ray enters the last medium (water) and
            its direction there. Without: origin C and the direction in air. NaN for
            pixels with no physical ray (beyond the distortion's fold, rays that miss
            the window or are totally internally reflected).
        """
        xy = as_points(xy, 2, "pixel coordinates xy")
        origins = np.empty((len(xy), 3))
        directions = np.empty((len(xy), 3))
        for lo in range(0, len(xy), BLOCK):
            block = self.pixel_directions(xy[lo : lo + BLOCK])
            if self.interfaces is None:
                origins[lo : lo + BLOCK] = self.center
                directions[lo : lo + BLOCK] = block
            else:
                path = trace(np.broadcast_to(self.center, block.shape), block, self.interfaces)
                origins[lo : lo + BLOCK] = path.points[-1]
                directions[lo : lo + BLOCK] = path.directions[-1]
        return Rays(origins=origins, directions=directions)
