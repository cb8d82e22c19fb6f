"""An overview picture of a rig, drawn offscreen with pyrender.

The picture shows, in the world frame of the rig:

- the rig's tank (:mod:`simulator.tank`: the icosahedron or the box; none for a free
  tank), pale and semi-transparent, with its edges drawn;
- each camera: a small body and lens barrel behind the entrance pupil, labelled with
  its name, its viewing frustum (a pyramid from the pupil along the rays of the four
  sensor corners, ``frustum_length`` long), the part of its window it looks through
  (the glass between the corner rays' crossings of the window's faces, in the camera's
  colour), and the four corner rays traced through the window (air → glass → water,
  refracted exactly) down to the sheet's mid-plane, where they outline the camera's
  footprint;
- the laser sheet: a translucent green slab;
- optionally the calibration plate at one traverse position (a thin dark box with
  its dots) and particles (small spheres);
- the world frame's X (red), Y (green), Z (blue) axes, drawn from the world origin
  (the sheet's centre, inside the tank) and labelled;
- a caption in a white band at the top: the rig and what the axes show.

It is a figure, not a measurement: the accuracy path is the analytic renderer. The PNG
is readable by everyone (mode 0644, as every figure synptv writes), not only its owner.
"""

import itertools
import logging
from dataclasses import dataclass, replace

import numpy as np
import trimesh

from simulator.optics.interfaces import trace
from simulator.optics.placement import look_rotation, viewing_direction
from simulator.pyrender_view import import_pyrender, opengl_pose
from simulator.tank import box_tank, icosahedral_tank

logger = logging.getLogger(__name__)

#: Camera colours (RGB in [0, 1]), cycled.
CAMERA_COLOURS = (
    (0.85, 0.33, 0.10),
    (0.00, 0.45, 0.74),
    (0.49, 0.18, 0.56),
    (0.47, 0.67, 0.19),
)
SHEET_COLOUR = (0.15, 0.85, 0.25)
TANK_COLOUR = (0.55, 0.75, 0.95)
EDGE_COLOUR = (0.25, 0.35, 0.50)
AXIS_COLOURS = ((0.85, 0.1, 0.1), (0.1, 0.55, 0.1), (0.1, 0.2, 0.85))


@dataclass(frozen=True)
class SceneOptions:
    """How to draw the overview picture.

    Attributes
    ----------
    size : tuple of int
        (width, height) of the picture, px.
    view_azimuth, view_elevation : float
        Direction of the viewpoint seen from the centre of the drawn objects, rad
        (azimuth about Y from +Z toward +X, elevation toward +Y).
    fov : float
        Vertical field of view of the overview camera, rad.
    frustum_length : float
        Length of the camera frusta along their corner rays, m.
    show_sheet, show_tank, show_rays, show_axes : bool
        Draw the laser sheet, the tank, the traced corner rays, the axes of the world
        frame (with the caption).
    particle_radius : float
        Radius of the particle spheres, m (exaggerated so that they are visible).
    """

    size: tuple[int, int] = (1600, 1000)
    view_azimuth: float = float(np.deg2rad(-15.0))
    view_elevation: float = float(np.deg2rad(30.0))
    fov: float = float(np.deg2rad(30.0))
    frustum_length: float = 0.15
    show_sheet: bool = True
    show_tank: bool = True
    show_rays: bool = True
    show_axes: bool = True
    particle_radius: float = 1.5e-3

    def __post_init__(self) -> None:
        width, height = self.size
        if (
            int(width) != width
            or int(height) != height
            or not (16 <= width <= 8192)
            or not (16 <= height <= 8192)
        ):
            raise ValueError(
                f"SceneOptions.size must be (width, height) in 16–8192 px; got {self.size!r}"
            )
        for name in ("view_azimuth", "view_elevation"):
            if not np.isfinite(getattr(self, name)):
                raise ValueError(f"SceneOptions.{name} must be finite (rad)")
        if abs(self.view_elevation) >= np.pi / 2 - 1e-3:
            raise ValueError(
                "SceneOptions.view_elevation must be within ±90° (rad); "
                f"got {self.view_elevation!r}"
            )
        if not (0 < self.fov < np.pi):
            raise ValueError(f"SceneOptions.fov must be in (0, π) rad; got {self.fov!r}")
        for name in ("frustum_length", "particle_radius"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"SceneOptions.{name} must be finite and > 0 m; got {value!r}")


