"""Dot lists instead of plate images: dots another program found and indexed.

experiment.json's ``calibration_dots`` names one list per camera and traverse position
(docs/experiment.md §3) in one of two layouts; either gives, per dot, its grid index
(i, j), plate coordinates (X, Y) = pitch·(i, j), and its pixel (x, y) in synptv's
convention (x = column, y = row, (0, 0) the centre of the top-left pixel):

- ``csv``: a CSV file with the header ``i,j,x,y`` (other columns are ignored), one row
  per dot (:func:`read_csv_dots`);
- ``openptv``: OpenPTV's sorted target pair, a ``.crd`` file of lines ``number x y``
  (px) and a ``.fix`` file of lines ``number X Y Z`` (mm), paired by point number
  (:func:`read_openptv_dots`). OpenPTV puts (0, 0) at the top-left pixel's corner
  (its centroids add half a pixel), so half a pixel is taken off x and y.

Every list is checked line by line and refused, in one line naming the file and the
line, for a malformed line, a repeated dot, a pixel off the image, a plate point off the
plate's grid or extent, a Z other than the traverse reading, or too few dots.
"""

import csv
from pathlib import Path

import numpy as np

from ptv.calibration.blobs import MIN_BLOBS
from ptv.calibration.plate import PlateDescription
from ptv.camera_model import on_image
from ptv.errors import DatasetError

__all__ = ["CSV_COLUMNS", "DotListError", "read_csv_dots", "read_openptv_dots"]

#: Columns a CSV dot list must have.
CSV_COLUMNS = ("i", "j", "x", "y")
#: OpenPTV's pixel origin (the top-left pixel's corner) in synptv's pixel coordinates, px.
OPENPTV_PIXEL_ORIGIN = -0.5
#: The coordinate OpenPTV writes for a point it did not find, px.
NOT_FOUND = -999.0
#: How far a .fix point may lie from its grid node, in pitches (the files round to 10 nm).
GRID_TOLERANCE = 0.01
#: How far a .fix point's Z may differ from the traverse reading, m.
Z_TOLERANCE = 1e-6


class DotListError(DatasetError):
    """A dot list that cannot be used (the message names the file and the line)."""


def _number(text: str, path: Path, line: int, what: str) -> float:
    """``text`` as a finite number, or a DotListError naming the file, line and field."""
    try:
        value = float(text)
    except ValueError:
        value = np.nan
    if not np.isfinite(value):
        raise DotListError(f"{path}: line {line}: {what} must be a finite number, got {text!r}")
    return value


def _integer(text: str, path: Path, line: int, what: str) -> int:
    """``text`` as an integer (``12`` or ``12.0``), or a DotListError."""
    value = _number(text, path, line, what)
    if value != round(value):
        raise DotListError(f"{path}: line {line}: {what} must be an integer, got {text!r}")
    return int(value)


def _checked_dots(
    path: Path,
    dots: list[tuple[int, tuple[int, int], float, float]],
    plate: PlateDescription,
    image_size: tuple[int, int],
) -> tuple[np.ndarray, np.ndarray]:
    """The dots ``(line, (i, j), x, y)`` of one list as arrays, each on the image and the
    plate, none twice, enough of them.

    Returns
    -------
    indices : ndarray of int, shape (N, 2)
        Grid indices (i, j).
    pixels : ndarray, shape (N, 2)
        Pixels (x, y), px, synptv's convention.
    """
    width, height = image_size
    seen: dict[tuple[int, int], int] = {}
    for line, node, x, y in dots:
        if node in seen:
            raise DotListError(
                f"{path}: line {line}: grid node {node} listed twice (first on line {seen[node]})"
            )
        seen[node] = line
        if not plate.in_extent(np.array(node))[0]:
            raise DotListError(
                f"{path}: line {line}: grid node {node} lies outside the target's extent "
                f"{plate.extent}"
            )
        if not on_image(np.array([[x, y]]), image_size)[0]:
            raise DotListError(
                f"{path}: line {line}: pixel ({x:g}, {y:g}) lies off the {width} × {height} "
                "px image"
            )
    if len(dots) < MIN_BLOBS:
        raise DotListError(
            f"{path}: {len(dots)} dot(s), a plate position needs at least {MIN_BLOBS}"
        )
    indices = np.array([node for _, node, _, _ in dots], dtype=np.int64).reshape(-1, 2)
    pixels = np.array([(x, y) for _, _, x, y in dots], dtype=float).reshape(-1, 2)
    return indices, pixels


