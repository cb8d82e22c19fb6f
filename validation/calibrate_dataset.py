"""Calibrate the cameras of a dataset folder from its plate images (``synptv calibrate``).

Works on any folder in the ``synptv render`` layout, real or synthetic: it reads
``experiment.json`` and ``calibration/<camera>/plane_<jj>.tif``, finds and indexes the
dots, calibrates every camera with each requested method and writes one calibration
file per method. The Table 1 metric is computed against the nominal dot positions (as
in the paper) and, when the folder holds a ``truth.h5``, against the true centres too.
"""

import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np
import tifffile

from ptv.calibration.io import save_calibrations
from ptv.calibration.methods import CALIBRATION_METHODS, CameraSheet, calibrate
from ptv.calibration.targets import PlateDescription, find_dots
from simulator.target import PlateDesign
from validation.calibration_accuracy import PlaneDots, nominal_positions, table1_errors

Progress = Callable[[int, int], None]


@dataclass(frozen=True)
class DatasetCalibration:
    """What ``synptv calibrate`` found.

    Attributes
    ----------
    dots : list (per camera) of list (per plane) of PlaneDots
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
    path = folder / "experiment.json"
    if not path.is_file():
        raise ValueError(f"{folder} is not a dataset: {path.name} is missing")
    return json.loads(path.read_text())


def _design(target: dict) -> PlateDesign:
    """The nominal plate of experiment.json's ``target``."""
    keys = ("pitch", "dot_diameter", "mark_diameter", "columns", "rows", "thickness")
    return PlateDesign(**{key: target[key] for key in keys})


def _true_positions(folder: Path) -> np.ndarray | None:
    """True dot centres (N_Z, D, 3) from truth.h5, or None for a real experiment."""
    path = folder / "truth.h5"
    if not path.is_file():
        return None
    with h5py.File(path) as truth:
        return truth["plate/dots_world"][:]


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
    return true, nominal_positions(_design(spec["target"]), spec["traverse_z"])


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
    z = [float(v) for v in spec["traverse_z"]]
    cameras = list(spec["cameras"])
    total = len(cameras) * (len(z) + len(methods))
    done = 0
    dots = []
    for name in cameras:
        planes = []
        for j, zj in enumerate(z):
            path = folder / "calibration" / name / f"plane_{j:02d}.tif"
            found = find_dots(tifffile.imread(path), description, source=str(path))
            planes.append(PlaneDots(zj, found.indices, found.pixels, description.pitch))
            done += 1
            if progress is not None:
                progress(done, total)
        dots.append(planes)
    design = _design(spec["target"])
    references = {"nominal": nominal_positions(design, z), "true": _true_positions(folder)}
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
            done += 1
            if progress is not None:
                progress(done, total)
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
    out.mkdir(parents=True, exist_ok=True)
    metadata = {"dataset": str(folder)}
    files = {
        method: str(save_calibrations(out / f"{method}.h5", calibrations, metadata=metadata))
        for method, calibrations in fitted_models.items()
    }
    return DatasetCalibration(dots, residuals, table1, files, errors)
