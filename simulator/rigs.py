"""Camera rigs described by TOML files: presets ``paper-stereo``, ``conventional``,
``box-3cam``, ``box-4cam``, ``box-4cam-unequal``, ``lpt-challenge`` and
``lpt-challenge-small``.

A rig file has a ``name``, a ``description``, a ``[sheet]`` table (width, height and
thickness of the laser sheet, m, centred on the origin with its normal along Z; and its
light ``profile``: ``"gaussian"``, the default laser sheet of the particle lighting, or
``"top-hat"``, uniform over the thickness, for a volume lit through its depth), a
``[tank]`` table and one ``[[cameras]]`` table per camera. The tank is one of::

    kind = "icosahedron"   inradius (m, centre to faces); the default kind
    kind = "box"           size ([L_X, L_Y, L_Z] inner, m, centred on the origin),
                           yaw_deg (turn about Y, from +Z toward +X; default 0),
                           glass_thickness (m), n_glass, n_water
    kind = "free"          no vessel: only the cameras' own windows

A camera has::

    name, azimuth_deg, elevation_deg (default 0), distance (m, pupil to the aim point),
    aim ([X, Y, Z] m, default the sheet centre), roll_deg (turn about the optical axis,
    default 0), focal_length (m), f_number, pixel_pitch (m), sensor_size ([width,
    height] px), distortion (a table of named coefficients k1, k2, k3, p1, p2, each
    default 0: Brown–Conrady radial k and tangential p, in OpenCV's meaning),
    scheimpflug (true: sensor tilted to focus the sheet plane; false: untilted, focused
    on the sheet centre),

and, in an icosahedral or free tank, an optional [cameras.window] table (a flat slab
placed relative to the line of sight): water_path (m), glass_thickness (m),
obliquity_deg, obliquity_direction_deg (0: in the camera's horizontal plane, 45:
about a diagonal), n_glass, n_water. In a box tank a camera looks through the wall its
line of sight to the aim point crosses, which must also be the wall it sees the whole
sheet through; it has no window table.

Missing or unknown fields are errors that name the file and the field. Camera names
become folder and file names: letters, digits, '.', '_' and '-', starting with a letter
or digit (:data:`FILE_NAME_RULE`).
"""

import itertools
import re
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np

from simulator.optics import Camera, Lens, WindowSpec, focus_on_plane, look_at_camera
from simulator.optics.interfaces import N_PMMA, N_WATER
from simulator.optics.placement import viewing_direction
from simulator.particles import Box
from simulator.tank import box_tank, sight_face, wall_window
from simulator.target import PlateDesign

_TOP = {
    "name": True,
    "description": False,
    "sheet": True,
    "tank": True,
    "cameras": True,
    "plate": False,
}
#: A [plate]: the calibration plate's design and the traverse's step (every field
#: optional; left out, PlateDesign's and 1 mm).
_PLATE = {
    "pitch": False,
    "dot_diameter": False,
    "mark_diameter": False,
    "columns": False,
    "rows": False,
    "plane_spacing": False,
}
_SHEET = {"width": True, "height": True, "thickness": True, "profile": False}
#: Light profiles of a [sheet] (``simulator.render.spot.SHEET_PROFILES``, which the rig
#: loader does not import: it would bring the renderer along).
_SHEET_PROFILES = ("gaussian", "top-hat")
_TANKS = {
    "icosahedron": {"kind": False, "inradius": True},
    "box": {
        "kind": True,
        "size": True,
        "yaw_deg": False,
        "glass_thickness": True,
        "n_glass": False,
        "n_water": False,
    },
    "free": {"kind": True},
}
_DISTORTION = ("k1", "k2", "k3", "p1", "p2")
_CAMERA = {
    "name": True,
    "azimuth_deg": True,
    "elevation_deg": False,
    "aim": False,
    "roll_deg": False,
    "distance": True,
    "focal_length": True,
    "f_number": True,
    "pixel_pitch": True,
    "sensor_size": True,
    "distortion": False,
    "scheimpflug": True,
    "window": False,
}
_WINDOW = {
    "water_path": True,
    "glass_thickness": True,
    "obliquity_deg": False,
    "obliquity_direction_deg": False,
    "n_glass": False,
    "n_water": False,
}