def read_csv_dots(
    path: str | Path, plate: PlateDescription, image_size: tuple[int, int]
) -> tuple[np.ndarray, np.ndarray]:
    """One plate position's dots from a CSV file with the header ``i,j,x,y``.

    Parameters
    ----------
    path : str or Path
        The file: a header naming at least the columns i, j (grid indices, integers) and
        x, y (pixel, px; (0, 0) the centre of the top-left pixel), then one row per dot.
    plate : PlateDescription
        The plate (its extent bounds the indices).
    image_size : (int, int)
        (width, height) of the camera's images, px.

    Returns
    -------
    indices : ndarray of int, shape (N, 2)
        Grid indices (i, j), in the file's order.
    pixels : ndarray, shape (N, 2)
        Pixels (x, y), px.

    Raises
    ------
    FileNotFoundError
        No such file.
    DotListError
        A missing column, a malformed row (naming its line), a repeated grid node, a
        node off the plate's extent, a pixel off the image, or fewer than
        :data:`~ptv.calibration.blobs.MIN_BLOBS` dots.

    Examples
    --------
    A list of 4 × 4 dots 20 px apart, read, then made the observation a calibration
    takes (plate coordinates (X, Y) = pitch·(i, j)):

    >>> import pathlib, tempfile
    >>> import ptv
    >>> tmp = tempfile.TemporaryDirectory()
    >>> path = pathlib.Path(tmp.name) / "cam1_z0.csv"
    >>> rows = [f"{i},{j},{100 + 20 * i},{80 + 20 * j}" for i in range(4) for j in range(4)]
    >>> _ = path.write_text("\\n".join(["i,j,x,y", *rows]))
    >>> plate = ptv.PlateDescription(pitch=5e-3, dot_diameter=1e-3)
    >>> indices, pixels = ptv.read_csv_dots(path, plate, (640, 480))
    >>> indices[5], pixels[5]
    (array([1, 1]), array([120., 100.]))
    >>> plane = ptv.PlaneObservation(z=0.0, pixels=pixels, world_xy=indices * plate.pitch)
    >>> plane.world_xy[5]
    array([0.005, 0.005])
    >>> tmp.cleanup()
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: dot list missing")
    with path.open(newline="") as f:
        reader = csv.DictReader(f)
        missing = [c for c in CSV_COLUMNS if c not in (reader.fieldnames or [])]
        if missing:
            raise DotListError(
                f"{path}: missing column(s) {', '.join(missing)} (the header is i,j,x,y)"
            )
        dots = []
        for row in reader:
            line = reader.line_num
            if any(row[c] is None for c in CSV_COLUMNS):
                raise DotListError(f"{path}: line {line}: fewer fields than the header")
            node = (_integer(row["i"], path, line, "i"), _integer(row["j"], path, line, "j"))
            x, y = (_number(row[c], path, line, c) for c in ("x", "y"))
            dots.append((line, node, x, y))
    return _checked_dots(path, dots, plate, image_size)


def _openptv_lines(path: Path, fields: int, names: str) -> dict[int, tuple[int, list[float]]]:
    """The lines of a .crd or .fix file by point number: number → (line, other values).

    Raises
    ------
    FileNotFoundError
        No such file.
    DotListError
        A line without ``fields`` numbers, or a point number listed twice.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: dot list missing")
    points: dict[int, tuple[int, list[float]]] = {}
    for line, text in enumerate(path.read_text().splitlines(), start=1):
        parts = text.split()
        if not parts:
            continue
        if len(parts) != fields:
            raise DotListError(
                f"{path}: line {line}: expected {fields} numbers ({names}), got {text.strip()!r}"
            )
        number = _integer(parts[0], path, line, "the point number")
        if number in points:
            raise DotListError(
                f"{path}: line {line}: point number {number} listed twice (first on line "
                f"{points[number][0]})"
            )
        values = [
            _number(p, path, line, name)
            for p, name in zip(parts[1:], names.split()[1:], strict=True)
        ]
        points[number] = (line, values)
    return points


