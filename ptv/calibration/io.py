"""Calibrations on disk: one versioned HDF5 file per rig, one entry per camera.

Layout (format ``synptv-calibration``, version :data:`FORMAT_VERSION`)::

    /                     attrs: format, format_version, written_by, calibrated_volume
                          (2, 3) m when known, + user metadata
    /cameras/<name>       attrs: model (a registered name below), then the model's data

``model-free`` (:class:`~ptv.calibration.model_free.ModelFreeCalibration`)::

    attrs    image_size (2,), z_ref
    datasets grid_x, grid_y, line_parameters (4 or 6, ny, nx), line_rms (ny, nx)
    planes/<k>            attrs z; datasets residual_px, residual_m, hull_points (N, 2)
    planes/<k>/to_world   attrs degree; datasets centre, scale, coefficients
    planes/<k>/to_pixel   (the same)

``opencv-pinhole`` (:class:`~ptv.calibration.pinhole.PinholeCalibration`)::

    attrs    image_size (2,), distortion, tilted, fixed_principal_point, rms, start,
             n_points
    datasets params (17,)

``refractive-pinhole`` (:class:`~ptv.calibration.refractive_pinhole.
RefractivePinholeCalibration`): the ``opencv-pinhole`` entries, and::

    attrs    window_normal (3,), window_distance, window_thickness, glass_index,
             medium_index, air_index

The plane hulls are rebuilt from their points (Delaunay), the splines from the grid and
line parameters, so a loaded calibration maps pixels to rays, and points to pixels,
bit for bit as the saved one.

``tsai`` (:class:`~ptv.calibration.tsai.TsaiCalibration`)::

    datasets rotation (3, 3), translation (3,)
    attrs    focal_length, kappa1, sx, principal_point (2,), pixel_size (2,),
             reprojection_rms, n_points, free_principal_point

Writing goes to a temporary name in the target folder, then renames it over the
target: a reader never sees a half-written file. Reading a file that is not HDF5, an
HDF5 file of another program, a newer format version, or a file with missing or
malformed entries raises :class:`CalibrationFileError` naming the file.

Further calibration types join through :func:`register_codec` (a writer and a reader
per type; files dispatch on the stored model name, never on ``if`` chains).
"""

import logging
import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np
from scipy.spatial import Delaunay

from ptv.box import Box, check_box
from ptv.calibration.model_free import ModelFreeCalibration, PlaneFit
from ptv.calibration.pinhole import PinholeCalibration, PinholeModel
from ptv.calibration.polynomial import Polynomial2D
from ptv.calibration.refractive_pinhole import FlatWindow, RefractivePinholeCalibration
from ptv.calibration.soloff import SoloffCalibration
from ptv.calibration.tsai import TsaiCalibration
from ptv.camera_model import CameraModel
from ptv.names import check_file_name

log = logging.getLogger(__name__)

#: The format name written to the root attribute ``format``.
FORMAT_NAME = "synptv-calibration"
#: Version written; files of a higher version are refused.
FORMAT_VERSION = 1


class CalibrationFileError(ValueError):
    """A calibration file that cannot be read (corrupt, foreign, too new)."""


@dataclass(frozen=True)
class _Codec:
    model: str
    kind: type
    write: Callable[[h5py.Group, object], None]
    read: Callable[[h5py.Group], CameraModel]


_BY_TYPE: dict[type, _Codec] = {}
_BY_MODEL: dict[str, _Codec] = {}


def register_codec(
    kind: type,
    model: str,
    write: Callable[[h5py.Group, object], None],
    read: Callable[[h5py.Group], CameraModel],
) -> None:
    """Teach the file format a calibration type.

    Parameters
    ----------
    kind : type
        The calibration class.
    model : str
        Its name in files (attribute ``model`` of its group); never reuse a name.
    write : callable (group, calibration) -> None
        Stores the calibration in an empty HDF5 group.
    read : callable (group) -> calibration
        Rebuilds it; raise KeyError, ValueError or TypeError on malformed content.
    """
    codec = _Codec(model, kind, write, read)
    _BY_TYPE[kind] = codec
    _BY_MODEL[model] = codec


