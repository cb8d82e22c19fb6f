"""Calibrate a dataset folder's cameras and score them (``synptv calibrate``).

Works on any folder with an experiment.json that describes its plate, real or
synthetic: :mod:`ptv.calibration.plate_images` finds and indexes the dots and calibrates
every camera with each requested method (no truth involved); this module writes one
calibration file per method and computes the Table 1 metric against the nominal dot
positions (as in the paper) and, when the folder holds a ``truth.h5``, against the
true centres too. A folder whose target is a 3-D target of listed points, imaged once
per camera, is calibrated by :func:`calibrate_point_dataset`
(:mod:`ptv.calibration.point_experiment`): one pinhole per camera.
"""

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

from ptv.calibration.grid_errors import PositionErrors, TraverseDots, table1_errors
from ptv.calibration.io import save_calibrations
from ptv.calibration.methods import CALIBRATION_METHODS, check_planes
from ptv.calibration.plate_images import (
    CameraCalibrationError,
    PlateSetup,
    calibrate_cameras,
    find_traverse_dots,
    nominal_grid,
    plate_setup,
)
from ptv.calibration.plate_offsets import MODES as PLATE_OFFSET_MODES
from ptv.calibration.plate_offsets import PlateOffsets, estimate_plate_offsets
from ptv.calibration.point_experiment import (
    calibrate_point_cameras,
    point_target_setup,
    target_errors,
)
from ptv.calibration.point_target import PointTargetFit, principal_point_warning
from ptv.calibration.reprojection import large_plane_residual, reprojection_rms
from ptv.io.dataset import DatasetError
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
        ``{method: {"nominal": {...}, "true": {...}, "corrected": {...}}}`` with d_X_um,
        d_Y_um, d_Z_um, d_um, coverage ("true" only when truth.h5 exists, "corrected"
        only with a self-calibrated plate).
    files : dict
        ``{method: path}`` of the written calibration files.
    errors : dict
        ``{method: {"nominal": PositionErrors, "true": PositionErrors}}``, the per-dot
        errors behind ``table1``.
    leave_one_plane_out : dict
        ``{method: {"d_um": mean, "planes_d_um": [...]}}``: each plate position's dots
        triangulated by calibrations fitted on the other positions, mean 3-D distance to
        their nominal positions (or to the corrected grid of the plate self-calibrated
        on the other positions), µm (empty with fewer than three positions).
    warnings : list of str
        What the user should know about the result (two plate positions: Z unchecked).
    plate_offsets : PlateOffsets or None
        The plate's estimated offsets from its nominal grid, when self-calibrated.
    failed : dict
        ``{method: {"camera", "reason"}}``: the methods that could not fit a camera and
        were not required (none of their results or files is kept).
    per_image : dict
        ``{camera: [{"image", "z_m", "dots", "rms_px": {method: px}}, ...]}``: per plate
        image, its dots found and each method's reprojection RMS of them, px.
    """

    dots: list
    max_plane_residual_px: dict
    table1: dict
    files: dict
    errors: dict
    leave_one_plane_out: dict
    warnings: list[str]
    plate_offsets: PlateOffsets | None = None
    failed: dict = field(default_factory=dict)
    per_image: dict = field(default_factory=dict)


#: Fewest plate positions for a leave-one-plane-out error (two are needed to calibrate).
LEAVE_ONE_OUT_PLANES = 3


def leave_one_plane_out(
    setup: PlateSetup,
    dots: dict[str, list[TraverseDots]],
    method: str,
    indices: np.ndarray,
    nominal: np.ndarray,
    *,
    plate_offsets: str | None = None,
) -> dict:
    """Each plate position's dots triangulated by the calibrations of the others.

    Parameters
    ----------
    setup : PlateSetup
        The plate, traverse and cameras.
    dots : dict of str to list of TraverseDots
        The dots found, per camera.
    method : str
        Calibration method.
    indices, nominal : ndarray
        The plate's grid indices (D, 2) and their nominal positions (N_Z, D, 3), m.
    plate_offsets : str, optional
        A mode of :func:`ptv.calibration.plate_offsets.estimate_plate_offsets`: the
        plate is self-calibrated on the other positions too, and the held-out dots are
        compared with that corrected grid.

    Returns
    -------
    dict
        ``d_um``: the mean over the positions of their mean 3-D distance, µm;
        ``planes_d_um``: per position.
    """
    per_plane = []
    for j in range(len(setup.z)):
        others = [k for k in range(len(setup.z)) if k != j]
        fitted, expected = dots, nominal
        if plate_offsets is not None:
            kept = {name: [planes[k] for k in others] for name, planes in dots.items()}
            offsets = estimate_plate_offsets(kept, mode=plate_offsets)
            fitted, expected = offsets.corrected(dots), offsets.positions(indices, setup.z)
        models = calibrate_cameras(setup, fitted, method, fit_planes=others)
        errors = table1_errors(
            list(models.values()), [dots[n] for n in models], indices, expected, planes=[j]
        )
        per_plane.append(errors.d * 1e6)
    return {"d_um": float(np.mean(per_plane)), "planes_d_um": per_plane}


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
    setup = plate_setup(folder)
    _, nominal = nominal_grid(setup, {})
    return true, nominal


def check_methods(methods: Sequence[str]) -> None:
    """Refuse an empty list of calibration methods or an unknown one (ValueError)."""
    unknown = [m for m in methods if m not in CALIBRATION_METHODS]
    if unknown or not methods:
        raise ValueError(
            f"calibration methods must be some of {', '.join(CALIBRATION_METHODS)}; got "
            f"{', '.join(map(repr, methods)) or 'none'}"
        )


def calibrate_dataset(
    folder: Path,
    *,
    methods: Sequence[str] = ("model-free", "tsai", "pinhole", "soloff"),
    out: Path | None = None,
    fit_planes: Sequence[int] | None = None,
    plate_offsets: str | None = None,
    progress: Progress | None = None,
    required: Sequence[str] | None = None,
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
    plate_offsets : str, optional
        Self-calibrate the plate (``"rows-columns"`` or ``"dots"``,
        :mod:`ptv.calibration.plate_offsets`) on the fitted positions: every method is
        fitted on the corrected grid, and Table 1 is also taken against it
        (``"corrected"``).
    progress : callable(done, total), optional
        Called after each plate image and each calibration.
    required : sequence of str, optional
        The methods whose failure on a camera stops the work (default: every method);
        another that cannot fit a camera is reported in ``failed`` and left out.

    Returns
    -------
    DatasetCalibration

    Raises
    ------
    FileNotFoundError
        ``folder`` holds no experiment.json.
    ValueError
        An unknown method, or one the traverse has too few planes for
        (:func:`ptv.calibration.methods.check_planes`); or
        (:class:`ptv.io.dataset.DatasetError`) a bad field of
        experiment.json, a plate image missing or unreadable, an unreadable truth.h5,
        all found before any dot is searched; a required method that cannot fit a
        camera (:class:`ptv.calibration.plate_images.CameraCalibrationError`). Nothing is
        written unless every required method calibrates.
    """
    check_methods(methods)
    if plate_offsets is not None and plate_offsets not in PLATE_OFFSET_MODES:
        raise ValueError(
            f"plate offsets must be one of {', '.join(PLATE_OFFSET_MODES)}; got {plate_offsets!r}"
        )
    folder = Path(folder)
    setup = plate_setup(folder)
    fitted_z = setup.z if fit_planes is None else [setup.z[j] for j in fit_planes]
    try:
        check_planes(methods, len(set(fitted_z)))
    except ValueError as error:
        raise DatasetError(f"{folder / 'experiment.json'}: traverse_z: {error}") from None
    true = _true_positions(folder)  # read before the long work: a bad file fails now
    if true is not None and true.shape[0] != len(setup.z):
        raise DatasetError(
            f"{folder / 'truth.h5'}: plate/dots_world holds {true.shape[0]} plate positions, "
            f"but experiment.json's traverse_z gives {len(setup.z)}"
        )
    total = len(setup.cameras) * (len(setup.z) + len(methods))
    done = 0

    def tick() -> None:
        nonlocal done
        done += 1
        if progress is not None:
            progress(done, total)

    dots = find_traverse_dots(setup, tick)
    warnings = []
    if len(setup.z) < LEAVE_ONE_OUT_PLANES:
        warnings.append(
            f"only {len(setup.z)} plate positions: the calibration fits them exactly in Z, "
            "so nothing checks it in Z (no leave-one-plane-out error; use three or more)"
        )
    indices, nominal = nominal_grid(setup, dots)
    references = {"nominal": nominal, "true": true}
    offsets, fitted_dots = None, dots
    if plate_offsets is not None:
        fitted = dots
        if fit_planes is not None:
            fitted = {name: [p[j] for j in fit_planes] for name, p in dots.items()}
        offsets = estimate_plate_offsets(fitted, mode=plate_offsets)
        fitted_dots = offsets.corrected(dots)
        references["corrected"] = offsets.positions(indices, setup.z)
    table1, fitted_models, residuals, errors, held_out, failed = {}, {}, {}, {}, {}, {}
    must_fit = set(methods if required is None else required)
    for method in methods:
        try:
            calibrations = calibrate_cameras(setup, fitted_dots, method, fit_planes=fit_planes)
            if len(setup.z) >= LEAVE_ONE_OUT_PLANES:
                held_out[method] = leave_one_plane_out(
                    setup, dots, method, indices, nominal, plate_offsets=plate_offsets
                )
        except CameraCalibrationError as err:
            if method in must_fit:
                raise
            failed[method] = {"camera": err.camera, "reason": err.reason}
            warnings.append(f"{err}; the run goes on without {method}")
            for _ in setup.sheets:
                tick()
            continue
        for _ in calibrations:
            tick()
        if method == "model-free":
            residuals = {
                name: max(p.residual_px.max() for p in model.planes)
                for name, model in calibrations.items()
            }
            warnings += _large_plane_residuals(setup, fitted_dots, calibrations, fit_planes)
        models = list(calibrations.values())
        per_camera = [dots[name] for name in calibrations]
        errors[method] = {
            name: table1_errors(models, per_camera, indices, expected)
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
            save_calibrations(
                staging / f"{method}.h5",
                calibrations,
                metadata=metadata,
                calibrated_volume=_plate_volume(fitted_dots, fit_planes),
            )
    files = {method: str(out / f"{method}.h5") for method in fitted_models}
    return DatasetCalibration(
        list(dots.values()),
        residuals,
        table1,
        files,
        errors,
        held_out,
        warnings,
        offsets,
        failed,
        _per_image(setup, fitted_dots, fitted_models),
    )


def _plate_volume(dots: dict, fit_planes: Sequence[int] | None) -> tuple | None:
    """The box the plate's dots span over the traverse positions fitted on (default:
    all), m: every dot any camera found (its plate position, offsets included) at its
    traverse reading."""
    world = np.concatenate(
        [
            np.column_stack([o.world_xy, np.full(len(o.world_xy), o.z)])
            for planes in dots.values()
            for j, plane in enumerate(planes)
            if fit_planes is None or j in fit_planes
            for o in (plane.observation(),)
        ]
    )
    return _spanned_box(world)


def _spanned_box(points: np.ndarray) -> tuple | None:
    """(lower, upper) corners of the points (N, 3), m; None when they are flat on an
    axis (a box needs depth)."""
    lower, upper = points.min(axis=0), points.max(axis=0)
    if not np.all(lower < upper):
        return None
    return tuple(float(v) for v in lower), tuple(float(v) for v in upper)


def _image_names(setup: PlateSetup, camera: str) -> list[str]:
    """Each plate position's image of ``camera`` as the messages name it: the file
    name, or the position with dot lists."""
    if setup.images:
        return [path.name for path in setup.images[camera]]
    return [f"plate position {j}" for j in range(len(setup.z))]


def _per_image(setup: PlateSetup, dots: dict, models: dict) -> dict:
    """``DatasetCalibration.per_image``: per camera and plate image, the dots found and
    each method's reprojection RMS of them."""
    return {
        name: [
            {
                "image": image,
                "z_m": plane.z,
                "dots": len(plane.indices),
                "rms_px": {
                    method: reprojection_rms(calibrations[name], plane)
                    for method, calibrations in models.items()
                },
            }
            for plane, image in zip(dots[name], _image_names(setup, name), strict=True)
        ]
        for name in setup.cameras
    }


def _large_plane_residuals(
    setup: PlateSetup, dots: dict, calibrations: dict, fit_planes: Sequence[int] | None
) -> list[str]:
    """Warnings for the model-free plane fits that miss a dot by more than the paper's
    2 px (:func:`ptv.calibration.reprojection.large_plane_residual`)."""
    fitted = range(len(setup.z)) if fit_planes is None else fit_planes
    warnings = (
        large_plane_residual(
            name,
            model,
            [dots[name][j] for j in fitted],
            [_image_names(setup, name)[j] for j in fitted],
        )
        for name, model in calibrations.items()
    )
    return [warning for warning in warnings if warning is not None]


#: The one method a point target calibrates with.
POINT_TARGET_METHOD = "pinhole"


@dataclass(frozen=True)
class PointTargetCalibration:
    """What ``synptv calibrate`` found on a dataset with a point target.

    Attributes
    ----------
    fits : dict of str to PointTargetFit
        Per camera: the pinhole, the target points used and their residuals.
    errors : PositionErrors
        The target points used by two or more cameras, triangulated back, against their
        listed positions.
    files : dict
        ``{"pinhole": path}`` of the written calibration file.
    warnings : list of str
        A camera whose fitted principal point lies off its sensor
        (:func:`ptv.calibration.point_target.principal_point_warning`).
    """

    fits: dict[str, PointTargetFit]
    errors: PositionErrors
    files: dict
    warnings: list[str] = field(default_factory=list)

    def as_dict(self) -> dict:
        """JSON-able: per camera the fit's summary (reprojection RMS, points used, ...),
        the target points' errors (d_X_um, d_Y_um, d_Z_um, d_um, count) and the files."""
        return {
            "cameras": {name: fit.summary() for name, fit in self.fits.items()},
            "target_points": {
                **{k: v for k, v in self.errors.summary().items() if k != "coverage"},
                "points": len(self.errors.truth),
            },
            "files": self.files,
            "warnings": self.warnings,
        }


def calibrate_point_dataset(
    folder: Path, *, out: Path | None = None, progress: Progress | None = None
) -> PointTargetCalibration:
    """Calibrate every camera of a dataset from its image of a point target, and save.

    Parameters
    ----------
    folder : Path
        Dataset folder whose experiment.json gives a point target.
    out : Path, optional
        Folder for the calibration file, ``pinhole.h5`` (``<folder>/calibrations`` by
        default).
    progress : callable(done, total), optional
        Called after each camera.

    Returns
    -------
    PointTargetCalibration

    Raises
    ------
    FileNotFoundError
        No experiment.json, target file, seed file or image.
    ValueError
        A bad experiment.json, target file, seed file or image (found before any dot is
        searched), or a camera that cannot be calibrated (naming its image). Nothing is
        written unless every camera calibrates.
    """
    folder = Path(folder)
    setup = point_target_setup(folder)
    done = 0

    def tick() -> None:
        nonlocal done
        done += 1
        if progress is not None:
            progress(done, len(setup.cameras))

    fits = calibrate_point_cameras(setup, tick)
    errors = target_errors(setup.target, fits)
    out = Path(out) if out is not None else folder / "calibrations"
    calibrations = {name: fit.calibration for name, fit in fits.items()}
    with staged_output(out) as staging:
        used = setup.target.points[np.unique(np.concatenate([f.rows for f in fits.values()]))]
        save_calibrations(
            staging / f"{POINT_TARGET_METHOD}.h5",
            calibrations,
            metadata={"dataset": str(folder)},
            calibrated_volume=_spanned_box(used),
        )
    warnings = [principal_point_warning(name, fit) for name, fit in fits.items()]
    return PointTargetCalibration(
        fits,
        errors,
        {POINT_TARGET_METHOD: str(out / f"{POINT_TARGET_METHOD}.h5")},
        [warning for warning in warnings if warning is not None],
    )