def read_openptv_dots(
    crd: str | Path, fix: str | Path, plate: PlateDescription, z: float, image_size: tuple[int, int]
) -> tuple[np.ndarray, np.ndarray]:
    """One plate position's dots from OpenPTV's sorted targets (``.crd``) and the plate
    points they are sorted on (``.fix``).

    Parameters
    ----------
    crd : str or Path
        Lines ``number x y``: the dots found on the image, px, OpenPTV's pixel origin
        (the top-left pixel's corner). A line with a negative number or with x, y at
        −999 (OpenPTV's mark of a point it did not find) is skipped.
    fix : str or Path
        Lines ``number X Y Z``: the plate points, mm, on the plate's grid
        (X, Y) = pitch·(i, j), Z the traverse reading.
    plate : PlateDescription
        The plate (its pitch gives the indices, its extent bounds them).
    z : float
        The traverse reading of this position, m.
    image_size : (int, int)
        (width, height) of the camera's images, px.

    Returns
    -------
    indices : ndarray of int, shape (N, 2)
        Grid indices (i, j), in the .crd file's order.
    pixels : ndarray, shape (N, 2)
        Pixels (x, y), px, synptv's convention.

    Raises
    ------
    FileNotFoundError
        Either file missing.
    DotListError
        A malformed line or a repeated point number in either file, a .crd point number
        the .fix file lacks, a .fix point off the grid or at another Z, a pixel off the
        image, or too few dots (each message names the file and the line).

    Examples
    --------
    OpenPTV's files of 4 × 4 dots 5 mm apart at Z = 2 mm; the .crd pixels are taken half a
    pixel down to synptv's origin:

    >>> import pathlib, tempfile
    >>> import ptv
    >>> tmp = tempfile.TemporaryDirectory()
    >>> crd, fix = pathlib.Path(tmp.name) / "cam1.crd", pathlib.Path(tmp.name) / "plate.fix"
    >>> nodes = [(i, j) for i in range(4) for j in range(4)]
    >>> lines = [f"{n} {100.5 + 20 * i} {80.5 + 20 * j}" for n, (i, j) in enumerate(nodes)]
    >>> _ = crd.write_text("\\n".join(lines))
    >>> lines = [f"{n} {5.0 * i} {5.0 * j} 2.0" for n, (i, j) in enumerate(nodes)]
    >>> _ = fix.write_text("\\n".join(lines))
    >>> plate = ptv.PlateDescription(pitch=5e-3, dot_diameter=1e-3)
    >>> indices, pixels = ptv.read_openptv_dots(crd, fix, plate, 2e-3, (640, 480))
    >>> indices[5], pixels[5]
    (array([1, 1]), array([120., 100.]))
    >>> tmp.cleanup()
    """
    points = _openptv_lines(fix, 4, "number X Y Z")
    found = _openptv_lines(crd, 3, "number x y")
    dots = []
    for number, (line, (x, y)) in found.items():
        if number < 0 or x == NOT_FOUND or y == NOT_FOUND:
            continue
        if number not in points:
            raise DotListError(f"{crd}: line {line}: point number {number} is not in {fix}")
        fix_line, (big_x, big_y, big_z) = points[number]
        ij = np.array([big_x, big_y]) * 1e-3 / plate.pitch
        if np.abs(ij - np.round(ij)).max() > GRID_TOLERANCE:
            raise DotListError(
                f"{fix}: line {fix_line}: point ({big_x:g}, {big_y:g}) mm is not on the "
                f"target's {plate.pitch * 1e3:g} mm grid"
            )
        if abs(big_z * 1e-3 - z) > Z_TOLERANCE:
            raise DotListError(
                f"{fix}: line {fix_line}: Z = {big_z:g} mm, but traverse_z gives "
                f"{z * 1e3:g} mm for this plate position"
            )
        node = (round(ij[0]), round(ij[1]))
        dots.append((line, node, x + OPENPTV_PIXEL_ORIGIN, y + OPENPTV_PIXEL_ORIGIN))
    return _checked_dots(crd, dots, plate, image_size)
