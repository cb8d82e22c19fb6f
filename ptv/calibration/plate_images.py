"""Calibrate the cameras of a dataset folder from its plate images: no truth needed.

What a real experiment provides is enough: experiment.json (checked against its schema
up front, :mod:`ptv.io.experiment_file`) with the plate (``target``), the traverse readings
(``traverse_z``), the plate images' pattern (``calibration_images``) and each camera's
pixel pitch and focal length, optionally a mask per camera and seed dots (a CSV file,
``calibration_seeds``, :func:`read_seed_dots`) for plates without marks. Instead of
images, ``calibration_dots`` may name lists of dots another program found and indexed
(:mod:`ptv.calibration.dot_lists`). :func:`plate_setup` reads and checks all of it, and
every plate image (present, readable, of the declared size, no two alike) or dot list,
before any dot is searched; :func:`find_traverse_dots` finds and indexes the dots (or
hands over the listed ones); :func:`calibrate_cameras` fits one calibration per camera;
Table 1 against the nominal grid is :func:`ptv.calibration.grid_errors.table1_errors`
with :func:`nominal_grid`.
"""

import csv
import hashlib
import itertools
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ptv.calibration.dot_lists import read_csv_dots, read_openptv_dots
from ptv.calibration.grid_errors import TraverseDots, nominal_positions
from ptv.calibration.methods import CameraSheet, calibrate
from ptv.calibration.plate import PlateDescription
from ptv.calibration.targets import find_dots
from ptv.camera_model import CameraModel
from ptv.io.dataset import DatasetError, camera_masks
from ptv.io.experiment_file import read_experiment
from ptv.io.images import read_image

__all__ = [
    "PlateSetup",
    "calibrate_cameras",
    "find_traverse_dots",
    "nominal_grid",
    "plate_setup",
    "read_seed_dots",
]

#: RMS image shift of the dots between two traverse positions below which the plate is
#: taken not to have moved, px: a few times the scatter of a dot centre found twice on
#: independent noise (~0.02 px), far below the shift of a 1 mm step seen at any angle.
STUCK_TRAVERSE_SHIFT_PX = 0.1


@dataclass(frozen=True, eq=False)
class PlateSetup:
    """A dataset's calibration plate, traverse, cameras and plate images, all checked.

    Attributes
    ----------
    folder : Path
        The dataset folder.
    plate : PlateDescription
        The nominal plate.
    z : list of float
        Traverse reading of each plate position, m.
    sheets : dict of str to CameraSheet
        Each camera's image size, pixel pitch and focal length, in experiment.json's order.
    images : dict of str to list of Path
        Each camera's plate image per traverse position (empty with dot lists).
    masks : dict of str to ndarray of bool, shape (H, W)
        The masks of the cameras that have one (True where the image is used).
    seeds : dict of (str, int) to dict of (int, int) to (float, float)
        Seed dots of (camera, plate position): grid index → pixel (empty: the marks).
    listed : dict of str to list of TraverseDots
        The dots of ``calibration_dots``' lists, per camera and traverse position
        (empty with plate images).
    threshold : {"global", "local"}
        How the dot threshold is set on the plate images (``target.threshold``,
        :func:`ptv.calibration.targets.find_dots`).
    """

    folder: Path
    plate: PlateDescription
    z: list[float]
    sheets: dict[str, CameraSheet]
    images: dict[str, list[Path]]
    masks: Mapping[str, np.ndarray]
    seeds: Mapping[tuple[str, int], dict] = field(default_factory=dict)
    listed: Mapping[str, list[TraverseDots]] = field(default_factory=dict)
    threshold: str = "global"

    @property
    def cameras(self) -> list[str]:
        """Camera names, in experiment.json's order."""
        return list(self.sheets)