@dataclass(frozen=True, eq=False)
class _Item:
    mesh: trimesh.Trimesh
    rgba: tuple[float, float, float, float]
    double_sided: bool = False
    poses: np.ndarray | None = None  # instancing


@dataclass(frozen=True)
class _Label:
    text: str
    anchor: np.ndarray  # (3,), m
    rgb: tuple[float, float, float]


def _segment(a: np.ndarray, b: np.ndarray, radius: float) -> trimesh.Trimesh | None:
    if np.linalg.norm(b - a) < 1e-9:
        return None
    return trimesh.creation.cylinder(radius=radius, segment=np.array([a, b]), sections=10)


def _segments(pairs: list[tuple[np.ndarray, np.ndarray]], radius: float) -> trimesh.Trimesh | None:
    parts = [m for a, b in pairs if (m := _segment(np.asarray(a), np.asarray(b), radius))]
    return trimesh.util.concatenate(parts) if parts else None


def _oriented_box(extents, center, rotation_rows) -> trimesh.Trimesh:
    transform = np.eye(4)
    transform[:3, :3] = np.asarray(rotation_rows).T
    transform[:3, 3] = center
    return trimesh.creation.box(extents=extents, transform=transform)


def _corner_pixels(lens) -> np.ndarray:
    width, height = lens.sensor_size
    return np.array(
        [[-0.5, -0.5], [width - 0.5, -0.5], [width - 0.5, height - 0.5], [-0.5, height - 0.5]]
    )


def _window_item(camera, directions: np.ndarray, colour) -> _Item | None:
    """The glass a camera looks through: the hull of its four corner rays' crossings
    of the window's faces."""
    if camera.interfaces is None or len(directions) != 4:
        return None
    path = trace(np.broadcast_to(camera.center, directions.shape), directions, camera.interfaces)
    crossings = np.vstack(path.points[1:3])
    if not np.isfinite(crossings).all():
        return None
    return _Item(trimesh.convex.convex_hull(crossings), (*colour, 0.55), True)


def _camera_items(camera, colour, sheet_z: float, options: SceneOptions) -> list[_Item]:
    items = []
    rot, c = camera.rotation, camera.center
    axis = rot[2]
    dark = (0.18, 0.18, 0.20, 1.0)
    # Body and lens barrel behind the pupil.
    barrel = trimesh.creation.cylinder(
        radius=0.022, segment=np.array([c - 0.07 * axis, c]), sections=24
    )
    items.append(_Item(barrel, dark))
    body = _oriented_box((0.075, 0.065, 0.10), c - 0.12 * axis, rot)
    items.append(_Item(body, (*colour, 1.0)))
    # Frustum from the pupil along the sensor-corner rays (in air).
    directions = camera.pixel_directions(_corner_pixels(camera.lens))
    ok = np.isfinite(directions).all(axis=1)
    if ok.all():
        base = c + options.frustum_length * directions
        vertices = np.vstack([c, base])
        faces = [[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 4, 1]]
        items.append(_Item(trimesh.Trimesh(vertices, faces, process=False), (*colour, 0.22), True))
        edges = [(c, p) for p in base] + [(base[i], base[(i + 1) % 4]) for i in range(4)]
        items.append(_Item(_segments(edges, 0.0012), (*colour, 1.0)))
        window = _window_item(camera, directions, colour)
        if window is not None:
            items.append(window)
    else:
        logger.debug("scene: a sensor corner of a camera has no ray; frustum not drawn")
    if options.show_rays and ok.any():
        items += _ray_items(camera, directions[ok], colour, sheet_z)
    return items


