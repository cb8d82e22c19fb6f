"""Calibrate the cameras of a dataset folder from its plate images (``synptv calibrate``).

Works on any folder in the ``synptv render`` layout, real or synthetic: it reads
``experiment.json`` and ``calibration/<camera>/plane_<jj>.tif``, finds and indexes the
dots, calibrates every camera with each requested method and writes one calibration
file per method. The Table 1 metric is computed against the nominal dot positions (as
in the paper) and, when the folder holds a ``truth.h5``, against the true centres too.
"""

import hashlib
import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np
import tifffile

from ptv.calibration.io import save_calibrations
from ptv.calibration.methods import CALIBRATION_METHODS, CameraSheet, calibrate
from ptv.calibration.targets import PlateDescription, find_dots
from ptv.dataset import DatasetError, read_description
from simulator.target import PlateDesign
from validation.truth.calibration_errors import TraverseDots, nominal_positions, table1_errors
from validation.workflow.files import staged_output

Progress = Callable[[int, int], None]


@dataclass(frozen=True)
class DatasetCalibration:
    """What ``synptv calibrate`` found.

    Attributes
    ----------
    dots : list (per camera) of list (per plane) of TraverseDots
        Identified dots.
    max_plane_residual_px : dict
        Largest |T_j⁻¹(X, Y) − pixel| per camera over all planes, px (model-free).
    table1 : dict
        ``{method: {"nominal": {...}, "true": {...}}}`` with d_X_um, d_Y_um, d_Z_um,
        d_um, coverage ("true" only when truth.h5 exists).
    files : dict
        ``{method: path}`` of the written calibration files.
    errors : dict
        ``{method: {"nominal": PositionErrors, "true": PositionErrors}}``, the per-dot
        errors behind ``table1``.
    """

    dots: list
    max_plane_residual_px: dict
    table1: dict
    files: dict
    errors: dict


def _read_experiment(folder: Path) -> dict:
    """experiment.json with the fields calibrating needs checked (errors name file and
    field)."""
    spec = read_description(folder)
    path = folder / "experiment.json"
    if not isinstance(spec.get("target"), dict):
        raise DatasetError(
            f"{path}: 'target' must be an object (the plate), got {spec.get('target')!r}"
        )
    z = spec.get("traverse_z")
    if not (isinstance(z, list) and z and all(_finite_number(v) for v in z)):
        raise DatasetError(
            f"{path}: 'traverse_z' must be a list of plane positions in m, got {z!r}"
        )
    cameras = spec.get("cameras")
    if not isinstance(cameras, dict) or not cameras:
        raise DatasetError(f"{path}: 'cameras' must be a non-empty object, got {cameras!r}")
    for name, info in cameras.items():
        info = info if isinstance(info, dict) else {}
        size = info.get("image_size")
        if not (isinstance(size, list) and len(size) == 2 and all(_count(v) for v in size)):
            raise DatasetError(
                f"{path}: camera {name!r}: image_size must be [width, height] in px, got {size!r}"
            )
        for key in ("pixel_pitch", "focal_length"):
            if not (_finite_number(info.get(key)) and info[key] > 0):
                raise DatasetError(
                    f"{path}: camera {name!r}: {key} must be a number > 0 in m, got "
                    f"{info.get(key)!r}"
                )
    return spec


def _finite_number(value: object) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def _count(value: object) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and value >= 1


def _plate_image(path: Path) -> np.ndarray:
    """A plate image; errors name the file."""
    try:
        return tifffile.imread(path)
    except Exception as err:  # tifffile raises many kinds on a file that is no TIFF
        raise DatasetError(f"{path}: not readable as a TIFF image ({err})") from None


def _check_plate_images(paths: list[Path], image_size: list[int]) -> None:
    """One camera's plate images: each readable, of the declared [width, height], and no
    two the same (a traverse that did not move)."""
    width, height = image_size
    first_seen = {}
    for path in paths:
        image = _plate_image(path)
        if image.shape != (height, width):
            raise DatasetError(
                f"{path}: image of shape {image.shape}, but experiment.json gives "
                f"{width} × {height} px for this camera"
            )
        digest = hashlib.sha256(image.tobytes()).hexdigest()
        if digest in first_seen:
            raise DatasetError(
                f"{path}: the same image as {first_seen[digest].name} (a stuck traverse?)"
            )
        first_seen[digest] = path