def plate_setup(folder: str | Path) -> PlateSetup:
    """Read and check everything calibrating ``folder`` needs, before any dot search.

    Raises
    ------
    FileNotFoundError
        No experiment.json, or a plate image or dot list missing.
    ptv.io.experiment_file.DescriptionError
        experiment.json breaks its schema or lacks a field calibrating needs (all the
        problems in one line).
    DatasetError
        A bad plate description, a bad ``calibration_images`` or ``calibration_dots``
        pattern, a plate image of the wrong size, two plate images alike or two dot
        lists at the same pixels (a stuck traverse), or a bad dot list
        (:class:`ptv.calibration.dot_lists.DotListError`).
    ptv.io.images.ImageError
        A plate image or a mask that cannot be read, or a mask of the wrong size.
    """
    folder = Path(folder)
    spec = read_experiment(folder, needs=("calibration",))
    source = folder / "experiment.json"
    try:
        plate = PlateDescription.from_dict(spec["target"], source=f"{source}: target")
    except ValueError as err:
        raise DatasetError(str(err)) from None
    sheets = {
        name: CameraSheet(tuple(info["image_size"]), info["pixel_pitch"], info["focal_length"])
        for name, info in spec["cameras"].items()
    }
    z = [float(v) for v in spec["traverse_z"]]
    if "calibration_dots" in spec:
        listed = _listed_dots(folder, spec["calibration_dots"], plate, sheets, z)
        return PlateSetup(folder, plate, z, sheets, {}, {}, listed=listed)
    images = {
        name: _file_paths(folder, spec["calibration_images"], "calibration_images", name, len(z))
        for name in sheets
    }
    shapes = {name: (sheet.image_size[1], sheet.image_size[0]) for name, sheet in sheets.items()}
    for name, paths in images.items():
        _check_plate_images(paths, shapes[name])
    seeds = {}
    if "calibration_seeds" in spec:
        seeds = read_seed_dots(folder / spec["calibration_seeds"], list(sheets), len(z))
    elif not plate.marks:
        raise DatasetError(
            f"{source}: the target has no marks and there is no 'calibration_seeds' file: "
            "the dots cannot be indexed"
        )
    masks = camera_masks(folder, spec, shapes)
    threshold = spec["target"].get("threshold", "global")
    return PlateSetup(folder, plate, z, sheets, images, masks, seeds, threshold=threshold)


#: Columns of a seed-dot file.
SEED_COLUMNS = ("camera", "plane", "i", "j", "x", "y")


def read_seed_dots(
    path: Path, cameras: Sequence[str], planes: int
) -> dict[tuple[str, int], dict[tuple[int, int], tuple[float, float]]]:
    """Seed dots from a CSV file with the header ``camera,plane,i,j,x,y``.

    Each row is one dot a user located on plate image ``plane`` (0-based traverse
    position) of ``camera``: its grid indices (i, j) and its approximate pixel (x, y).
    Images without rows are indexed from the plate's marks.

    Raises
    ------
    FileNotFoundError
        No such file.
    DatasetError
        A missing column, or a row with an unknown camera, a plane out of range, or a
        value that is not a number (the message names the file and the row).
    """
    if not path.is_file():
        raise FileNotFoundError(f"seed dot file {path} is missing")
    with path.open(newline="") as f:
        reader = csv.DictReader(f)
        missing = [c for c in SEED_COLUMNS if c not in (reader.fieldnames or [])]
        if missing:
            raise DatasetError(f"{path}: missing column(s) {', '.join(missing)}")
        seeds: dict = {}
        for row_number, row in enumerate(reader, start=2):
            try:
                plane, i, j = int(row["plane"]), int(row["i"]), int(row["j"])
                x, y = float(row["x"]), float(row["y"])
            except (TypeError, ValueError):
                raise DatasetError(
                    f"{path}: row {row_number}: plane, i, j, x, y must be numbers"
                ) from None
            if row["camera"] not in cameras:
                raise DatasetError(
                    f"{path}: row {row_number}: unknown camera {row['camera']!r} "
                    f"(experiment.json has {', '.join(cameras)})"
                )
            if not (0 <= plane < planes and np.isfinite([x, y]).all()):
                raise DatasetError(
                    f"{path}: row {row_number}: plane {plane} out of 0 … {planes - 1} or "
                    "pixel not finite"
                )
            seeds.setdefault((row["camera"], plane), {})[i, j] = (x, y)
    return seeds


