"""Camera rigs described by TOML files: presets ``paper-stereo`` and ``conventional``.

A rig file has a ``name``, a ``description``, a ``[sheet]`` table (width, height and
thickness of the laser sheet, m, centred on the origin with its normal along Z), a
``[tank]`` table (``inradius``: distance from the centre to the window faces, m) and one
``[[cameras]]`` table per camera::

    name, azimuth_deg, elevation_deg (default 0), distance (m, pupil to the origin),
    focal_length (m), f_number, pixel_pitch (m), sensor_size ([width, height] px),
    distortion ([k1, k2, k3, p1, p2], OpenCV convention; default zeros),
    scheimpflug (true: sensor tilted to focus the sheet plane; false: untilted, focused
    on the sheet centre), and an optional [cameras.window] table: water_path (m),
    glass_thickness (m), obliquity_deg, obliquity_direction_deg (0: in the camera's
    horizontal plane, 45: about a diagonal), n_glass, n_water.

Missing or unknown fields are errors that name the file and the field. Camera names
become folder and file names: letters, digits, '.', '_' and '-', starting with a letter
or digit (:data:`FILE_NAME_RULE`).
"""

import itertools
import re
import tomllib
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from simulator.optics import Camera, Lens, WindowSpec, focus_on_plane, look_at_camera
from simulator.particles import Box

_TOP = {"name": True, "description": False, "sheet": True, "tank": True, "cameras": True}
_SHEET = {"width": True, "height": True, "thickness": True}
_TANK = {"inradius": True}
_CAMERA = {
    "name": True,
    "azimuth_deg": True,
    "elevation_deg": False,
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
    tank_inradius : float
        Distance from the tank centre to its faces, m.
    spec : dict
        The parsed rig description (to save beside a dataset).
    """

    name: str
    description: str
    cameras: tuple[Camera, ...]
    camera_names: tuple[str, ...]
    sheet: Box
    tank_inradius: float
    spec: dict


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


def _distortion(table: dict, where: str, focal_length: float, pitch: float, size) -> tuple:
    """(k1, k2, k3, p1, p2) of ``table``, bounded, and radially monotonic over the sensor.

    A radial mapping r ↦ r (1 + k1 r² + k2 r⁴ + k3 r⁶) that turns back within the field
    (up to 1.5 × the sensor's half-diagonal in normalised coordinates) folds the image
    onto itself, which no lens does.
    """
    coefficients = table.get("distortion", [0.0] * 5)
    if not (
        isinstance(coefficients, list)
        and len(coefficients) == 5
        and all(
            isinstance(v, int | float) and not isinstance(v, bool) and np.isfinite(v)
            for v in coefficients
        )
    ):
        raise RigFileError(
            f"{where}.distortion: expected 5 finite numbers [k1, k2, k3, p1, p2], "
            f"got {coefficients!r}"
        )
    if max(abs(v) for v in coefficients) > _DISTORTION_MAX:
        raise RigFileError(
            f"{where}.distortion: coefficients must lie within ±{_DISTORTION_MAX:g}, "
            f"got {coefficients!r}"
        )
    k1, k2, k3 = (float(v) for v in coefficients[:3])
    r = np.linspace(0.0, 1.5 * 0.5 * np.hypot(*size) * pitch / focal_length, 512)
    slope = 1 + 3 * k1 * r**2 + 5 * k2 * r**4 + 7 * k3 * r**6
    if (slope <= 0).any():
        raise RigFileError(
            f"{where}.distortion: the radial distortion folds the image over at "
            f"r = {r[np.argmax(slope <= 0)]:.3g} (normalised) within the field of view, "
            f"got {coefficients!r}"
        )
    return tuple(float(v) for v in coefficients)


def _camera(table: dict, where: str, sheet: Box) -> tuple[str, Camera]:
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
    window = None
    if "window" in table:
        w_where = f"{where}.window"
        w = _check_fields(table["window"], _WINDOW, w_where)
        window = WindowSpec(
            water_path=_number(w, "water_path", w_where),
            glass_thickness=_number(w, "glass_thickness", w_where),
            obliquity=np.deg2rad(_number(w, "obliquity_deg", w_where))
            if "obliquity_deg" in w
            else 0.0,
            obliquity_direction=np.deg2rad(_number(w, "obliquity_direction_deg", w_where))
            if "obliquity_direction_deg" in w
            else 0.0,
            **{k: _number(w, k, w_where) for k in ("n_glass", "n_water") if k in w},
        )
    distance = _number(table, "distance", where)
    azimuth = np.deg2rad(_number(table, "azimuth_deg", where))
    elevation = (
        np.deg2rad(_number(table, "elevation_deg", where)) if "elevation_deg" in table else 0.0
    )
    try:
        camera = look_at_camera(
            np.array(sheet.centre),
            lens,
            distance=distance,
            azimuth=azimuth,
            elevation=elevation,
            window=window,
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


def check_sheet_in_water(camera: Camera, sheet: Box, tank_inradius: float, where: str) -> None:
    """Raise RigFileError unless the whole sheet lies in the water: inside the tank's
    inscribed sphere and beyond the wet face of the camera's window."""
    half = 0.5 * np.asarray(sheet.size)
    signs = np.array(list(itertools.product((-1.0, 1.0), repeat=3)))
    corners = np.asarray(sheet.centre) + signs * half
    reach = float(np.linalg.norm(corners, axis=1).max())
    if reach > tank_inradius:
        raise RigFileError(
            f"{where}: the sheet reaches {reach:.3g} m from the centre, beyond the tank's "
            f"inradius {tank_inradius:g} m"
        )
    window = camera.interfaces
    if window is not None:
        depth = corners @ window.normal - window.offsets[-1]
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
    """Build a rig from a parsed description (see the module docstring for the fields)."""
    _check_fields(spec, _TOP, source)
    s = _check_fields(spec["sheet"], _SHEET, f"{source}: sheet")
    sheet = Box(tuple(_number(s, k, f"{source}: sheet") for k in ("width", "height", "thickness")))
    t = _check_fields(spec["tank"], _TANK, f"{source}: tank")
    tank_inradius = _number(t, "inradius", f"{source}: tank")
    cameras_spec = spec["cameras"]
    if not isinstance(cameras_spec, list) or len(cameras_spec) < 1:
        raise RigFileError(f"{source}: cameras: expected at least one [[cameras]] table")
    names, cameras = [], []
    for i, table in enumerate(cameras_spec):
        where = f"{source}: cameras[{i}]"
        name, camera = _camera(table, where, sheet)
        check_sheet_in_water(camera, sheet, tank_inradius, where)
        check_sees_sheet(name, camera, sheet, where)
        names.append(name)
        cameras.append(camera)
    if len(set(names)) != len(names):
        raise RigFileError(f"{source}: camera names must be unique, got {names}")
    return Rig(
        name=str(spec["name"]),
        description=str(spec.get("description", "")),
        cameras=tuple(cameras),
        camera_names=tuple(names),
        sheet=sheet,
        tank_inradius=tank_inradius,
        spec=spec,
    )


def rig_presets() -> list[str]:
    """Names of the rigs shipped with synptv."""
    folder = resources.files("simulator") / "rig_presets"
    return sorted(
        p.name.removesuffix(".toml") for p in folder.iterdir() if p.name.endswith(".toml")
    )


def load_rig(name_or_path: str | Path) -> Rig:
    """A preset rig by name, or a rig file by path.

    Raises
    ------
    ValueError
        Unknown preset, unreadable or invalid file (the message names the file and field).
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
