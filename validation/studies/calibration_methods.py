"""Calibration method comparisons and studies: plane count and window obliquity.

Every comparison reports both metrics of :mod:`validation.truth.calibration_errors`: the
paper's in-sample Table 1 metric and the pure model error at random points. Plane
subsets span the full traverse depth (first, last and evenly spaced planes between)
and are always evaluated on the dots of every plane.
"""

import copy
import logging
from collections.abc import Callable, Sequence

import numpy as np

from ptv.calibration.grid_errors import TraverseDots, nominal_positions, table1_errors
from ptv.calibration.methods import CALIBRATION_METHODS, CameraSheet, calibrate
from ptv.camera_model import CameraModel
from simulator.optics import Camera
from simulator.particles import Box
from simulator.rigs import Rig, rig_from_dict
from simulator.target import (
    Imperfections,
    PhysicalPlate,
    PlateDesign,
    build_plate,
    traverse_positions,
)
from validation.truth.calibration_errors import model_errors, synthetic_plane_dots

log = logging.getLogger(__name__)

Progress = Callable[[int, int], None]

#: Where model errors are measured: the traverse depth and the plate's central area.
MODEL_VOLUME = Box((0.08, 0.08, 0.012))


def camera_sheet(camera: Camera) -> CameraSheet:
    """The nominal data-sheet values of a simulated camera (what its user would know)."""
    lens = camera.lens
    return CameraSheet(
        image_size=tuple(lens.sensor_size),
        pixel_pitch=lens.pixel_pitch,
        focal_length=lens.focal_length,
    )


def plane_subset(total: int, count: int) -> list[int]:
    """``count`` plane indices spanning all ``total`` planes (first and last included)."""
    if not 2 <= count <= total:
        raise ValueError(f"plane count must be in [2, {total}], got {count}")
    return sorted(set(np.round(np.linspace(0, total - 1, count)).astype(int).tolist()))


def calibrate_cameras(
    method: str,
    rig: Rig,
    dots: Sequence[Sequence[TraverseDots]],
    *,
    planes: Sequence[int] | None = None,
) -> list[CameraModel]:
    """Calibrate every camera of a rig with one method from (a subset of) its planes."""
    chosen = range(len(dots[0])) if planes is None else planes
    return [
        calibrate(method, [cam_dots[j].observation() for j in chosen], camera_sheet(camera))
        for camera, cam_dots in zip(rig.cameras, dots, strict=True)
    ]


def compare_methods(
    rig: Rig,
    plate: PhysicalPlate,
    dots: Sequence[Sequence[TraverseDots]],
    *,
    methods: Sequence[str] = tuple(CALIBRATION_METHODS),
    rng: np.random.Generator | int | None = None,
) -> dict[str, dict[str, dict[str, float]]]:
    """Table 1 metric and model error of each method on one set of dot observations.

    Returns
    -------
    dict
        ``{method: {"table1": {d_X_um, d_Y_um, d_Z_um, d_um, coverage},
        "model": {...}}}``.
    """
    expected = nominal_positions(plate.design.indices, plate.design.pitch, plate.z_nominal)
    out = {}
    for method in methods:
        calibrations = calibrate_cameras(method, rig, dots)
        out[method] = {
            "table1": table1_errors(calibrations, dots, plate.design.indices, expected).summary(),
            "model": model_errors(calibrations, rig.cameras, MODEL_VOLUME, rng=rng).summary(),
        }
        log.info("%s: Table 1 d = %.2f um", method, out[method]["table1"]["d_um"])
    return out


def plane_count_errors(
    rig: Rig,
    plate: PhysicalPlate,
    dots: Sequence[Sequence[TraverseDots]],
    count: int,
    *,
    method: str = "model-free",
    rng: np.random.Generator | int | None = None,
) -> dict[str, float]:
    """Errors of a calibration from ``count`` planes spanning the depth, on both metrics.

    Returns
    -------
    dict
        ``planes``, ``table1_d_um`` (on the dots of every plane) and ``model_d_um``
        (at random points), µm.
    """
    expected = nominal_positions(plate.design.indices, plate.design.pitch, plate.z_nominal)
    calibrations = calibrate_cameras(
        method, rig, dots, planes=plane_subset(len(plate.poses), count)
    )
    return {
        "planes": count,
        "table1_d_um": table1_errors(calibrations, dots, plate.design.indices, expected).d * 1e6,
        "model_d_um": model_errors(calibrations, rig.cameras, MODEL_VOLUME, rng=rng).d * 1e6,
    }


def relative_to_most_planes(rows: Sequence[dict[str, float]]) -> list[dict[str, float]]:
    """Rows of :func:`plane_count_errors` with their ratios to the largest plane count.

    Returns
    -------
    list of dict
        Copies of ``rows`` with ``table1_ratio`` and ``model_ratio`` added.
    """
    reference = max(rows, key=lambda row: row["planes"])
    return [
        {
            **row,
            "table1_ratio": row["table1_d_um"] / reference["table1_d_um"],
            "model_ratio": row["model_d_um"] / reference["model_d_um"],
        }
        for row in rows
    ]