#: RMS image shift of the dots between two traverse positions below which the plate is
#: taken not to have moved, px: a few times the scatter of a dot centre found twice on
#: independent noise (~0.02 px), far below the shift of a 1 mm step seen at any angle.
STUCK_TRAVERSE_SHIFT_PX = 0.1


def _check_traverse_moved(planes: list[TraverseDots], paths: list[Path]) -> None:
    """Refuse two traverse positions whose dots sit at the same pixels (the images differ
    only by noise: the traverse did not move)."""
    for (a, path_a), (b, path_b) in itertools.pairwise(zip(planes, paths, strict=True)):
        rows_a = {tuple(index): k for k, index in enumerate(a.indices.tolist())}
        common = [
            (rows_a[tuple(index)], k)
            for k, index in enumerate(b.indices.tolist())
            if tuple(index) in rows_a
        ]
        if not common:
            continue
        ka, kb = np.array(common).T
        shift = np.sqrt(np.mean(np.sum((a.pixels[ka] - b.pixels[kb]) ** 2, axis=1)))
        if shift < STUCK_TRAVERSE_SHIFT_PX:
            raise DatasetError(
                f"{path_b}: the plate's dots sit where they were in {path_a.name} "
                f"({shift:.3f} px RMS over {len(common)} dots, though traverse_z moved "
                f"{abs(b.z - a.z) * 1e3:g} mm): a stuck traverse?"
            )


def _checked_plate_paths(folder: Path, spec: dict, planes: int) -> list[list[Path]]:
    """The plate images of every camera (per camera, per plane), each checked: present,
    readable, of the declared size, no two the same."""
    paths = [[_plane_path(folder, name, j) for j in range(planes)] for name in spec["cameras"]]
    missing = [path for row in paths for path in row if not path.is_file()]
    if missing:
        raise DatasetError(
            f"{missing[0]}: plate image missing ({len(missing)} of {planes * len(paths)})"
        )
    for name, camera_paths in zip(spec["cameras"], paths, strict=True):
        _check_plate_images(camera_paths, spec["cameras"][name]["image_size"])
    return paths


def _camera_dots(
    paths: list[Path], z: list[float], description: PlateDescription, tick: Callable[[], None]
) -> list[TraverseDots]:
    """The dots found on one camera's plate images, one entry per traverse position;
    ``tick`` is called after each image."""
    planes = []
    for zj, path in zip(z, paths, strict=True):
        found = find_dots(_plate_image(path), description, source=str(path))
        planes.append(TraverseDots(zj, found.indices, found.pixels, description.pitch))
        tick()
    _check_traverse_moved(planes, paths)
    return planes


def _design(target: dict, path: Path) -> PlateDesign:
    """The nominal plate of experiment.json's ``target`` (``path``, for errors)."""
    keys = ("pitch", "dot_diameter", "mark_diameter", "columns", "rows", "thickness")
    missing = [key for key in keys if key not in target]
    if missing:
        raise DatasetError(f"{path}: target: missing {', '.join(missing)}")
    try:
        return PlateDesign(**{key: target[key] for key in keys})
    except (TypeError, ValueError) as err:
        raise DatasetError(f"{path}: target: {err}") from None


def _plane_path(folder: Path, camera: str, plane: int) -> Path:
    return folder / "calibration" / camera / f"plane_{plane:02d}.tif"


def _true_positions(folder: Path) -> np.ndarray | None:
    """True dot centres (N_Z, D, 3) from truth.h5, or None for a real experiment."""
    path = folder / "truth.h5"
    if not path.is_file():
        return None
    try:
        with h5py.File(path, "r") as truth:
            return truth["plate/dots_world"][:]
    except (OSError, KeyError) as err:
        raise DatasetError(f"{path}: cannot read plate/dots_world ({err})") from None


def dot_positions(folder: Path) -> tuple[np.ndarray, np.ndarray]:
    """True and nominal centres of every dot of a rendered dataset, (N_Z, D, 3) each, m.

    Raises
    ------
    ValueError
        The folder holds no truth.h5 (a real experiment).
    """
    folder = Path(folder)
    true = _true_positions(folder)
    if true is None:
        raise ValueError(f"{folder} has no truth.h5: the true dot centres are unknown")
    spec = _read_experiment(folder)
    return true, nominal_positions(
        _design(spec["target"], folder / "experiment.json"), spec["traverse_z"]
    )