# -- model-free ------------------------------------------------------------------------------
def _write_polynomial(group: h5py.Group, poly: Polynomial2D) -> None:
    group.attrs["degree"] = int(poly.degree)
    group.create_dataset("centre", data=np.asarray(poly.centre, dtype=np.float64))
    group.create_dataset("scale", data=np.asarray(poly.scale, dtype=np.float64))
    group.create_dataset("coefficients", data=np.asarray(poly.coefficients, dtype=np.float64))


def _read_polynomial(group: h5py.Group) -> Polynomial2D:
    degree = int(group.attrs["degree"])
    coefficients = _array(group, "coefficients", ndim=2)
    terms = (degree + 1) * (degree + 2) // 2
    if degree not in (1, 2, 3) or coefficients.shape != (terms, 2):
        raise ValueError(
            f"{group.name}: degree {degree} with coefficients of shape {coefficients.shape}"
        )
    return Polynomial2D(
        degree,
        _array(group, "centre", shape=(2,)),
        _array(group, "scale", shape=(2,)),
        coefficients,
    )


def _write_model_free(group: h5py.Group, cal: ModelFreeCalibration) -> None:
    group.attrs["image_size"] = np.asarray(cal.image_size, dtype=np.int64)
    group.attrs["z_ref"] = float(cal.z_ref)
    for name in ("grid_x", "grid_y", "line_parameters", "line_rms"):
        group.create_dataset(name, data=np.asarray(getattr(cal, name), dtype=np.float64))
    planes = group.create_group("planes")
    for k, plane in enumerate(cal.planes):
        g = planes.create_group(f"{k:03d}")
        g.attrs["z"] = float(plane.z)
        g.create_dataset("residual_px", data=np.asarray(plane.residual_px, dtype=np.float64))
        g.create_dataset("residual_m", data=np.asarray(plane.residual_m, dtype=np.float64))
        g.create_dataset("hull_points", data=np.asarray(plane.hull.points, dtype=np.float64))
        _write_polynomial(g.create_group("to_world"), plane.to_world)
        _write_polynomial(g.create_group("to_pixel"), plane.to_pixel)


def _read_model_free(group: h5py.Group) -> ModelFreeCalibration:
    size = np.asarray(group.attrs["image_size"])
    if size.shape != (2,):
        raise ValueError(f"image_size must be (width, height), got {size!r}")
    planes_group = group["planes"]
    planes = []
    for key in sorted(planes_group, key=int):
        g = planes_group[key]
        planes.append(
            PlaneFit(
                z=float(g.attrs["z"]),
                to_world=_read_polynomial(g["to_world"]),
                to_pixel=_read_polynomial(g["to_pixel"]),
                residual_px=_array(g, "residual_px", ndim=1),
                residual_m=_array(g, "residual_m", ndim=1),
                hull=Delaunay(_array(g, "hull_points", ndim=2)),
            )
        )
    if len(planes) < 2:
        raise ValueError(f"a model-free calibration has at least two planes, found {len(planes)}")
    grid_x = _array(group, "grid_x", ndim=1)
    grid_y = _array(group, "grid_y", ndim=1)
    shape = (len(grid_y), len(grid_x))
    return ModelFreeCalibration(
        image_size=(int(size[0]), int(size[1])),
        planes=tuple(planes),
        z_ref=float(group.attrs["z_ref"]),
        grid_x=grid_x,
        grid_y=grid_y,
        line_parameters=_line_parameters(group, shape),
        line_rms=_array(group, "line_rms", shape=shape),
    )


