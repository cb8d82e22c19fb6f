"""The calibration's Table 1 metric: dots triangulated against where they should be.

Every dot of every plate position is triangulated from its image positions in all
cameras and Δ = P − X is taken against the dot's expected position: as in the paper,
its nominal position (grid indices × pitch, traverse reading Z_j), or, in a rendered
experiment, its true centre (``validation.truth``). d_X, d_Y, d_Z are the mean absolute
components and d is the mean 3-D distance (docs/calibration.md §7). It is in-sample:
the same dots built the calibration.
"""

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ptv.calibration.model_free import PlaneObservation
from ptv.camera_model import CameraModel
from ptv.triangulate import triangulate


@dataclass(frozen=True)
class TraverseDots:
    """Dots one camera saw at one traverse position, identified by their grid indices
    (what a calibration is fitted on and Table 1 is measured with; unlike
    :class:`ptv.calibration.plate.PlaneDots`, it knows its traverse reading Z_j).

    Attributes
    ----------
    z : float
        Traverse reading Z_j, m.
    indices : ndarray of int, shape (N, 2)
        Grid indices (i, j) of the dots.
    pixels : ndarray, shape (N, 2)
        Their image positions, px.
    pitch : float
        Grid pitch, m (world X, Y = indices × pitch).
    offsets : ndarray, shape (N, 2), optional
        The dots' offsets from the nominal grid, m, when the plate was self-calibrated
        (:mod:`ptv.calibration.plate_offsets`); world X, Y = indices × pitch + offsets.
    """

    z: float
    indices: np.ndarray
    pixels: np.ndarray
    pitch: float
    offsets: np.ndarray | None = None

    def observation(self) -> PlaneObservation:
        """The correspondences a calibration is built from."""
        xy = self.indices * self.pitch
        if self.offsets is not None:
            xy = xy + self.offsets
        return PlaneObservation(self.z, self.pixels, xy)


@dataclass(frozen=True)
class PositionErrors:
    """Errors Δ = estimate − truth of triangulated points.

    Attributes
    ----------
    truth : ndarray, shape (N, 3)
        True positions, m.
    delta : ndarray, shape (N, 3)
        Errors, m (NaN rows where the points could not be triangulated).
    plane : ndarray of int, shape (N,)
        Plane index of each point (−1 for random points).
    """

    truth: np.ndarray
    delta: np.ndarray
    plane: np.ndarray

    @property
    def components(self) -> np.ndarray:
        """d_X, d_Y, d_Z: mean absolute error per component, shape (3,), m."""
        return np.nanmean(np.abs(self.delta), axis=0)

    @property
    def d(self) -> float:
        """Mean 3-D distance, m (the paper's d)."""
        return float(np.nanmean(np.linalg.norm(self.delta, axis=1)))

    @property
    def coverage(self) -> float:
        """Fraction of points that could be triangulated."""
        return float(np.mean(np.isfinite(self.delta).all(axis=1)))

    def summary(self) -> dict[str, float]:
        """d_X, d_Y, d_Z, d (µm) and the coverage, for tables and JSON."""
        dx, dy, dz = self.components * 1e6
        return {
            "d_X_um": dx,
            "d_Y_um": dy,
            "d_Z_um": dz,
            "d_um": self.d * 1e6,
            "coverage": self.coverage,
        }


def nominal_positions(indices: np.ndarray, pitch: float, z: Sequence[float]) -> np.ndarray:
    """Expected dot positions as the paper uses them: (indices × pitch, Z_j).

    Parameters
    ----------
    indices : ndarray of int, shape (D, 2)
        Grid indices (i, j) of the plate's dots.
    pitch : float
        Grid pitch, m.
    z : sequence of float, length N_Z
        Traverse readings, m.

    Returns
    -------
    ndarray, shape (N_Z, D, 3)
        m.
    """
    xy = np.asarray(indices) * pitch
    return np.stack([np.column_stack([xy, np.full(len(xy), zj)]) for zj in z])


def table1_errors(
    calibrations: Sequence[CameraModel],
    dots: Sequence[Sequence[TraverseDots]],
    indices: np.ndarray,
    expected: np.ndarray,
    *,
    planes: Sequence[int] | None = None,
) -> PositionErrors:
    """The paper's Table 1 metric: each dot triangulated from all cameras vs its position.

    Parameters
    ----------
    calibrations : sequence of C CameraModel
        One calibration per camera.
    dots : sequence (per camera) of sequence (per plane) of TraverseDots
        Identified dots; a dot enters when every camera saw it.
    indices : ndarray of int, shape (D, 2)
        Grid indices of the plate's dots (the rows of ``expected``).
    expected : ndarray, shape (N_Z, D, 3)
        Where each dot should be: :func:`nominal_positions` (the paper's metric) or
        :func:`true_positions`, m.
    planes : sequence of int, optional
        Planes to evaluate (all by default).

    Returns
    -------
    PositionErrors
    """
    if len(calibrations) != len(dots) or len(dots) < 2:
        raise ValueError("need one calibration and one set of dots per camera, two or more")
    row_of = {tuple(ij): k for k, ij in enumerate(np.asarray(indices))}
    truth, delta, plane_of = [], [], []
    for j in planes if planes is not None else range(len(expected)):
        per_camera = [
            {tuple(ij): xy for ij, xy in zip(cam[j].indices, cam[j].pixels, strict=True)}
            for cam in dots
        ]
        common = sorted(set.intersection(*(set(p) for p in per_camera)))
        if not common:
            continue
        pixels = [np.array([p[key] for key in common]) for p in per_camera]
        centres = expected[j][[row_of[key] for key in common]]
        points = triangulate(calibrations, pixels).points
        truth.append(centres)
        delta.append(points - centres)
        plane_of.append(np.full(len(common), j))
    if not truth:
        raise ValueError("no dot was seen by every camera")
    return PositionErrors(np.concatenate(truth), np.concatenate(delta), np.concatenate(plane_of))