@dataclass(frozen=True)
class Tank:
    """The vessel around the sheet (module docstring).

    Attributes
    ----------
    kind : str
        ``"icosahedron"``, ``"box"`` or ``"free"``.
    inradius : float or None
        Centre to faces of the icosahedron, m.
    size : tuple of 3 float or None
        Inner size (L_X, L_Y, L_Z) of the box along its own axes, m.
    yaw : float
        Turn of the box about world Y, rad (:func:`simulator.tank.box_tank`).
    glass_thickness : float
        The box's wall thickness, m.
    n_glass, n_water : float
        Refractive indices of the box's walls and water.
    """

    kind: str = "icosahedron"
    inradius: float | None = None
    size: tuple[float, float, float] | None = None
    yaw: float = 0.0
    glass_thickness: float = 0.0
    n_glass: float = N_PMMA
    n_water: float = N_WATER

    def reach_beyond(self, points: np.ndarray) -> float:
        """How far the farthest of ``points`` (N, 3) lies beyond the wet surface, m
        (≤ 0: all inside; −inf for a free tank)."""
        if self.kind == "icosahedron":
            return float(np.linalg.norm(points, axis=1).max() - self.inradius)
        if self.kind == "box":
            c, s = np.cos(self.yaw), np.sin(self.yaw)
            x, y, z = np.asarray(points, dtype=float).T
            own = np.column_stack([c * x - s * z, y, s * x + c * z])  # in the box's axes
            return float((np.abs(own) - 0.5 * np.asarray(self.size)).max())
        return -np.inf


@dataclass(frozen=True, eq=False)
class Rig:
    """Cameras around a laser sheet.

    Attributes
    ----------
    name, description : str
        Identification.
    cameras : tuple of Camera
        The physical cameras (pose, lens, tilted sensor, window).
    camera_names : tuple of str
        One name per camera.
    sheet : Box
        The illuminated slab, m.
    tank : Tank
        The vessel.
    spec : dict
        The parsed rig description (to save beside a dataset).
    sheet_profile : str
        ``"gaussian"`` (the particle lighting's own Gaussian sheet) or ``"top-hat"``
        (uniform over the sheet's thickness,
        :func:`simulator.render.camera_frames.rig_lighting`).
    plate : PlateDesign
        The calibration plate (a rig file's ``[plate]``; default
        :class:`simulator.target.PlateDesign`'s 21 × 21 dots on a 5 mm pitch).
    plane_spacing : float
        Step of the plate's traverse, m (``[plate] plane_spacing``; default 1 mm).

    Examples
    --------
    The paper's stereo rig: two cameras 1 m from the sheet centre, ±35° about Y, behind
    the windows of an icosahedral tank.

    >>> import simulator
    >>> rig = simulator.load_rig("paper-stereo")
    >>> rig.camera_names, rig.tank.kind, rig.sheet.size  # the sheet in m
    (('cam1', 'cam2'), 'icosahedron', (0.1, 0.1, 0.01))
    >>> first = rig.cameras[0]
    >>> first.center.round(3), first.lens.sensor_size  # pupil (m), (W, H) px
    (array([-0.577,  0.   ,  0.817]), (2048, 1088))
    >>> centre_and_along_x = [[0.0, 0.0, 0.0], [0.01, 0.0, 0.0]]  # m
    >>> first.project(centre_and_along_x).round(2)  # px
    array([[1023.5 ,  543.5 ],
           [1103.54,  542.1 ]])
    """

    name: str
    description: str
    cameras: tuple[Camera, ...]
    camera_names: tuple[str, ...]
    sheet: Box
    tank: Tank
    spec: dict
    sheet_profile: str = "gaussian"
    plate: PlateDesign = field(default_factory=PlateDesign)
    plane_spacing: float = 1e-3


#: Camera names become folder and file names: letters, digits, '.', '_' and '-',
#: starting with a letter or digit, so that no name can point elsewhere ("../x",
#: "/tmp/x") or hide. The rule of ``ptv.names``, which the simulator may not import; a
#: test holds the two to the same answers.
_FILE_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,63}")
FILE_NAME_RULE = (
    "1 to 64 letters, digits, '.', '_' or '-', starting with a letter or digit (it names "
    "folders and files)"
)