# -- Tsai ----------------------------------------------------------------------------------
def _write_tsai(group: h5py.Group, cal: TsaiCalibration) -> None:
    group.create_dataset("rotation", data=np.asarray(cal.rotation, dtype=np.float64))
    group.create_dataset("translation", data=np.asarray(cal.translation, dtype=np.float64))
    group.attrs["focal_length"] = float(cal.focal_length)
    group.attrs["kappa1"] = float(cal.kappa1)
    group.attrs["sx"] = float(cal.sx)
    group.attrs["principal_point"] = np.asarray(cal.principal_point, dtype=np.float64)
    group.attrs["pixel_size"] = np.asarray(cal.pixel_size, dtype=np.float64)
    group.attrs["reprojection_rms"] = float(cal.reprojection_rms)
    group.attrs["n_points"] = int(cal.n_points)
    group.attrs["free_principal_point"] = bool(cal.free_principal_point)


def _read_tsai(group: h5py.Group) -> TsaiCalibration:
    centre = np.asarray(group.attrs["principal_point"], dtype=np.float64)
    pitch = np.asarray(group.attrs["pixel_size"], dtype=np.float64)
    if centre.shape != (2,) or pitch.shape != (2,):
        raise ValueError(f"principal_point {centre!r} and pixel_size {pitch!r} must be pairs")
    return TsaiCalibration(
        rotation=_array(group, "rotation", shape=(3, 3)),
        translation=_array(group, "translation", shape=(3,)),
        focal_length=float(group.attrs["focal_length"]),
        kappa1=float(group.attrs["kappa1"]),
        sx=float(group.attrs["sx"]),
        principal_point=(float(centre[0]), float(centre[1])),
        pixel_size=(float(pitch[0]), float(pitch[1])),
        reprojection_rms=float(group.attrs["reprojection_rms"]),
        n_points=int(group.attrs["n_points"]),
        free_principal_point=bool(group.attrs["free_principal_point"]),
    )


# -- OpenCV pinhole ----------------------------------------------------------------------------
def _write_pinhole(group: h5py.Group, cal: PinholeCalibration) -> None:
    group.attrs["image_size"] = np.asarray(cal.image_size, dtype=np.int64)
    group.attrs["distortion"] = ",".join(cal.model.distortion)
    group.attrs["tilted"] = bool(cal.model.tilted)
    group.attrs["fixed_principal_point"] = bool(cal.model.fixed_principal_point)
    group.create_dataset("params", data=np.asarray(cal.params, dtype=np.float64))
    group.attrs["rms"] = float(cal.rms)
    group.attrs["start"] = str(cal.start)
    group.attrs["n_points"] = int(cal.n_points)


def _read_pinhole(group: h5py.Group) -> PinholeCalibration:
    size = np.asarray(group.attrs["image_size"])
    distortion = str(group.attrs["distortion"])
    return PinholeCalibration(
        image_size=(int(size[0]), int(size[1])),
        model=PinholeModel(
            distortion=tuple(distortion.split(",")) if distortion else (),
            tilted=bool(group.attrs["tilted"]),
            fixed_principal_point=bool(group.attrs.get("fixed_principal_point", False)),
        ),
        params=_array(group, "params", ndim=1),
        rms=float(group.attrs["rms"]),
        start=str(group.attrs["start"]),
        n_points=int(group.attrs["n_points"]),
    )


# -- pinhole behind a flat window ------------------------------------------------------------
_WINDOW_ATTRS = {
    "window_normal": "normal",
    "window_distance": "distance",
    "window_thickness": "thickness",
    "glass_index": "glass_index",
    "medium_index": "medium_index",
    "air_index": "air_index",
}


def _write_refractive_pinhole(group: h5py.Group, cal: RefractivePinholeCalibration) -> None:
    _write_pinhole(group, cal.pinhole)
    window = cal.window.as_dict()
    for attr, field in _WINDOW_ATTRS.items():
        group.attrs[attr] = window[field]


