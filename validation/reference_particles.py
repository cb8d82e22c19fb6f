"""3-D particles of another PTV code beside synptv's, on the same real images.

The real examples ship the particles their own software matched: MyPTV's
``particles`` file and OpenPTV's ``rt_is.<frame>`` files. They are that software's
output, not ground truth; what can be measured is agreement: the fraction of the shipped
particles that synptv has a particle near (within 0.1 mm by default) and the median
distance from a shipped particle to synptv's nearest, per recorded frame.

- :func:`read_myptv_particles`: MyPTV's matched particles (X, Y, Z in mm, one blob index
  per camera, the matching error in mm, the frame index, 0 for the recording's first
  image).
- :func:`read_rt_is`: an OpenPTV correspondence file (a count, then ``id X Y Z`` and a
  target index per camera, mm).
- :func:`synptv_frames`: the matched points of a ``synptv ptv`` run per recorded frame.
- :func:`agreement`: the two compared.
"""

from collections.abc import Mapping
from pathlib import Path

import h5py
import numpy as np
from scipy.spatial import cKDTree

from ptv.io.dataset import Dataset

__all__ = ["agreement", "read_myptv_particles", "read_rt_is", "synptv_frames"]

#: Millimetre, m.
MM = 1e-3
#: The agreement radius of the real-data comparisons, m.
RADIUS = 0.1 * MM


def read_myptv_particles(path: Path, first_frame: int = 1) -> dict[int, np.ndarray]:
    """MyPTV's matched particles, per recorded frame.

    Parameters
    ----------
    path : Path
        A MyPTV ``particles`` file: X Y Z (mm), one blob index per camera, the
        matching error (mm) and the frame index (0 for the first image), blank
        separated.
    first_frame : int
        The recorded frame number of frame index 0 (MyPTV's example: 1, for ``01.tif``).

    Returns
    -------
    dict of int to ndarray, shape (N, 3)
        Recorded frame number → particles, m.

    Raises
    ------
    ValueError
        Not a table of at least six columns (naming the file).
    """
    table = np.loadtxt(path, ndmin=2)
    if table.shape[1] < 6:
        raise ValueError(f"{path}: expected X Y Z, blob indices, error and frame per line")
    frames = table[:, -1].astype(int)
    return {int(f) + first_frame: table[frames == f, :3] * MM for f in np.unique(frames)}


def read_rt_is(path: Path) -> np.ndarray:
    """The particles of an OpenPTV correspondence file (``rt_is.<frame>``).

    Parameters
    ----------
    path : Path
        First line the count, then per particle ``id X Y Z`` (mm) and its target index
        in each camera (−1 for none).

    Returns
    -------
    ndarray, shape (N, 3)
        m.

    Raises
    ------
    ValueError
        The count does not match the lines (naming the file).
    """
    lines = Path(path).read_text().split("\n")
    count = int(lines[0])
    table = np.loadtxt(lines[1:], ndmin=2)
    if len(table) != count:
        raise ValueError(f"{path}: says {count} particles, holds {len(table)}")
    return table[:, 1:4] * MM


def synptv_frames(results: Path, dataset: Dataset) -> dict[int, np.ndarray]:
    """The matched points of a ``synptv ptv`` run on a time-resolved dataset, per
    recorded frame (a frame shared by several Δt once).

    Parameters
    ----------
    results : Path
        Its ``results.h5`` (``/positions``).
    dataset : Dataset
        The dataset it ran on (its ``sequence`` numbers the frames).

    Returns
    -------
    dict of int to ndarray, shape (N, 3)
        Recorded frame number → points, m, in the calibration's frame.
    """
    if dataset.sequence is None:
        raise ValueError(f"{dataset.folder}: not a time-resolved recording")
    with h5py.File(results, "r") as f:
        g = f["positions"]
        k, m, frame = g["dt"][:], g["snapshot"][:], g["frame"][:].astype(str)
        points = np.column_stack([g["x"][:], g["y"][:], g["z"][:]])
    keys = np.unique(np.column_stack([k, m, frame == "b"]), axis=0)
    out: dict[int, np.ndarray] = {}
    for kk, mm, b in keys:
        number = dataset.sequence.frame_number(int(kk), int(mm), "b" if b else "a")
        if number not in out:
            out[number] = points[(k == kk) & (m == mm) & ((frame == "b") == bool(b))]
    return out


def agreement(
    found: Mapping[int, np.ndarray],
    reference: Mapping[int, np.ndarray],
    radius: float = RADIUS,
) -> dict[int, dict]:
    """How many reference particles synptv found, per frame both have.

    Parameters
    ----------
    found, reference : mapping of int to ndarray, shape (N, 3)
        Frame → particles, m, in one frame of reference.
    radius : float
        Agreement radius, m.

    Returns
    -------
    dict of int to dict
        Per frame: ``reference`` and ``found`` (counts), ``within`` (the fraction of
        reference particles with a found one within ``radius``), ``median_mm`` (median
        distance from a reference particle to the nearest found one).
    """
    out = {}
    for number in sorted(set(found) & set(reference)):
        ref, ours = reference[number], found[number]
        distance = cKDTree(ours).query(ref)[0] if len(ours) else np.full(len(ref), np.inf)
        out[number] = {
            "reference": len(ref),
            "found": len(ours),
            "within": float(np.mean(distance <= radius)),
            "median_mm": float(np.median(distance) / MM),
        }
    return out