def is_file_name(name: object) -> bool:
    """Whether ``name`` may be used as a folder or file name (:data:`FILE_NAME_RULE`)."""
    return isinstance(name, str) and _FILE_NAME.fullmatch(name) is not None


class RigFileError(ValueError):
    """A rig description with a missing, unknown or invalid field."""


def _check_fields(table: object, fields: dict[str, bool], where: str) -> dict:
    if not isinstance(table, dict):
        raise RigFileError(f"{where}: expected a table, got {type(table).__name__}")
    unknown = sorted(set(table) - set(fields))
    if unknown:
        raise RigFileError(
            f"{where}: unknown field {unknown[0]!r} (known fields: {', '.join(fields)})"
        )
    missing = [f for f, required in fields.items() if required and f not in table]
    if missing:
        raise RigFileError(f"{where}: missing field {missing[0]!r}")
    return table


#: Plausible range of every number of a rig file, SI units: (lowest, highest, unit).
#: Values outside are refused by name, since they would fail later with an unrelated
#: message or describe no laboratory (a 100 m sheet, water of index 100).
_LIMITS = {
    "width": (1e-3, 2.0, "m"),
    "size": (1e-2, 10.0, "m"),
    "aim": (-10.0, 10.0, "m"),
    "roll_deg": (-360.0, 360.0, "°"),
    "yaw_deg": (-360.0, 360.0, "°"),
    "height": (1e-3, 2.0, "m"),
    "thickness": (1e-5, 0.2, "m"),
    "inradius": (0.01, 10.0, "m"),
    "azimuth_deg": (-360.0, 360.0, "°"),
    "elevation_deg": (-90.0, 90.0, "°"),
    "distance": (0.01, 100.0, "m"),
    "focal_length": (1e-3, 2.0, "m"),
    "f_number": (0.5, 128.0, ""),
    "pixel_pitch": (0.5e-6, 100e-6, "m"),
    "water_path": (1e-3, 10.0, "m"),
    "glass_thickness": (0.0, 0.5, "m"),
    "obliquity_deg": (-80.0, 80.0, "°"),
    "obliquity_direction_deg": (-360.0, 360.0, "°"),
    "n_glass": (1.0, 2.5, ""),
    "n_water": (1.0, 2.0, ""),
    "pitch": (1e-4, 0.2, "m"),
    "dot_diameter": (1e-5, 0.1, "m"),
    "mark_diameter": (1e-5, 0.1, "m"),
    "plane_spacing": (1e-5, 0.1, "m"),
}
#: Sensor width and height, px, and the largest distortion coefficient (normalised
#: image coordinates, where the edge of a 35 mm-class field lies near 0.4).
_SENSOR_PX = (16, 16384)
_DISTORTION_MAX = 10.0


def _number(table: dict, key: str, where: str) -> float:
    """``table[key]`` as a float within :data:`_LIMITS`, else a RigFileError naming it."""
    value = table[key]
    if isinstance(value, bool) or not isinstance(value, int | float) or not np.isfinite(value):
        raise RigFileError(f"{where}.{key}: expected a finite number, got {value!r}")
    low, high, unit = _LIMITS[key]
    if not low <= value <= high:
        unit = unit if unit in ("", "°") else f" {unit}"
        raise RigFileError(f"{where}.{key}: must be from {low:g} to {high:g}{unit}, got {value!r}")
    return float(value)


def _tank(table: object, where: str) -> Tank:
    """The [tank] table as a Tank (module docstring)."""
    if not isinstance(table, dict):
        raise RigFileError(f"{where}: expected a table, got {type(table).__name__}")
    kind = table.get("kind", "icosahedron")
    if not isinstance(kind, str) or kind not in _TANKS:
        raise RigFileError(f"{where}.kind: expected one of {', '.join(_TANKS)}, got {kind!r}")
    t = _check_fields(table, _TANKS[kind], where)
    if kind == "icosahedron":
        return Tank(kind, inradius=_number(t, "inradius", where))
    if kind == "box":
        return Tank(
            kind,
            size=tuple(float(v) for v in _vector(t, "size", where)),
            yaw=np.deg2rad(_number(t, "yaw_deg", where)) if "yaw_deg" in t else 0.0,
            glass_thickness=_number(t, "glass_thickness", where),
            **{k: _number(t, k, where) for k in ("n_glass", "n_water") if k in t},
        )
    return Tank(kind)


