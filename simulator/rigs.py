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


#: Names that become folder and file names (cameras, scenarios): letters, digits, '.',
#: '_' and '-', starting with a letter or digit, so that no name can point elsewhere
#: ("../x", "/tmp/x") or hide.
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


def _number(table: dict, key: str, where: str, *, positive: bool = True) -> float:
    value = table[key]
    if isinstance(value, bool) or not isinstance(value, int | float) or not np.isfinite(value):
        raise RigFileError(f"{where}.{key}: expected a number, got {value!r}")
    if positive and value <= 0:
        raise RigFileError(f"{where}.{key}: must be > 0, got {value!r}")
    return float(value)


def _camera(table: dict, where: str, sheet: Box) -> tuple[str, Camera]:
    _check_fields(table, _CAMERA, where)
    size = table["sensor_size"]
    if not (
        isinstance(size, list)
        and len(size) == 2
        and all(isinstance(v, int) and v > 0 for v in size)
    ):
        raise RigFileError(f"{where}.sensor_size: expected [width, height] in px, got {size!r}")
    distortion = table.get("distortion", [0.0] * 5)
    if not (isinstance(distortion, list) and len(distortion) == 5):
        raise RigFileError(f"{where}.distortion: expected [k1, k2, k3, p1, p2], got {distortion!r}")
    if not isinstance(table["scheimpflug"], bool):
        raise RigFileError(
            f"{where}.scheimpflug: expected true or false, got {table['scheimpflug']!r}"
        )
    k1, k2, k3, p1, p2 = (float(v) for v in distortion)
    lens = Lens(
        focal_length=_number(table, "focal_length", where),
        pixel_pitch=_number(table, "pixel_pitch", where),
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
            glass_thickness=_number(w, "glass_thickness", w_where, positive=False),
            obliquity=np.deg2rad(_number(w, "obliquity_deg", w_where, positive=False))
            if "obliquity_deg" in w
            else 0.0,
            obliquity_direction=np.deg2rad(
                _number(w, "obliquity_direction_deg", w_where, positive=False)
            )
            if "obliquity_direction_deg" in w
            else 0.0,
            **{k: _number(w, k, w_where) for k in ("n_glass", "n_water") if k in w},
        )
    camera = look_at_camera(
        np.array(sheet.centre),
        lens,
        distance=_number(table, "distance", where),
        azimuth=np.deg2rad(_number(table, "azimuth_deg", where, positive=False)),
        elevation=np.deg2rad(_number(table, "elevation_deg", where, positive=False))
        if "elevation_deg" in table
        else 0.0,
        window=window,
    )
    camera = focus_on_plane(
        camera, plane_point=sheet.centre, plane_normal=(0.0, 0.0, 1.0), tilt=table["scheimpflug"]
    )
    name = table["name"]
    if not is_file_name(name):
        raise RigFileError(f"{where}.name: expected {FILE_NAME_RULE}, got {name!r}")
    return name, camera


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
    cameras_spec = spec["cameras"]
    if not isinstance(cameras_spec, list) or len(cameras_spec) < 1:
        raise RigFileError(f"{source}: cameras: expected at least one [[cameras]] table")
    names, cameras = [], []
    for i, table in enumerate(cameras_spec):
        where = f"{source}: cameras[{i}]"
        name, camera = _camera(table, where, sheet)
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
        tank_inradius=_number(t, "inradius", f"{source}: tank"),
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
        text, source = path.read_text(), str(path)
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