def _read_refractive_pinhole(group: h5py.Group) -> RefractivePinholeCalibration:
    window = FlatWindow(**{field: group.attrs[attr] for attr, field in _WINDOW_ATTRS.items()})
    return RefractivePinholeCalibration(_read_pinhole(group), window)


# -- Soloff ----------------------------------------------------------------------------------
_SOLOFF_ARRAYS = ("centre", "scale", "coefficients", "inverse", "z_levels", "residual_px")


def _write_soloff(group: h5py.Group, cal: SoloffCalibration) -> None:
    group.attrs["image_size"] = np.asarray(cal.image_size, dtype=np.int64)
    for name in _SOLOFF_ARRAYS:
        group.create_dataset(name, data=np.asarray(getattr(cal, name), dtype=np.float64))


def _read_soloff(group: h5py.Group) -> SoloffCalibration:
    size = np.asarray(group.attrs["image_size"])
    return SoloffCalibration(
        image_size=(int(size[0]), int(size[1])),
        **{name: _array(group, name) for name in _SOLOFF_ARRAYS},
    )


register_codec(ModelFreeCalibration, "model-free", _write_model_free, _read_model_free)
register_codec(TsaiCalibration, "tsai", _write_tsai, _read_tsai)
register_codec(PinholeCalibration, "opencv-pinhole", _write_pinhole, _read_pinhole)
register_codec(SoloffCalibration, "soloff", _write_soloff, _read_soloff)
register_codec(
    RefractivePinholeCalibration,
    "refractive-pinhole",
    _write_refractive_pinhole,
    _read_refractive_pinhole,
)


def _line_parameters(group: h5py.Group, shape: tuple) -> np.ndarray:
    """Ray coefficients: 4 (straight) or 6 (curved) rows over the grid."""
    params = _array(group, "line_parameters", ndim=3)
    if params.shape[0] not in (4, 6) or params.shape[1:] != tuple(shape):
        raise ValueError(f"line_parameters has shape {params.shape}, expected (4 or 6, {shape})")
    return params


def _array(
    group: h5py.Group, name: str, *, ndim: int | None = None, shape: tuple | None = None
) -> np.ndarray:
    obj = group[name]
    if not isinstance(obj, h5py.Dataset):
        raise TypeError(f"{obj.name} is not a dataset")
    arr = np.asarray(obj[()], dtype=np.float64)
    if (ndim is not None and arr.ndim != ndim) or (shape is not None and arr.shape != shape):
        want = shape if shape is not None else f"{ndim}-D"
        raise ValueError(f"{obj.name} has shape {arr.shape}, expected {want}")
    return arr