def _vector(table: dict, key: str, where: str) -> np.ndarray:
    """``table[key]`` as 3 numbers, each within :data:`_LIMITS`, else a RigFileError."""
    value = table[key]
    if not (isinstance(value, list) and len(value) == 3):
        raise RigFileError(f"{where}.{key}: expected 3 numbers [X, Y, Z], got {value!r}")
    return np.array([_number({key: v}, key, where) for v in value])


def _distortion(table: dict, where: str, focal_length: float, pitch: float, size) -> tuple:
    """(k1, k2, k3, p1, p2) of ``table``, bounded, and radially monotonic over the sensor.

    A radial mapping r ↦ r (1 + k1 r² + k2 r⁴ + k3 r⁶) that turns back within the field
    (up to 1.5 × the sensor's half-diagonal in normalised coordinates) folds the image
    onto itself, which no lens does.
    """
    named = table.get("distortion", {})
    if isinstance(named, list):
        raise RigFileError(
            f"{where}.distortion: give the coefficients by name, e.g. distortion = "
            "{ k1 = -0.08, p1 = 0.001 } (missing ones are 0): a list is refused because "
            "its order is ambiguous (OpenCV's is k1, k2, p1, p2, k3; synptv's rig files "
            f"used k1, k2, k3, p1, p2), got {named!r}"
        )
    _check_fields(named, dict.fromkeys(_DISTORTION, False), f"{where}.distortion")
    for key, value in named.items():
        if isinstance(value, bool) or not isinstance(value, int | float) or not np.isfinite(value):
            raise RigFileError(f"{where}.distortion.{key}: expected a finite number, got {value!r}")
        if abs(value) > _DISTORTION_MAX:
            raise RigFileError(
                f"{where}.distortion.{key}: must lie within ±{_DISTORTION_MAX:g}, got {value!r}"
            )
    coefficients = [float(named.get(key, 0.0)) for key in _DISTORTION]
    k1, k2, k3 = coefficients[:3]
    r = np.linspace(0.0, 1.5 * 0.5 * np.hypot(*size) * pitch / focal_length, 512)
    slope = 1 + 3 * k1 * r**2 + 5 * k2 * r**4 + 7 * k3 * r**6
    if (slope <= 0).any():
        raise RigFileError(
            f"{where}.distortion: the radial distortion folds the image over at "
            f"r = {r[np.argmax(slope <= 0)]:.3g} (normalised) within the field of view, "
            f"got {coefficients!r}"
        )
    return tuple(coefficients)


def _window(table: dict, where: str, tank: Tank) -> WindowSpec | None:
    """The camera's own window slab (icosahedral and free tanks), or None."""
    if "window" not in table:
        return None
    w_where = f"{where}.window"
    if tank.kind == "box":
        raise RigFileError(
            f"{w_where}: a camera of a box tank looks through the tank's wall; give the glass "
            "in [tank] (glass_thickness, n_glass) instead"
        )
    w = _check_fields(table["window"], _WINDOW, w_where)
    return WindowSpec(
        water_path=_number(w, "water_path", w_where),
        glass_thickness=_number(w, "glass_thickness", w_where),
        obliquity=np.deg2rad(_number(w, "obliquity_deg", w_where)) if "obliquity_deg" in w else 0.0,
        obliquity_direction=np.deg2rad(_number(w, "obliquity_direction_deg", w_where))
        if "obliquity_direction_deg" in w
        else 0.0,
        **{k: _number(w, k, w_where) for k in ("n_glass", "n_water") if k in w},
    )


def _sheet_corners(sheet: Box) -> np.ndarray:
    """The 8 corners of the sheet, (8, 3), m."""
    signs = np.array(list(itertools.product((-1.0, 1.0), repeat=3)))
    return np.asarray(sheet.centre) + signs * 0.5 * np.asarray(sheet.size)


