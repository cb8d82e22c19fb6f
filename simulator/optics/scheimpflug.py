"""Thin-lens focus: Scheimpflug sensor tilt for a plane, and defocus blur.

Model
-----
The lens is an ideal thin lens of focal length f at the entrance pupil C, aperture
diameter D = f/N. In camera coordinates (z along the axis, depths measured
perpendicular to the lens plane) a point at depth z_o images at depth

    z_i = f z_o / (z_o − f)                          (Gauss)

on its chief ray (through C): I = (z_i/z_o)·V, an exact collineation. The image is
drawn mirrored in front of the lens, like the pinhole sensor of ``lens.py``; this
point reflection changes no distance or angle. Hence the image of an object plane is
a plane, and the two meet the lens plane in one line — the Scheimpflug condition,
tan θ_i = M tan θ_o with M = z_i/z_o on the axis and θ measured from the lens plane.

Through flat windows the object is replaced by its virtual image seen along the
chief ray (``forward.py``): flat refraction is astigmatic, so each point has a
sagittal and a tangential virtual image, both at the paraxial apparent depth near
normal incidence. The sheet is focused on their mean. Because refraction makes the
apparent sheet only approximately planar, the sensor plane is fitted by least
squares through the images of a grid of sheet points: its normal gives (τ_x, τ_y)
(normal = (sin τ_y, −cos τ_y sin τ_x, cos τ_y cos τ_x) in the camera frame, OpenCV
tilt model) and its intercept with the axis the image distance s_i (principal
distance of the pinhole model), so that the pixel model is exactly the chief-ray
image on the physical sensor.

Blur: the cone from the aperture to an image point at depth z_i, cut at the depth t
where the chief ray meets the sensor, is a disc of diameter D |t − z_i| / z_i (the
sensor tilt makes it slightly elliptical; neglected). With astigmatism the blur
patch is an ellipse with axes given by this formula for the sagittal and the
tangential image; ``defocus_blur`` returns the major axis. In object space this is
Adrian's d_blur = M² |Δz| / (N (1 + M)) for an axial defocus Δz (docs/imaging.md §1).
Lens distortion is ignored in the blur and focus geometry (it displaces images
within the sensor plane, not along the chief ray).
"""

import dataclasses
import logging
from dataclasses import dataclass

import numpy as np

from simulator.optics.camera import Camera
from simulator.optics.forward import solve_chief_rays, virtual_image_distances
from simulator.optics.lens import sensor_normal, tilt_from_normal
from simulator.optics.rays import as_points

logger = logging.getLogger(__name__)