def _ray_items(camera, directions, colour, sheet_z: float) -> list[_Item]:
    c = camera.center
    origins = np.broadcast_to(c, directions.shape)
    if camera.interfaces is not None:
        path = trace(origins, directions, camera.interfaces)
        points, last = path.points, path.directions[-1]
    else:
        points, last = origins[None], directions
    pairs = []
    footprint = []
    for i in range(len(directions)):
        chain = [p[i] for p in points if np.isfinite(p[i]).all()]
        if len(chain) != len(points) or not np.isfinite(last[i]).all() or abs(last[i][2]) < 1e-9:
            continue
        s = (sheet_z - chain[-1][2]) / last[i][2]
        if s <= 0:
            continue
        end = chain[-1] + s * last[i]
        chain.append(end)
        footprint.append(end)
        pairs += list(itertools.pairwise(chain))
    items = []
    if pairs:
        items.append(_Item(_segments(pairs, 0.0008), (*colour, 1.0)))
    if len(footprint) == 4:
        outline = [(footprint[i], footprint[(i + 1) % 4]) for i in range(4)]
        items.append(_Item(_segments(outline, 0.0012), (*colour, 1.0)))
    return items


def vessel_mesh(tank) -> trimesh.Trimesh | None:
    """The wet surface of a rig's tank (:class:`simulator.rigs.Tank`); None for a free tank."""
    if tank.kind == "icosahedron":
        return icosahedral_tank(tank.inradius)
    if tank.kind == "box":
        return box_tank(tank.size, tank.yaw)
    return None


def _tank_items(vessel: trimesh.Trimesh) -> list[_Item]:
    # One item per face so that transparent faces are sorted back to front.
    items = [
        _Item(
            trimesh.Trimesh(vessel.vertices[face], [[0, 1, 2]], process=False),
            (*TANK_COLOUR, 0.10),
            True,
        )
        for face in vessel.faces
    ]
    # The edges between faces that meet at an angle (not a box wall's diagonal).
    creases = vessel.face_adjacency_edges[vessel.face_adjacency_angles > 1e-6]
    edges = [(vessel.vertices[a], vessel.vertices[b]) for a, b in creases]
    items.append(_Item(_segments(edges, 0.0015), (*EDGE_COLOUR, 1.0)))
    return items


def _plate_items(plate, plane: int) -> list[_Item]:
    if not 0 <= plane < len(plate.poses):
        raise ValueError(
            f"plate_plane must index one of the {len(plate.poses)} traverse positions; "
            f"got {plane!r}"
        )
    design, pose = plate.design, plate.poses[plane]
    width = (design.columns + 1) * design.pitch
    height = (design.rows + 1) * design.pitch
    thickness = max(design.thickness, 1e-3)  # thicker than life, to be visible
    normal = pose.rotation[:, 2]
    centre = np.array([0.0, 0.0, pose.z_actual]) - 0.5 * thickness * normal
    board = _oriented_box((width, height, thickness), centre, pose.rotation.T)
    dots = plate.dot_centres(plane) + 0.2e-3 * normal
    disc = trimesh.creation.cylinder(radius=0.5 * design.dot_diameter, height=0.2e-3, sections=12)
    poses = np.tile(np.eye(4), (len(dots), 1, 1))
    poses[:, :3, :3] = pose.rotation
    poses[:, :3, 3] = dots
    return [
        _Item(board, (0.12, 0.12, 0.14, 1.0)),
        _Item(disc, (0.95, 0.95, 0.92, 1.0), poses=poses),
    ]