def _box_wall(center: np.ndarray, aim: np.ndarray, sheet: Box, tank: Tank, where: str):
    """The wall of a box tank a camera at ``center`` looks through toward ``aim``, as a
    flat window; a RigFileError when part of the sheet is seen through another wall."""
    vessel = box_tank(tank.size, tank.yaw)
    try:
        face = sight_face(vessel, center, aim)
        walls = {
            tuple(np.round(vessel.face_normals[sight_face(vessel, center, x)], 9))
            for x in _sheet_corners(sheet)
        }
    except ValueError as err:
        raise RigFileError(f"{where}: {err}") from None
    if len(walls) > 1:
        raise RigFileError(
            f"{where}: the camera sees the sheet through {len(walls)} walls of the box (it "
            "looks across an edge of the tank); turn it toward one wall"
        )
    window = wall_window(
        vessel, face, tank.glass_thickness, n_glass=tank.n_glass, n_water=tank.n_water
    )
    if not window.camera_height(center) > 0:
        raise RigFileError(f"{where}: the camera lies inside the glass of the tank's wall")
    return window


def _camera(table: dict, where: str, sheet: Box, tank: Tank) -> tuple[str, Camera]:
    _check_fields(table, _CAMERA, where)
    if not is_file_name(table["name"]):
        raise RigFileError(f"{where}.name: expected {FILE_NAME_RULE}, got {table['name']!r}")
    size = table["sensor_size"]
    low, high = _SENSOR_PX
    if not (
        isinstance(size, list)
        and len(size) == 2
        and all(isinstance(v, int) and not isinstance(v, bool) and low <= v <= high for v in size)
    ):
        raise RigFileError(
            f"{where}.sensor_size: expected [width, height], each from {low} to {high} px, "
            f"got {size!r}"
        )
    if not isinstance(table["scheimpflug"], bool):
        raise RigFileError(
            f"{where}.scheimpflug: expected true or false, got {table['scheimpflug']!r}"
        )
    focal_length = _number(table, "focal_length", where)
    pitch = _number(table, "pixel_pitch", where)
    k1, k2, k3, p1, p2 = _distortion(table, where, focal_length, pitch, size)
    lens = Lens(
        focal_length=focal_length,
        pixel_pitch=pitch,
        sensor_size=(size[0], size[1]),
        k1=k1,
        k2=k2,
        k3=k3,
        p1=p1,
        p2=p2,
        f_number=_number(table, "f_number", where),
    )
    distance = _number(table, "distance", where)
    azimuth = np.deg2rad(_number(table, "azimuth_deg", where))
    angles = {
        key: np.deg2rad(_number(table, f"{key}_deg", where)) if f"{key}_deg" in table else 0.0
        for key in ("elevation", "roll")
    }
    aim = _vector(table, "aim", where) if "aim" in table else np.array(sheet.centre, dtype=float)
    if tank.reach_beyond(aim[None, :]) >= 0:
        raise RigFileError(f"{where}.aim: the aim point {aim.tolist()} m is not inside the tank")
    window = _window(table, where, tank)
    if tank.kind == "box":
        center = aim + distance * viewing_direction(azimuth, angles["elevation"])
        window = _box_wall(center, aim, sheet, tank, where)
    try:
        camera = look_at_camera(
            aim, lens, distance=distance, azimuth=azimuth, window=window, **angles
        )
        camera = focus_on_plane(
            camera,
            plane_point=sheet.centre,
            plane_normal=(0.0, 0.0, 1.0),
            tilt=table["scheimpflug"],
        )
    except ValueError as err:  # a geometry no camera can have (worded by the optics)
        raise RigFileError(f"{where}: {err}") from None
    return table["name"], camera


def check_sheet_in_tank(sheet: Box, tank: Tank, where: str) -> None:
    """Raise RigFileError unless the whole sheet lies inside the tank's wet surface."""
    beyond = tank.reach_beyond(_sheet_corners(sheet))
    if beyond >= 0:
        bound = (
            f"the tank's inradius {tank.inradius:g} m"
            if tank.kind == "icosahedron"
            else f"the box's walls (size {list(tank.size)} m)"
        )
        raise RigFileError(f"{where}: the sheet reaches {beyond * 1e3:.3g} mm beyond {bound}")