def calibrate_dataset(
    folder: Path,
    *,
    methods: Sequence[str] = ("model-free", "tsai", "pinhole", "soloff"),
    out: Path | None = None,
    fit_planes: Sequence[int] | None = None,
    progress: Progress | None = None,
) -> DatasetCalibration:
    """Find the dots, calibrate every camera with each method, save, and score.

    Parameters
    ----------
    folder : Path
        Dataset folder (layout of ``synptv render``).
    methods : sequence of str
        Calibration methods (see ``ptv.calibration.methods``).
    out : Path, optional
        Folder for the calibration files (``<folder>/calibrations`` by default).
    fit_planes : sequence of int, optional
        Traverse positions the calibrations are fitted on (default: all); the Table 1
        metric is measured on every plane.
    progress : callable(done, total), optional
        Called after each plate image and each calibration.

    Returns
    -------
    DatasetCalibration

    Raises
    ------
    FileNotFoundError
        ``folder`` holds no experiment.json.
    ValueError
        An unknown method; or (:class:`ptv.dataset.DatasetError`) a bad field of
        experiment.json, a plate image missing or unreadable, an unreadable truth.h5,
        all found before any dot is searched. Nothing is written unless every method
        calibrates.
    """
    unknown = [m for m in methods if m not in CALIBRATION_METHODS]
    if unknown or not methods:
        raise ValueError(
            f"calibration methods must be some of {', '.join(CALIBRATION_METHODS)}; got "
            f"{', '.join(map(repr, methods)) or 'none'}"
        )
    folder = Path(folder)
    spec = _read_experiment(folder)
    description = PlateDescription.from_dict(spec["target"], source=str(folder / "experiment.json"))
    design = _design(spec["target"], folder / "experiment.json")
    z = [float(v) for v in spec["traverse_z"]]
    cameras = list(spec["cameras"])
    paths = _checked_plate_paths(folder, spec, len(z))
    true = _true_positions(folder)  # read before the long work: a bad file fails now
    if true is not None and true.shape[0] != len(z):
        raise DatasetError(
            f"{folder / 'truth.h5'}: plate/dots_world holds {true.shape[0]} plate positions, "
            f"but experiment.json's traverse_z gives {len(z)}"
        )
    total = len(cameras) * (len(z) + len(methods))
    done = 0

    def tick() -> None:
        nonlocal done
        done += 1
        if progress is not None:
            progress(done, total)

    dots = [_camera_dots(camera_paths, z, description, tick) for camera_paths in paths]
    references = {"nominal": nominal_positions(design, z), "true": true}
    table1, fitted_models, residuals, errors = {}, {}, {}, {}
    for method in methods:
        calibrations = {}
        for name, camera_dots in zip(cameras, dots, strict=True):
            info = spec["cameras"][name]
            sheet = CameraSheet(
                tuple(info["image_size"]), float(info["pixel_pitch"]), float(info["focal_length"])
            )
            fitted = camera_dots if fit_planes is None else [camera_dots[j] for j in fit_planes]
            calibrations[name] = calibrate(method, [d.observation() for d in fitted], sheet)
            if method == "model-free":
                residuals[name] = max(p.residual_px.max() for p in calibrations[name].planes)
            tick()
        models = list(calibrations.values())
        errors[method] = {
            name: table1_errors(models, dots, design.indices, expected)
            for name, expected in references.items()
            if expected is not None
        }
        table1[method] = {name: e.summary() for name, e in errors[method].items()}
        fitted_models[method] = calibrations
    # Written only once every method has calibrated: a method that fails leaves no file.
    out = Path(out) if out is not None else folder / "calibrations"
    metadata = {"dataset": str(folder)}
    with staged_output(out) as staging:
        for method, calibrations in fitted_models.items():
            save_calibrations(staging / f"{method}.h5", calibrations, metadata=metadata)
    files = {method: str(out / f"{method}.h5") for method in fitted_models}
    return DatasetCalibration(dots, residuals, table1, files, errors)
