"""Calibrate a dataset's cameras from one image each of a 3-D target of listed points.

The dataset folder's experiment.json gives a point target (docs/experiment.md §3b):
``target`` with the points file and its units, ``calibration_images`` (a pattern with
``{camera}`` only: one image per camera) and ``calibration_seeds``, a CSV file of seed
points (:func:`read_point_seeds`). :func:`point_target_setup` reads and checks all of
it, and every image, before any dot is searched; :func:`calibrate_point_cameras` fits
one pinhole per camera (:mod:`ptv.calibration.point_target`); :func:`target_errors`
triangulates the target points back from the cameras (the Table 1 metric of a plate,
on the target's own points).
"""

import csv
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ptv.calibration.grid_errors import PositionErrors
from ptv.calibration.plate_images import masked_image
from ptv.calibration.point_target import (
    MIN_SEEDS,
    UNITS,
    PointTarget,
    PointTargetFit,
    calibrate_point_target,
)
from ptv.calibration.refractive_pinhole import FlatWindow
from ptv.io.dataset import DatasetError, camera_masks
from ptv.io.experiment_file import has_point_target, read_experiment
from ptv.io.images import read_image
from ptv.triangulate import triangulate

__all__ = [
    "PointTargetSetup",
    "calibrate_point_cameras",
    "point_target_setup",
    "read_point_seeds",
    "target_errors",
]

#: Columns of a point target's seed file.
SEED_COLUMNS = ("camera", "X", "Y", "Z", "x", "y")
#: A seed names the target point within this distance of its X, Y, Z, m.
SEED_MATCH_M = 1e-6


@dataclass(frozen=True, eq=False)
class PointTargetSetup:
    """A dataset's point target, cameras, calibration images and seeds, all checked.

    Attributes
    ----------
    folder : Path
        The dataset folder.
    target : PointTarget
        The target and the pinhole model fitted to it.
    image_sizes : dict of str to (int, int)
        (width, height) of each camera, px, in experiment.json's order.
    focal_px : dict of str to float or None
        Nominal principal distance of each camera, px (focal length / pixel pitch, when
        experiment.json gives both).
    images : dict of str to Path
        Each camera's image of the target.
    masks : dict of str to ndarray of bool, shape (H, W)
        The masks of the cameras that have one (True where the image is used).
    seeds : dict of str to dict of int to (float, float)
        Per camera, target row → approximate pixel of each seed point.
    windows : dict of str to FlatWindow
        The cameras that look through a flat window into the medium, and their window.
    """

    folder: Path
    target: PointTarget
    image_sizes: dict[str, tuple[int, int]]
    focal_px: dict[str, float | None]
    images: dict[str, Path]
    masks: Mapping[str, np.ndarray]
    seeds: dict[str, dict[int, tuple[float, float]]]
    windows: dict[str, FlatWindow]

    @property
    def cameras(self) -> list[str]:
        """Camera names, in experiment.json's order."""
        return list(self.image_sizes)


def point_target_setup(folder: str | Path) -> PointTargetSetup:
    """Read and check everything calibrating ``folder`` from a point target needs.

    Raises
    ------
    FileNotFoundError
        No experiment.json, or a missing target file, seed file or image.
    ptv.io.experiment_file.DescriptionError
        experiment.json breaks its schema or lacks a field calibrating needs (every
        problem in one line).
    DatasetError
        The target is a plate; a bad target file or seed file (naming the file and the
        line or row); a bad ``calibration_images`` pattern; an image of the wrong size
        or unreadable; a camera with fewer than four seeds; a window whose glass or
        medium is less dense than its air.
    """
    folder = Path(folder)
    spec = read_experiment(folder, needs=("calibration",))
    source = folder / "experiment.json"
    if not has_point_target(spec):
        raise DatasetError(f"{source}: target: a plate, not a target of listed points")
    try:
        target = PointTarget.from_dict(spec["target"], folder, source=f"{source}: target")
    except ValueError as err:
        raise DatasetError(str(err)) from None
    cameras = spec["cameras"]
    sizes = {name: tuple(info["image_size"]) for name, info in cameras.items()}
    focal = {
        name: info["focal_length"] / info["pixel_pitch"]
        if "focal_length" in info and "pixel_pitch" in info
        else None
        for name, info in cameras.items()
    }
    images = {}
    pattern = spec["calibration_images"]
    for name, (width, height) in sizes.items():
        try:
            path = folder / pattern.format(camera=name)
        except (KeyError, IndexError, ValueError) as err:
            raise DatasetError(
                f"{source}: bad 'calibration_images' pattern {pattern!r} (use {{camera}}: {err})"
            ) from None
        if not path.is_file():
            raise FileNotFoundError(f"{path}: calibration image of camera {name!r} missing")
        image = read_image(path)
        if image.shape != (height, width):
            raise DatasetError(
                f"{path}: image of {image.shape[1]} × {image.shape[0]} px, but experiment.json "
                f"gives {width} × {height} px for camera {name!r}"
            )
        images[name] = path
    windows = {}
    for name, info in cameras.items():
        if "window" in info:
            try:
                windows[name] = FlatWindow.from_dict(
                    info["window"], source=f"{source}: cameras.{name}.window"
                )
            except ValueError as err:
                raise DatasetError(str(err)) from None
    seeds = read_point_seeds(folder / spec["calibration_seeds"], list(sizes), target)
    masks = camera_masks(folder, spec, {n: (h, w) for n, (w, h) in sizes.items()})
    return PointTargetSetup(folder, target, sizes, focal, images, masks, seeds, windows)