def thin_lens_image_distance(focal_length: float, object_distance: np.ndarray) -> np.ndarray:
    """Gauss image distance z_i = f z_o/(z_o − f), m; NaN where z_o ≤ f (no real image)."""
    z_o = np.asarray(object_distance, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(z_o > focal_length, focal_length * z_o / (z_o - focal_length), np.nan)


def image_points(camera: Camera, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Thin-lens images of world points, camera frame (mirrored in front of the lens).

    Parameters
    ----------
    camera : Camera
        Its ``lens.focal_length`` is the thin-lens f.
    points : array_like, shape (N, 3)
        World points, m.

    Returns
    -------
    sagittal, tangential : ndarray, shape (N, 3)
        Image points of the sagittal and tangential virtual objects, camera frame,
        m (equal without a window); NaN where the point has no real image.
    """
    points = as_points(points, 3, "points")
    if camera.interfaces is None:
        rel = points - camera.center
        dist = np.sqrt(np.einsum("ij,ij->i", rel, rel))
        with np.errstate(divide="ignore", invalid="ignore"):
            directions = rel / dist[:, None]  # NaN for a point at the pupil
        dist_sag = dist_tan = dist
    else:
        chief = solve_chief_rays(camera.center, points, camera.interfaces)
        directions = chief.directions
        dist_sag, dist_tan = virtual_image_distances(chief, camera.interfaces)
    cam_dir = directions @ camera.rotation.T
    images = []
    for dist in (dist_sag, dist_tan):
        virtual = cam_dir * dist[:, None]
        z_o = virtual[:, 2]
        z_i = thin_lens_image_distance(camera.lens.focal_length, z_o)
        with np.errstate(divide="ignore", invalid="ignore"):
            images.append(virtual * (z_i / z_o)[:, None])
    return images[0], images[1]


def defocus_blur(camera: Camera, points: np.ndarray) -> np.ndarray:
    """Defocus blur diameter on the sensor (major axis of the blur ellipse), px.

    Parameters
    ----------
    camera : Camera
        Uses the lens' f, f-number, image distance and sensor tilt.
    points : array_like, shape (N, 3)
        World points, m.

    Returns
    -------
    ndarray, shape (N,)
        D |t − z_i| / z_i / pixel pitch, the larger of the sagittal and tangential
        values (module docstring); NaN where the point has no real image or its
        chief ray misses the sensor plane.
    """
    lens = camera.lens
    normal = sensor_normal(lens.tau_x, lens.tau_y)
    blur = np.full(len(as_points(points, 3, "points")), -np.inf)
    for image in image_points(camera, points):
        z_i = image[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            unit_depth = image / z_i[:, None]  # chief-ray direction with z = 1
            t = lens.image_distance * normal[2] / (unit_depth @ normal)
            t = np.where(t > 0, t, np.nan)
            blur = np.maximum(blur, lens.aperture_diameter * np.abs(t - z_i) / z_i)
    return blur / lens.pixel_pitch


@dataclass(frozen=True)
class SheetFocus:
    """Focus settings that image an object plane sharply (thin lens, Scheimpflug).

    Attributes
    ----------
    tau_x, tau_y : float
        Sensor tilt, rad (OpenCV tilted model).
    image_distance : float
        Lens-to-sensor distance on the axis (principal distance), m.
    focus_distance : float
        Object-side in-focus distance on the axis, m (apparent, air-equivalent,
        through a window).
    magnification : float
        image_distance / focus_distance.
    rms_residual : float
        Root-mean-square distance of the grid's images from the fitted sensor plane
        (image side), m: zero for a plane seen without refraction.
    n_points : int
        Grid points of the plane used in the fit.
    """

    tau_x: float
    tau_y: float
    image_distance: float
    focus_distance: float
    magnification: float
    rms_residual: float
    n_points: int


def _plane_points(
    camera: Camera, plane_point: np.ndarray, plane_normal: np.ndarray, grid: int
) -> np.ndarray:
    width, height = camera.lens.sensor_size
    gx, gy = np.meshgrid(np.linspace(0, width - 1, grid), np.linspace(0, height - 1, grid))
    pixels = np.column_stack([gx.ravel(), gy.ravel()])
    rays = camera.pixel_to_ray(pixels)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = ((plane_point - rays.origins) @ plane_normal) / (rays.directions @ plane_normal)
    hits = rays.point_at(np.where(s >= 0, s, np.nan))
    return hits[np.isfinite(hits).all(axis=1)]


def _axis_point(camera: Camera, plane_point: np.ndarray, plane_normal: np.ndarray) -> np.ndarray:
    ray = camera.pixel_to_ray(np.array([camera.lens.principal_point]))
    with np.errstate(divide="ignore", invalid="ignore"):
        s = ((plane_point - ray.origins[0]) @ plane_normal) / (ray.directions[0] @ plane_normal)
    if not (np.isfinite(s) and s >= 0):
        raise ValueError(
            f"the optical axis of the camera at {camera.center.tolist()} does not meet the plane "
            f"through {plane_point.tolist()} with normal {plane_normal.tolist()}"
        )
    return ray.point_at(s)


def scheimpflug_focus(
    camera: Camera,
    *,
    plane_point: object = (0.0, 0.0, 0.0),
    plane_normal: object = (0.0, 0.0, 1.0),
    grid: int = 15,
) -> SheetFocus:
    """Sensor tilt and image distance that focus ``camera`` on a plane (e.g. the sheet Z = 0).

    Parameters
    ----------
    camera : Camera
        Pose, window and lens (its focal length is the thin-lens f; its current
        tilt and image distance only choose which part of the plane is sampled).
    plane_point, plane_normal : array_like, shape (3,)
        A point of the object plane and its normal (any length > 0), m.
    grid : int
        The plane is sampled where a grid × grid lattice of pixels spanning the
        sensor sees it.

    Returns
    -------
    SheetFocus
    """
    point = np.asarray(plane_point, dtype=np.float64)
    normal = np.asarray(plane_normal, dtype=np.float64)
    if point.shape != (3,) or not np.isfinite(point).all():
        raise ValueError(f"plane_point must be a finite 3-vector in m; got {plane_point!r}")
    norm = np.linalg.norm(normal) if normal.shape == (3,) else 0.0
    if not (np.isfinite(norm) and norm > 0):
        raise ValueError(f"plane_normal must be a finite non-zero 3-vector; got {plane_normal!r}")
    normal = normal / norm
    if grid < 3:
        raise ValueError(f"grid must be >= 3; got {grid!r}")
    points = _plane_points(camera, point, normal, grid)
    sag, tan = image_points(camera, points) if len(points) else (points, points)
    images = 0.5 * (sag + tan)
    images = images[np.isfinite(images).all(axis=1)]
    if len(images) < 3:
        raise ValueError(
            f"only {len(images)} points of the plane through {point.tolist()} with normal "
            f"{normal.tolist()} are seen by the camera with a real image; need >= 3"
        )
    design = np.column_stack([images[:, 0], images[:, 1], np.ones(len(images))])
    (a, b, c), *_ = np.linalg.lstsq(design, images[:, 2], rcond=None)
    scale = np.sqrt(1.0 + a * a + b * b)
    residual = (images[:, 2] - design @ np.array([a, b, c])) / scale
    tau_x, tau_y = tilt_from_normal(np.array([-a, -b, 1.0]) / scale)
    focus = camera.lens.focal_length * c / (c - camera.lens.focal_length)
    result = SheetFocus(
        tau_x=tau_x,
        tau_y=tau_y,
        image_distance=float(c),
        focus_distance=float(focus),
        magnification=float(c / focus),
        rms_residual=float(np.sqrt(np.mean(residual**2))),
        n_points=len(images),
    )
    logger.debug("Scheimpflug focus: %s", result)
    return result


def focus_on_plane(
    camera: Camera,
    *,
    plane_point: object = (0.0, 0.0, 0.0),
    plane_normal: object = (0.0, 0.0, 1.0),
    tilt: bool = True,
    grid: int = 15,
) -> Camera:
    """The camera with its sensor placed (and tilted) to focus on a plane.

    Parameters
    ----------
    camera : Camera
        The camera to refocus (pose and window kept).
    plane_point, plane_normal : array_like, shape (3,)
        The object plane.
    tilt : bool
        True: Scheimpflug tilt from :func:`scheimpflug_focus`. False: untilted sensor
        focused on the point where the optical axis meets the plane (a conventional
        camera; the rest of an oblique plane is out of focus).
    grid : int
        Sampling of the plane for the tilt fit.

    Returns
    -------
    Camera
        A copy with ``lens.tau_x``, ``lens.tau_y`` and ``lens.image_distance`` set.

    Examples
    --------
    A camera at f/4 looking at the sheet Z = 0 from 30° through a window: the
    Scheimpflug tilt keeps the whole sheet in focus, where an untilted sensor blurs
    points 1 cm either side of the centre over about a pixel
    (:func:`simulator.optics.defocus_blur`).

    >>> import numpy as np
    >>> import simulator
    >>> from simulator.optics import defocus_blur
    >>> lens = simulator.Lens(focal_length=0.05, pixel_pitch=10e-6, sensor_size=(640, 480),
    ...                       f_number=4.0)
    >>> window = simulator.WindowSpec(water_path=0.1, glass_thickness=0.01)
    >>> camera = simulator.look_at_camera([0.0, 0.0, 0.0], lens, distance=0.5,
    ...                                   azimuth=np.radians(30), window=window)
    >>> tilted = simulator.focus_on_plane(camera)  # the sheet Z = 0, by default
    >>> untilted = simulator.focus_on_plane(camera, tilt=False)
    >>> tilt = float(np.degrees(tilted.lens.tau_y))  # the sensor's tilt, °
    >>> round(tilt, 2), round(tilted.lens.image_distance * 1e3, 2)  # °, lens to sensor in mm
    (-2.94, 55.93)
    >>> sheet = np.array([[-0.01, 0.0, 0.0], [0.0, 0.0, 0.0], [0.01, 0.0, 0.0]])  # m
    >>> defocus_blur(tilted, sheet).round(2), defocus_blur(untilted, sheet).round(2)  # px
    (array([0.03, 0.03, 0.02]), array([1.17, 0.  , 1.19]))
    """
    if tilt:
        focus = scheimpflug_focus(
            camera, plane_point=plane_point, plane_normal=plane_normal, grid=grid
        )
        lens = dataclasses.replace(
            camera.lens, tau_x=focus.tau_x, tau_y=focus.tau_y, image_distance=focus.image_distance
        )
    else:
        point = np.asarray(plane_point, dtype=np.float64)
        normal = np.asarray(plane_normal, dtype=np.float64)
        normal = normal / np.linalg.norm(normal)
        flat_lens = dataclasses.replace(camera.lens, tau_x=0.0, tau_y=0.0)
        untilted = dataclasses.replace(camera, lens=flat_lens)
        on_axis = _axis_point(untilted, point, normal)
        sag, tan = image_points(untilted, on_axis)
        depth = 0.5 * (sag[0, 2] + tan[0, 2])
        if not np.isfinite(depth):
            raise ValueError(
                f"the plane point on the optical axis {on_axis[0].tolist()} has no real image"
            )
        lens = dataclasses.replace(untilted.lens, image_distance=float(depth))
    return dataclasses.replace(camera, lens=lens)