def _file_paths(
    folder: Path,
    pattern: str | Sequence[str],
    field: str,
    camera: str,
    planes: int,
    first_j: int = 0,
) -> list[Path]:
    """The files of ``camera`` experiment.json's ``field`` names, one per traverse
    position, each present: by one ``pattern`` ({j} from ``first_j``), or by a list of
    patterns with {camera} only, one per position (checked to be as long as the traverse
    by :func:`ptv.io.experiment_file.description_problems`)."""
    try:
        if isinstance(pattern, str):
            names = [pattern.format(camera=camera, j=first_j + j) for j in range(planes)]
        else:
            names = [entry.format(camera=camera) for entry in pattern]
    except (KeyError, IndexError, ValueError) as err:
        use = "{camera} and {j}" if isinstance(pattern, str) else "{camera} only in each entry"
        raise DatasetError(
            f"{folder / 'experiment.json'}: bad '{field}' pattern {pattern!r} (use {use}: {err})"
        ) from None
    paths = [folder / name for name in names]
    missing = [path for path in paths if not path.is_file()]
    if missing:
        what = "plate image" if field == "calibration_images" else "dot list"
        raise FileNotFoundError(f"{missing[0]}: {what} missing ({len(missing)} of {planes})")
    return paths


def _listed_dots(
    folder: Path,
    dots: Mapping,
    plate: PlateDescription,
    sheets: Mapping[str, CameraSheet],
    z: Sequence[float],
) -> dict[str, list[TraverseDots]]:
    """The dots of experiment.json's ``calibration_dots`` lists, per camera and traverse
    position, every list checked (:mod:`ptv.calibration.dot_lists`)."""
    first_j = dots.get("first_j", 0)
    listed = {}
    for name, sheet in sheets.items():
        if dots["format"] == "csv":
            paths = _file_paths(
                folder, dots["files"], "calibration_dots.files", name, len(z), first_j
            )
            read = [read_csv_dots(path, plate, sheet.image_size) for path in paths]
        else:
            paths = _file_paths(folder, dots["crd"], "calibration_dots.crd", name, len(z), first_j)
            fixes = _file_paths(folder, dots["fix"], "calibration_dots.fix", name, len(z), first_j)
            read = [
                read_openptv_dots(crd, fix, plate, zj, sheet.image_size)
                for crd, fix, zj in zip(paths, fixes, z, strict=True)
            ]
        planes = [
            TraverseDots(zj, indices, pixels, plate.pitch)
            for zj, (indices, pixels) in zip(z, read, strict=True)
        ]
        _check_traverse_moved(planes, paths)
        listed[name] = planes
    return listed


def _check_plate_images(paths: list[Path], shape: tuple[int, int]) -> None:
    """One camera's plate images: readable, of ``shape`` (rows, columns), no two alike."""
    first_seen = {}
    for path in paths:
        image = read_image(path)
        if image.shape != shape:
            raise DatasetError(
                f"{path}: image of {image.shape[1]} × {image.shape[0]} px, but experiment.json "
                f"gives {shape[1]} × {shape[0]} px for this camera"
            )
        digest = hashlib.sha256(image.tobytes()).hexdigest()
        if digest in first_seen:
            raise DatasetError(
                f"{path}: the same image as {first_seen[digest].name} (a stuck traverse?)"
            )
        first_seen[digest] = path


def masked_image(image: np.ndarray, mask: np.ndarray | None) -> np.ndarray:
    """``image`` with the pixels ``mask`` leaves out set to the median of the others."""
    if mask is None:
        return image
    out = image.copy()
    out[~mask] = np.median(image[mask]).astype(image.dtype)
    return out