def read_point_seeds(
    path: Path, cameras: Sequence[str], target: PointTarget
) -> dict[str, dict[int, tuple[float, float]]]:
    """Seed points from a CSV file with the header ``camera,X,Y,Z,x,y``.

    Each row is one target point (X, Y, Z in the target file's units, as listed there)
    that a user located on the image of ``camera``, at pixel (x, y) (x = column,
    y = row). Every camera needs at least four, not all on one line.

    Returns
    -------
    dict of str to dict of int to (float, float)
        Per camera (all of ``cameras``), target row → pixel.

    Raises
    ------
    FileNotFoundError
        No such file.
    DatasetError
        A missing column; a row with an unknown camera, a value that is not a finite
        number, a point not in the target file, or a point given twice for one camera;
        a camera with fewer than four seeds (the message names the file and the row).
    """
    if not path.is_file():
        raise FileNotFoundError(f"seed point file {path} is missing")
    seeds: dict[str, dict[int, tuple[float, float]]] = {name: {} for name in cameras}
    scale = UNITS[target.units]
    with path.open(newline="") as f:
        reader = csv.DictReader(f)
        missing = [c for c in SEED_COLUMNS if c not in (reader.fieldnames or [])]
        if missing:
            raise DatasetError(
                f"{path}: missing column(s) {', '.join(missing)} (a point target's seed file "
                f"has the header {','.join(SEED_COLUMNS)})"
            )
        for row_number, row in enumerate(reader, start=2):
            where = f"{path}: row {row_number}"
            try:
                values = [float(row[c]) for c in SEED_COLUMNS[1:]]
            except (TypeError, ValueError):
                raise DatasetError(f"{where}: X, Y, Z, x, y must be numbers") from None
            if not np.isfinite(values).all():
                raise DatasetError(f"{where}: X, Y, Z, x, y must be finite")
            if row["camera"] not in seeds:
                raise DatasetError(
                    f"{where}: unknown camera {row['camera']!r} (experiment.json has "
                    f"{', '.join(cameras)})"
                )
            point = np.array(values[:3]) * scale
            target_row = target.row_of(point, SEED_MATCH_M)
            if target_row is None:
                raise DatasetError(
                    f"{where}: no point of {target.source} at X, Y, Z = "
                    f"{', '.join(row[c] for c in 'XYZ')} {target.units}"
                )
            if target_row in seeds[row["camera"]]:
                raise DatasetError(
                    f"{where}: point {', '.join(row[c] for c in 'XYZ')} is seeded twice "
                    f"for camera {row['camera']!r}"
                )
            seeds[row["camera"]][target_row] = (values[3], values[4])
    few = [name for name, points in seeds.items() if len(points) < MIN_SEEDS]
    if few:
        raise DatasetError(
            f"{path}: camera {few[0]!r} has {len(seeds[few[0]])} seed point(s); each camera "
            f"needs at least {MIN_SEEDS}"
        )
    return seeds


def calibrate_point_cameras(
    setup: PointTargetSetup, progress: Callable[[], None] | None = None
) -> dict[str, PointTargetFit]:
    """One pinhole per camera from its image of the point target (behind the camera's
    window when it has one).

    Parameters
    ----------
    setup : PointTargetSetup
        From :func:`point_target_setup`.
    progress : callable(), optional
        Called after each camera.

    Returns
    -------
    dict of str to PointTargetFit
        In experiment.json's camera order.

    Raises
    ------
    ValueError
        Errors of :func:`ptv.calibration.point_target.calibrate_point_target`, naming
        the image.
    """
    fits = {}
    for name, path in setup.images.items():
        image = masked_image(read_image(path), setup.masks.get(name))
        fits[name] = calibrate_point_target(
            image,
            setup.target,
            setup.seeds[name],
            focal_px=setup.focal_px[name],
            window=setup.windows.get(name),
            source=str(path),
        )
        if progress is not None:
            progress()
    return fits


def target_errors(target: PointTarget, fits: Mapping[str, PointTargetFit]) -> PositionErrors:
    """The target points triangulated back from the calibrated cameras.

    Every point that two or more cameras used is triangulated from the blob centres
    those cameras associated with it; Δ is taken against its listed position. In
    sample: the same points built the calibrations.

    Parameters
    ----------
    target : PointTarget
        The target.
    fits : mapping of str to PointTargetFit
        One fit per camera.

    Returns
    -------
    PositionErrors
        ``plane`` holds the number of cameras that saw each point.

    Raises
    ------
    ValueError
        No point was used by two cameras.
    """
    pixels = np.full((len(fits), len(target), 2), np.nan)
    for c, fit in enumerate(fits.values()):
        pixels[c, fit.rows] = fit.pixels
    seen = np.isfinite(pixels[:, :, 0]).sum(axis=0)
    rows = np.flatnonzero(seen >= 2)
    if len(rows) == 0:
        raise ValueError("no target point was used by two cameras")
    cameras = [fit.calibration for fit in fits.values()]
    points = triangulate(cameras, [p[rows] for p in pixels]).points
    truth = target.points[rows]
    return PositionErrors(truth, points - truth, seen[rows])