def axes_length(rig) -> float:
    """Length of the drawn world axes, m: 1.2 times the sheet's larger side, so that the
    arrowheads stand clear of the sheet (and of a plate on it) inside the tank."""
    return 1.2 * float(max(rig.sheet.size[:2]))


def _axes_items(origin: np.ndarray, length: float) -> list[_Item]:
    """The X, Y, Z arrows from ``origin``, ``length`` long, arrowheads included."""
    items = []
    head = 0.18 * length
    for k, colour in enumerate(AXIS_COLOURS):
        base = origin + (length - head) * np.eye(3)[k]
        shaft = _segment(origin, base, 0.03 * length)
        cone = trimesh.creation.cone(radius=0.08 * length, height=head, sections=16)
        transform = trimesh.geometry.align_vectors([0.0, 0.0, 1.0], np.eye(3)[k])
        transform[:3, 3] = base
        cone.apply_transform(transform)
        items.append(_Item(trimesh.util.concatenate([shaft, cone]), (*colour, 1.0)))
    return items


def _scene_items(rig, plate, plate_plane, particles, options) -> tuple[list[_Item], list[_Label]]:
    sheet = rig.sheet
    sheet_z = float(sheet.centre[2])
    items: list[_Item] = []
    labels: list[_Label] = []
    vessel = vessel_mesh(rig.tank)
    if options.show_tank and vessel is not None:
        items += _tank_items(vessel)
    for i, (name, camera) in enumerate(zip(rig.camera_names, rig.cameras, strict=True)):
        colour = CAMERA_COLOURS[i % len(CAMERA_COLOURS)]
        items += _camera_items(camera, colour, sheet_z, options)
        labels.append(
            _Label(name, camera.center - 0.12 * camera.rotation[2] + [0.0, 0.06, 0.0], colour)
        )
    if plate is not None:
        items += _plate_items(plate, plate_plane)
    if particles is not None:
        pts = np.asarray(particles, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 3 or not np.isfinite(pts).all():
            raise ValueError(f"particles must be a finite (N, 3) array in m; got shape {pts.shape}")
        if len(pts):
            sphere = trimesh.creation.icosphere(subdivisions=1, radius=options.particle_radius)
            poses = np.tile(np.eye(4), (len(pts), 1, 1))
            poses[:, :3, 3] = pts
            items.append(_Item(sphere, (0.55, 0.05, 0.05, 1.0), poses=poses))
    if options.show_sheet:
        slab = trimesh.creation.box(extents=sheet.size)
        slab.apply_translation(sheet.centre)
        items.append(_Item(slab, (*SHEET_COLOUR, 0.40), True))
    if options.show_axes:
        # At the world origin: the centre of the sheet, inside the tank.
        origin, length = np.zeros(3), axes_length(rig)
        items += _axes_items(origin, length)
        labels += [
            _Label(axis, origin + 1.15 * length * np.eye(3)[k], rgb)
            for k, (axis, rgb) in enumerate(zip("XYZ", AXIS_COLOURS, strict=True))
        ]
    return items, labels


def caption(rig) -> str:
    """The caption written on the picture (ASCII: the picture's font has no µ)."""
    return (
        f"rig {rig.name}: world axes X, Y, Z from the origin (centre of the laser sheet), "
        f"{axes_length(rig) * 1e3:.0f} mm long"
    )


def _item_points(items: list[_Item]) -> np.ndarray:
    """Vertices of everything drawn (box corners for instanced meshes), (M, 3), m."""
    corners = []
    for item in items:
        if item.mesh is None:
            continue
        if item.poses is None:
            corners.append(np.asarray(item.mesh.vertices))
            continue
        box = trimesh.bounds.corners(item.mesh.bounds)
        centres = item.poses[:, :3, 3]
        corners.append(centres.min(axis=0) + box)
        corners.append(centres.max(axis=0) + box)
    return np.vstack(corners)


def _view_pose(items: list[_Item], options: SceneOptions) -> tuple[np.ndarray, float, float]:
    """Overview camera pose (OpenGL, 4 × 4) framing everything, its distance and depth span.

    The viewing direction is fixed by the options; the look-at point and the distance
    are chosen so that every bounding-box corner lies inside the field of view with a
    small margin, and the drawing is centred.
    """
    points = _item_points(items)
    width, height = options.size
    tan_v = np.tan(0.5 * options.fov) * 0.94
    tan_h = tan_v * width / height
    u = viewing_direction(options.view_azimuth, options.view_elevation)
    rows = look_rotation(-u)  # camera x (right), y (down), z (forward) in the world
    centre = 0.5 * (points.min(axis=0) + points.max(axis=0))
    distance = 1.0
    for _ in range(4):  # re-centre on the projected extent, then refit the distance
        rel = (points - centre) @ rows.T
        distance = float(
            np.max(np.maximum(np.abs(rel[:, 0]) / tan_h, np.abs(rel[:, 1]) / tan_v) - rel[:, 2])
        )
        depth = distance + rel[:, 2]
        xn, yn = rel[:, 0] / depth, rel[:, 1] / depth
        shift_x = 0.5 * (xn.max() + xn.min())
        shift_y = 0.5 * (yn.max() + yn.min())
        centre = centre + distance * (shift_x * rows[0] + shift_y * rows[1])
    eye = centre + distance * u
    span = float(np.ptp((points - eye) @ rows[2]))
    return opengl_pose(eye, rows), distance, span


def render_scene(
    rig,
    *,
    plate=None,
    plate_plane: int = 0,
    particles: object = None,
    options: SceneOptions = SceneOptions(),
) -> np.ndarray:
    """Draw an overview picture of a rig (module docstring).

    Parameters
    ----------
    rig : Rig
        Cameras and their names, sheet and tank (:func:`simulator.rigs.load_rig`).
    plate : PhysicalPlate or None
        Calibration plate to draw (:func:`simulator.target.build_plate`).
    plate_plane : int
        Traverse position j of the plate.
    particles : array_like, shape (N, 3), or None
        Particle positions to draw, m.
    options : SceneOptions
        Size, viewpoint and what to draw.

    Returns
    -------
    ndarray, shape (H, W, 3), uint8
        The RGB picture (white background).
    """
    band = _caption_band(options)
    if not band:
        return _drawing(rig, plate, plate_plane, particles, options)
    # The drawing below a white band that holds the caption, the size unchanged.
    width, height = options.size
    body = replace(options, size=(width, height - band))
    top = np.full((band, width, 3), 255, dtype=np.uint8)
    _draw_caption(top, caption(rig))
    return np.vstack([top, _drawing(rig, plate, plate_plane, particles, body)])


def _drawing(rig, plate, plate_plane, particles, options: SceneOptions) -> np.ndarray:
    """The picture of :func:`render_scene` without its caption, ``options.size``."""
    pyrender = import_pyrender()
    items, labels = _scene_items(rig, plate, plate_plane, particles, options)
    scene = pyrender.Scene(bg_color=[1.0, 1.0, 1.0, 1.0], ambient_light=[0.35, 0.35, 0.35])
    for item in items:
        if item.mesh is None:
            continue
        rgba = [float(v) for v in item.rgba]
        material = pyrender.MetallicRoughnessMaterial(
            baseColorFactor=rgba,
            metallicFactor=0.0,
            roughnessFactor=0.9,
            alphaMode="BLEND" if rgba[3] < 1.0 else "OPAQUE",
            doubleSided=item.double_sided,
        )
        if item.poses is not None:
            mesh = pyrender.Mesh.from_trimesh(
                item.mesh, material=material, poses=item.poses, smooth=False
            )
            scene.add(mesh)
            continue
        # Centre each mesh on its node so that pyrender sorts transparent nodes by distance.
        centre = np.asarray(item.mesh.bounds).mean(axis=0)
        local = item.mesh.copy()
        local.apply_translation(-centre)
        pose = np.eye(4)
        pose[:3, 3] = centre
        scene.add(pyrender.Mesh.from_trimesh(local, material=material, smooth=False), pose=pose)
    view, distance, span = _view_pose(items, options)
    width, height = options.size
    camera = pyrender.PerspectiveCamera(
        yfov=options.fov,
        aspectRatio=width / height,
        znear=max(1e-3, 0.5 * (distance - span)),
        zfar=2.0 * (distance + span),
    )
    scene.add(camera, pose=view)
    # A key light from over the viewer's shoulder and a fill light from above.
    for tilt, intensity in ((np.deg2rad(15.0), 2.2), (np.deg2rad(60.0), 1.2)):
        light_pose = view.copy()
        rot = trimesh.transformations.rotation_matrix(tilt, [1.0, 0.0, 0.0])
        light_pose[:3, :3] = view[:3, :3] @ rot[:3, :3]
        scene.add(pyrender.DirectionalLight(color=np.ones(3), intensity=intensity), pose=light_pose)
    renderer = pyrender.OffscreenRenderer(width, height)
    try:
        color, _ = renderer.render(scene)
    finally:
        renderer.delete()
    logger.debug("scene of rig %r rendered at %dx%d px", rig.name, width, height)
    picture = np.ascontiguousarray(color[:, :, :3], dtype=np.uint8)
    _draw_labels(picture, labels, view, options)
    return picture


def _caption_band(options: SceneOptions) -> int:
    """Height of the caption's band at the top of the picture, px (0: no caption: no
    axes, or a picture too small to hold one)."""
    height = options.size[1]
    return round(0.05 * height) if options.show_axes and height >= 200 else 0


def _draw_caption(band: np.ndarray, text: str) -> None:
    """Write ``text`` in dark grey in the white ``band`` (in place), from its left,
    shrunk to fit its width and height."""
    import cv2

    height, width = band.shape[:2]
    margin = max(2, round(0.02 * width))
    scale = 1.0
    (w, h), _ = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, scale, 1)
    scale = min(0.45 * height / h, (width - 2 * margin) / w)
    (w, h), _ = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, scale, 1)
    corner = (margin, round(0.5 * (height + h)))
    cv2.putText(
        band,
        text,
        corner,
        cv2.FONT_HERSHEY_SIMPLEX,
        scale,
        (60, 60, 60),
        max(1, round(1.4 * scale)),
        cv2.LINE_AA,
    )