def check_sheet_beyond_window(camera: Camera, sheet: Box, where: str) -> None:
    """Raise RigFileError unless the whole sheet lies beyond the wet face of the camera's
    window (on the water side)."""
    window = camera.interfaces
    if window is not None:
        depth = _sheet_corners(sheet) @ window.normal - window.offsets[-1]
        if depth.min() <= 0:
            raise RigFileError(
                f"{where}.window: a corner of the sheet lies {-depth.min() * 1e3:.3g} mm on the "
                "camera's side of the window's wet face: lengthen water_path or reduce "
                "obliquity_deg"
            )


def check_sees_sheet(name: str, camera: Camera, sheet: Box, where: str) -> None:
    """Raise RigFileError unless ``camera`` images some point of a 9 × 9 grid on the sheet."""
    u = np.linspace(-0.5, 0.5, 9)
    uu, vv = np.meshgrid(u * sheet.size[0], u * sheet.size[1])
    points = np.column_stack([uu.ravel(), vv.ravel(), np.zeros(uu.size)]) + np.array(sheet.centre)
    if not np.isfinite(camera.project(points)).all(axis=1).any():
        raise RigFileError(f"{where}: camera {name!r} sees none of the laser sheet")


def rig_from_dict(spec: dict, *, source: str = "<rig>") -> Rig:
    """Build a rig from a parsed description (see the module docstring for the fields).

    Parameters
    ----------
    spec : dict
        A rig file's table, as ``tomllib`` reads it (docs/rigs.md).
    source : str
        What the messages call it (the file's name).

    Returns
    -------
    Rig

    Raises
    ------
    RigFileError
        A missing, unknown or invalid field, or a rig that cannot work (a camera that
        sees none of the sheet, a sheet outside the tank): one line naming ``source``
        and the field.

    Examples
    --------
    One camera 0.5 m in front of a 5 × 5 cm sheet, no tank:

    >>> import simulator
    >>> camera = {"name": "front", "azimuth_deg": 0.0, "distance": 0.5,
    ...           "focal_length": 0.05, "f_number": 8.0, "pixel_pitch": 10e-6,
    ...           "sensor_size": [640, 480], "scheimpflug": False}
    >>> spec = {"name": "one-camera", "tank": {"kind": "free"}, "cameras": [camera],
    ...         "sheet": {"width": 0.05, "height": 0.05, "thickness": 0.002}}
    >>> rig = simulator.rig_from_dict(spec)
    >>> rig.camera_names, rig.cameras[0].center  # pupil centre, m
    (('front',), array([0. , 0. , 0.5]))
    >>> camera["focal_length"] = 50.0  # mm where m are asked for
    >>> try:
    ...     simulator.rig_from_dict(spec, source="my-rig.toml")
    ... except ValueError as error:
    ...     print(error)
    my-rig.toml: cameras[0].focal_length: must be from 0.001 to 2 m, got 50.0
    """
    _check_fields(spec, _TOP, source)
    s = _check_fields(spec["sheet"], _SHEET, f"{source}: sheet")
    sheet = Box(tuple(_number(s, k, f"{source}: sheet") for k in ("width", "height", "thickness")))
    profile = s.get("profile", "gaussian")
    if not isinstance(profile, str) or profile not in _SHEET_PROFILES:
        raise RigFileError(
            f"{source}: sheet.profile: expected one of {', '.join(_SHEET_PROFILES)}, "
            f"got {profile!r}"
        )
    tank = _tank(spec["tank"], f"{source}: tank")
    check_sheet_in_tank(sheet, tank, f"{source}: sheet")
    cameras_spec = spec["cameras"]
    if not isinstance(cameras_spec, list) or len(cameras_spec) < 1:
        raise RigFileError(f"{source}: cameras: expected at least one [[cameras]] table")
    names, cameras = [], []
    for i, table in enumerate(cameras_spec):
        where = f"{source}: cameras[{i}]"
        name, camera = _camera(table, where, sheet, tank)
        check_sheet_beyond_window(camera, sheet, where)
        check_sees_sheet(name, camera, sheet, where)
        names.append(name)
        cameras.append(camera)
    if len(set(names)) != len(names):
        raise RigFileError(f"{source}: camera names must be unique, got {names}")
    plate, plane_spacing = _plate(spec.get("plate", {}), f"{source}: plate")
    return Rig(
        name=str(spec["name"]),
        description=str(spec.get("description", "")),
        cameras=tuple(cameras),
        camera_names=tuple(names),
        sheet=sheet,
        tank=tank,
        spec=spec,
        sheet_profile=profile,
        plate=plate,
        plane_spacing=plane_spacing,
    )