def find_traverse_dots(
    setup: PlateSetup, progress: Callable[[], None] | None = None
) -> dict[str, list[TraverseDots]]:
    """The dots found and indexed on every plate image, per camera and traverse position.

    Parameters
    ----------
    setup : PlateSetup
        From :func:`plate_setup`.
    progress : callable(), optional
        Called after each image.

    Returns
    -------
    dict of str to list of TraverseDots
        Per camera (experiment.json's order), one entry per traverse position; with dot
        lists, the listed dots (``setup.listed``; ``progress`` is called once per list).

    Raises
    ------
    ptv.calibration.targets.NoTargetError
        The plate's marks or grid not found on an image (the message names it).
    ptv.calibration.targets.SeedDotsError
        Seed dots that no dot answers or that contradict each other.
    DatasetError
        Two traverse positions whose dots sit at the same pixels (a stuck traverse).
    """
    if setup.listed:
        if progress is not None:
            for _ in itertools.chain.from_iterable(setup.listed.values()):
                progress()
        return dict(setup.listed)
    found = {}
    for name, paths in setup.images.items():
        planes = []
        for j, (z, path) in enumerate(zip(setup.z, paths, strict=True)):
            image = masked_image(read_image(path), setup.masks.get(name))
            seeds = setup.seeds.get((name, j))
            dots = find_dots(
                image, setup.plate, source=str(path), seeds=seeds, threshold=setup.threshold
            )
            planes.append(TraverseDots(z, dots.indices, dots.pixels, setup.plate.pitch))
            if progress is not None:
                progress()
        _check_traverse_moved(planes, paths)
        found[name] = planes
    return found


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


class CameraCalibrationError(ValueError):
    """A calibration method that cannot fit one camera.

    Attributes
    ----------
    camera, method, reason : str
    """

    def __init__(self, camera: str, method: str, reason: str) -> None:
        super().__init__(f"{method} cannot calibrate camera {camera}: {reason}")
        self.camera, self.method, self.reason = camera, method, reason


def calibrate_cameras(
    setup: PlateSetup,
    dots: Mapping[str, Sequence[TraverseDots]],
    method: str,
    *,
    fit_planes: Sequence[int] | None = None,
) -> dict[str, CameraModel]:
    """One calibration per camera by ``method`` (``ptv.calibration.methods``).

    Parameters
    ----------
    setup : PlateSetup
        The cameras' sheets.
    dots : dict of str to sequence of TraverseDots
        From :func:`find_traverse_dots`.
    method : str
        A calibration method.
    fit_planes : sequence of int, optional
        Traverse positions fitted on (default: all).

    Returns
    -------
    dict of str to CameraModel
        In experiment.json's camera order.

    Raises
    ------
    CameraCalibrationError
        A camera the method cannot fit, named, with the method's reason; or one whose
        fitted model has no ray at any of the dots it was fitted on (a fit that
        diverged, as the OpenCV pinhole did on a strongly distorted oblique rig: every
        dot would then be left out of Table 1, silently).
    """
    calibrations = {}
    for name, sheet in setup.sheets.items():
        planes = dots[name] if fit_planes is None else [dots[name][j] for j in fit_planes]
        observations = [d.observation() for d in planes]
        try:
            model = calibrate(method, observations, sheet)
        except ValueError as err:
            raise CameraCalibrationError(name, method, str(err)) from err
        pixels = np.concatenate([o.pixels for o in observations])
        if len(pixels) and not np.isfinite(model.pixel_to_ray(pixels).directions).all(1).any():
            raise CameraCalibrationError(
                name,
                method,
                f"the fitted model has no ray at any of the {len(pixels)} dots it was "
                "fitted on (the fit diverged)",
            )
        calibrations[name] = model
    return calibrations


def nominal_grid(setup: PlateSetup, dots: Mapping[str, Sequence[TraverseDots]]):
    """The plate's grid indices and their nominal positions.

    Returns
    -------
    indices : ndarray of int, shape (D, 2)
        Every node of the plate's extent (i fastest), or, with no extent given, every
        node some camera found.
    positions : ndarray, shape (N_Z, D, 3)
        (indices × pitch, Z_j), m.
    """
    extent = setup.plate.extent
    if extent is None:
        found = np.concatenate([d.indices for planes in dots.values() for d in planes])
        indices = np.unique(found, axis=0)
    else:
        (i0, i1), (j0, j1) = extent
        ii, jj = np.meshgrid(np.arange(i0, i1 + 1), np.arange(j0, j1 + 1), indexing="xy")
        indices = np.column_stack([ii.ravel(), jj.ravel()])
    return indices, nominal_positions(indices, setup.plate.pitch, setup.z)