def _draw_labels(picture: np.ndarray, labels: list[_Label], view: np.ndarray, options) -> None:
    """Write each label at the picture position of its anchor (in place).

    ``view`` is the overview camera's OpenGL pose: its columns are the camera's right,
    up and backward axes in the world, its last column the eye.
    """
    import cv2

    height, width = picture.shape[:2]
    scale = 0.5 * height / np.tan(0.5 * options.fov)  # px per unit of x/depth
    font_scale = height / 1000.0
    for label in labels:
        x, y, z = view[:3, :3].T @ (label.anchor - view[:3, 3])
        if z >= 0:  # behind the viewer
            continue
        u, v = 0.5 * width + scale * x / -z, 0.5 * height - scale * y / -z
        (w, h), _ = cv2.getTextSize(label.text, cv2.FONT_HERSHEY_SIMPLEX, font_scale, 2)
        corner = (round(float(u) - 0.5 * w), round(float(v) + 0.5 * h))
        rgb = tuple(int(255 * 0.75 * c) for c in label.rgb)  # darkened to read on white
        for colour, thickness in (((255, 255, 255), 6), (rgb, 2)):
            cv2.putText(
                picture,
                label.text,
                corner,
                cv2.FONT_HERSHEY_SIMPLEX,
                font_scale,
                colour,
                thickness,
                cv2.LINE_AA,
            )