# -- files ---------------------------------------------------------------------------------
def save_calibrations(
    path: str | os.PathLike,
    calibrations: Mapping[str, CameraModel],
    *,
    metadata: Mapping[str, str | int | float] | None = None,
    calibrated_volume: Box | None = None,
) -> Path:
    """Write the calibrations of a rig's cameras to one file, atomically.

    Parameters
    ----------
    path : path-like
        The file to (over)write.
    calibrations : mapping of str to calibration
        Camera name → calibration (a registered type: ``ModelFreeCalibration``,
        ``TsaiCalibration``).
    metadata : mapping of str to str, int or float, optional
        Stored as root attributes (e.g. the dataset it was made from).
    calibrated_volume : (lower, upper), optional
        The box the calibration was fitted in (the plate's dots over the traverse, or a
        target's points), m: what :func:`read_calibrated_volume` gives back.

    Returns
    -------
    Path
        The written file.

    Raises
    ------
    TypeError
        A calibration of a type the format does not know.
    ValueError
        No calibrations, a bad camera name or metadata key.

    Examples
    --------
    A rig of two Tsai cameras written and read back: the loaded cameras image a point
    at the same pixels.

    >>> import pathlib, tempfile
    >>> import numpy as np
    >>> import ptv
    >>> from scipy.spatial.transform import Rotation
    >>> def camera(angle):  # 0.5 m from the origin, turned ``angle`` degrees about Y
    ...     turn = Rotation.from_euler("y", angle, degrees=True).as_matrix()
    ...     return ptv.TsaiCalibration(turn, [0, 0, 0.5], focal_length=0.05, kappa1=0.0,
    ...                                sx=1.0, principal_point=(319.5, 239.5),
    ...                                pixel_size=(1e-5, 1e-5))
    >>> rig = {"left": camera(-20), "right": camera(20)}
    >>> tmp = tempfile.TemporaryDirectory()
    >>> box = ((-0.01, -0.01, -0.002), (0.01, 0.01, 0.002))  # where it was fitted, m
    >>> path = ptv.save_calibrations(pathlib.Path(tmp.name) / "tsai.h5", rig,
    ...                              calibrated_volume=box)
    >>> loaded = ptv.load_calibrations(path)
    >>> list(loaded)
    ['left', 'right']
    >>> point = np.array([[1e-3, 2e-3, 0.0]])
    >>> all(np.array_equal(loaded[c].project(point), rig[c].project(point)) for c in rig)
    True
    >>> tmp.cleanup()
    """
    path = Path(path)
    if not calibrations:
        raise ValueError("no calibrations to save")
    codecs = {}
    for name, cal in calibrations.items():
        codec = _BY_TYPE.get(type(cal))
        if codec is None:
            known = ", ".join(sorted(c.__name__ for c in _BY_TYPE))
            raise TypeError(
                f"camera {name!r}: cannot save a {type(cal).__name__} "
                f"(the file format knows {known})"
            )
        codecs[check_file_name(name, "camera name")] = codec
    reserved = {"format", "format_version", "written_by", "calibrated_volume"}
    if calibrated_volume is not None:
        calibrated_volume = check_box("calibrated_volume", calibrated_volume)
    for key in metadata or {}:
        if not isinstance(key, str) or key in reserved:
            raise ValueError(
                f"metadata key {key!r} is not a string or is reserved ({sorted(reserved)})"
            )
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with h5py.File(tmp, "w") as f:
            f.attrs["format"] = FORMAT_NAME
            f.attrs["format_version"] = FORMAT_VERSION
            f.attrs["written_by"] = "synptv ptv.calibration.io"
            for key, value in (metadata or {}).items():
                f.attrs[key] = value
            if calibrated_volume is not None:
                f.attrs["calibrated_volume"] = np.asarray(calibrated_volume, dtype=np.float64)
            cameras = f.create_group("cameras", track_order=True)
            for name, cal in calibrations.items():
                group = cameras.create_group(name)
                group.attrs["model"] = codecs[name].model
                codecs[name].write(group, cal)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    log.info("wrote %d calibration(s) to %s", len(calibrations), path)
    return path