def _plate(table: object, where: str) -> tuple[PlateDesign, float]:
    """The plate design and the traverse step (m) of a [plate] table."""
    table = _check_fields(table, _PLATE, where)
    lengths = {
        k: _number(table, k, where)
        for k in ("pitch", "dot_diameter", "mark_diameter")
        if k in table
    }
    counts = {}
    for key in ("columns", "rows"):
        if key in table:
            value = table[key]
            if isinstance(value, bool) or not isinstance(value, int) or not 5 <= value <= 1001:
                raise RigFileError(
                    f"{where}.{key}: expected an integer from 5 to 1001, got {value!r}"
                )
            counts[key] = value
    try:
        design = PlateDesign(**lengths, **counts)
    except ValueError as err:
        raise RigFileError(f"{where}: {err}") from None
    spacing = _number(table, "plane_spacing", where) if "plane_spacing" in table else 1e-3
    return design, spacing


def rig_presets() -> list[str]:
    """Names of the rigs shipped with synptv.

    Returns
    -------
    list of str
        Sorted; each loads with :func:`load_rig` (docs/optics.md §5 compares them).

    Examples
    --------
    >>> import simulator
    >>> simulator.rig_presets()
    ['box-3cam', 'box-4cam', 'box-4cam-unequal', 'conventional', 'lpt-challenge',
     'lpt-challenge-small', 'paper-stereo']
    """
    folder = resources.files("simulator") / "rig_presets"
    return sorted(
        p.name.removesuffix(".toml") for p in folder.iterdir() if p.name.endswith(".toml")
    )


def load_rig(name_or_path: str | Path) -> Rig:
    """A preset rig by name, or a rig file by path.

    Parameters
    ----------
    name_or_path : str or Path
        A name of :func:`rig_presets`, or a rig TOML file (docs/rigs.md).

    Returns
    -------
    Rig

    Raises
    ------
    ValueError
        Unknown preset, unreadable or invalid file (the message names the file and field).

    Examples
    --------
    The CI-size crop of the LPT-Challenge rig: four cameras around a 20 × 25 × 30 mm
    volume lit through its depth.

    >>> import simulator
    >>> rig = simulator.load_rig("lpt-challenge-small")
    >>> rig.camera_names, rig.sheet.size, rig.sheet_profile  # the sheet in m
    (('cam1', 'cam2', 'cam3', 'cam4'), (0.02, 0.025, 0.03), 'top-hat')
    >>> simulator.load_rig("my-rig.toml")
    Traceback (most recent call last):
    ...
    simulator.rigs.RigFileError: rig file 'my-rig.toml' does not exist
    """
    path = Path(name_or_path)
    if path.suffix == ".toml" or path.exists():
        if not path.is_file():
            raise RigFileError(f"rig file {str(path)!r} does not exist")
        source = str(path)
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as err:
            raise RigFileError(f"{source}: not readable as a UTF-8 text file ({err})") from None
    else:
        presets = rig_presets()
        if str(name_or_path) not in presets:
            raise RigFileError(
                f"unknown rig {str(name_or_path)!r}; "
                f"presets: {', '.join(presets)} (or a .toml path)"
            )
        resource = resources.files("simulator") / "rig_presets" / f"{name_or_path}.toml"
        text, source = resource.read_text(), f"{name_or_path}.toml"
    try:
        spec = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise RigFileError(f"{source}: not valid TOML: {err}") from None
    return rig_from_dict(spec, source=source)