def plane_count_study(
    rig: Rig,
    plate: PhysicalPlate,
    dots: Sequence[Sequence[TraverseDots]],
    *,
    counts: Sequence[int] = (2, 3, 5, 7, 9, 13),
    method: str = "model-free",
    rng: np.random.Generator | int | None = None,
    progress: Progress | None = None,
) -> list[dict[str, float]]:
    """Errors with N_Z planes spanning the depth, relative to all planes, on both metrics.

    Returns
    -------
    list of dict
        Per count: ``planes``, ``table1_d_um``, ``model_d_um`` and their ratios to the
        largest count (``table1_ratio``, ``model_ratio``).
    """
    rows = []
    for n, count in enumerate(counts):
        rows.append(plane_count_errors(rig, plate, dots, count, method=method, rng=rng))
        if progress is not None:
            progress(n + 1, len(counts))
    return relative_to_most_planes(rows)


def with_obliquity(spec: dict, obliquity_deg: float, direction_deg: float) -> dict:
    """A copy of a rig description with every window tilted as given."""
    spec = copy.deepcopy(spec)
    for camera in spec["cameras"]:
        if "window" in camera:
            camera["window"]["obliquity_deg"] = float(obliquity_deg)
            camera["window"]["obliquity_direction_deg"] = float(direction_deg)
    return spec


def obliquity_rows(
    spec: dict,
    plate: PhysicalPlate,
    obliquity_deg: float,
    direction_deg: float,
    *,
    methods: Sequence[str] = tuple(CALIBRATION_METHODS),
    noise_px: float = 0.05,
    rng: np.random.Generator | int | None = None,
) -> list[dict[str, float]]:
    """Every method's errors with the windows of a rig tilted as given.

    Parameters
    ----------
    spec : dict
        A rig description (e.g. ``paper-stereo``'s); its windows are re-tilted.
    plate : PhysicalPlate
        The plate and its traverse.
    obliquity_deg, direction_deg : float
        Window obliquity and its direction (0: in the camera plane, 45: diagonal), °.
    methods : sequence of str
        Calibration methods.
    noise_px : float
        Dot-centre noise, px.
    rng : numpy.random.Generator, int or None
        Noise and test points.

    Returns
    -------
    list of dict
        One row per method: Table 1 and model errors and the Table 1 ratio to the
        model-free method (to the first method when model-free is not among them).
    """
    rng = np.random.default_rng(rng)
    rig = rig_from_dict(
        with_obliquity(spec, obliquity_deg, direction_deg), source="obliquity study"
    )
    dots = synthetic_plane_dots(rig.cameras, plate, noise_px=noise_px, rng=rng)
    result = compare_methods(rig, plate, dots, methods=methods, rng=rng)
    reference = result.get("model-free", next(iter(result.values())))["table1"]["d_um"]
    return [
        {
            "direction_deg": direction_deg,
            "obliquity_deg": obliquity_deg,
            "method": method,
            **{f"table1_{k}": v for k, v in metrics["table1"].items()},
            **{f"model_{k}": v for k, v in metrics["model"].items()},
            "ratio_to_model_free": metrics["table1"]["d_um"] / reference,
        }
        for method, metrics in result.items()
    ]


def obliquity_study(
    spec: dict,
    *,
    angles_deg: Sequence[float] = (0.0, 5.0, 10.0, 15.0, 20.0),
    directions_deg: Sequence[float] = (0.0, 45.0),
    methods: Sequence[str] = tuple(CALIBRATION_METHODS),
    noise_px: float = 0.05,
    rng: np.random.Generator | int | None = None,
    progress: Progress | None = None,
) -> list[dict[str, float]]:
    """Every method's errors as the windows tilt, in the camera plane and diagonally.

    Parameters
    ----------
    spec : dict
        A rig description (e.g. ``paper-stereo``'s); its windows are re-tilted.
    angles_deg, directions_deg : sequences of float
        Window obliquities and their directions (0: in the camera plane, 45: diagonal).
    methods : sequence of str
        Calibration methods.
    noise_px : float
        Dot-centre noise, px.
    rng : numpy.random.Generator, int or None
        Plate, noise and test points.

    Returns
    -------
    list of dict
        One row per (direction, angle, method), as :func:`obliquity_rows`.
    """
    rng = np.random.default_rng(rng)
    plate = build_plate(PlateDesign(), traverse_positions(), imperfections=Imperfections(), rng=rng)
    rows = []
    points = [(d, a) for d in directions_deg for a in angles_deg]
    for n, (direction, angle) in enumerate(points):
        rows += obliquity_rows(
            spec, plate, angle, direction, methods=methods, noise_px=noise_px, rng=rng
        )
        if progress is not None:
            progress(n + 1, len(points))
    return rows