def load_calibrations(path: str | os.PathLike) -> dict[str, CameraModel]:
    """Read the calibrations of a rig written by :func:`save_calibrations`.

    Parameters
    ----------
    path : path-like
        The file.

    Returns
    -------
    dict of str to calibration
        Camera name → calibration, in the order they were saved.

    Raises
    ------
    FileNotFoundError
        No such file.
    CalibrationFileError
        A folder, not HDF5, an HDF5 file of another program, a newer format version, an unknown
        model, or missing or malformed entries (the message names the file).

    Examples
    --------
    A calibration written by :func:`save_calibrations` (or ``synptv calibrate``) maps
    pixels to the same rays once read back:

    >>> import pathlib, tempfile
    >>> import numpy as np
    >>> import ptv
    >>> from scipy.spatial.transform import Rotation
    >>> def camera(angle):  # 0.5 m from the origin, turned ``angle`` degrees about Y
    ...     turn = Rotation.from_euler("y", angle, degrees=True).as_matrix()
    ...     return ptv.TsaiCalibration(turn, [0, 0, 0.5], focal_length=0.05, kappa1=0.0,
    ...                                sx=1.0, principal_point=(319.5, 239.5),
    ...                                pixel_size=(1e-5, 1e-5))
    >>> tmp = tempfile.TemporaryDirectory()
    >>> path = pathlib.Path(tmp.name) / "tsai.h5"
    >>> _ = ptv.save_calibrations(path, {"left": camera(-20), "right": camera(20)})
    >>> rig = ptv.load_calibrations(path)
    >>> {name: type(cal).__name__ for name, cal in rig.items()}
    {'left': 'TsaiCalibration', 'right': 'TsaiCalibration'}
    >>> pixels = np.array([[319.5, 239.5]])
    >>> bool(np.allclose(rig["right"].pixel_to_ray(pixels).directions,
    ...                  camera(20).pixel_to_ray(pixels).directions))
    True
    >>> tmp.cleanup()
    """
    path = Path(path)
    if path.is_dir():
        raise CalibrationFileError(
            f"{path} is a folder, not a calibration file (synptv calibrate writes "
            "<method>.h5 files into its folder)"
        )
    if not path.is_file():
        raise FileNotFoundError(f"calibration file {path} does not exist")
    try:
        f = h5py.File(path, "r")
    except OSError as err:
        raise CalibrationFileError(
            f"{path} is not a synptv calibration file: not readable as HDF5 ({err})"
        ) from None
    with f:
        fmt = f.attrs.get("format")
        if isinstance(fmt, bytes):
            fmt = fmt.decode(errors="replace")
        if fmt != FORMAT_NAME:
            raise CalibrationFileError(
                f"{path} is not a synptv calibration file: it was written by another "
                f"program (format attribute {fmt!r}, expected {FORMAT_NAME!r})"
            )
        version = f.attrs.get("format_version")
        if not isinstance(version, int | np.integer) or version < 1:
            raise CalibrationFileError(
                f"{path}: corrupt calibration file: format_version {version!r}"
            )
        if version > FORMAT_VERSION:
            raise CalibrationFileError(
                f"{path} has calibration format version {int(version)}, newer than this "
                f"synptv reads ({FORMAT_VERSION}): upgrade synptv"
            )
        cameras = f.get("cameras")
        if not isinstance(cameras, h5py.Group) or len(cameras) == 0:
            raise CalibrationFileError(f"{path}: corrupt calibration file: no cameras")
        out: dict[str, CameraModel] = {}
        for name in cameras:
            group = cameras[name]
            model = group.attrs.get("model") if isinstance(group, h5py.Group) else None
            if isinstance(model, bytes):
                model = model.decode(errors="replace")
            codec = _BY_MODEL.get(model)  # type: ignore[arg-type]
            if codec is None:
                raise CalibrationFileError(
                    f"{path}: camera {name!r} has an unknown calibration model {model!r} "
                    f"(known: {', '.join(sorted(_BY_MODEL))})"
                )
            try:
                out[name] = codec.read(group)
            except (KeyError, ValueError, TypeError, OSError) as err:
                raise CalibrationFileError(
                    f"{path}: camera {name!r} ({model}): corrupt or incomplete entry: {err}"
                ) from None
    return out


def read_calibrated_volume(path: str | os.PathLike) -> Box | None:
    """The box a calibration file records it was fitted in, m, or None when it records
    none (a file written before synptv recorded it, or without the dots).

    Raises
    ------
    CalibrationFileError
        A recorded box that is not (2, 3) finite numbers with lower < upper.
    """
    path = Path(path)
    with h5py.File(path, "r") as f:
        value = f.attrs.get("calibrated_volume")
    if value is None:
        return None
    try:
        return check_box("calibrated_volume", np.asarray(value, dtype=np.float64))
    except ValueError as err:
        raise CalibrationFileError(f"{path}: corrupt calibration file: {err}") from None
