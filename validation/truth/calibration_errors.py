"""Calibration accuracy against truth: the paper's Table 1 metric and the pure model error.

Table 1 metric (docs/calibration.md §7): every dot of every plane is triangulated from its image
positions in both cameras, and Δ = P − X is taken against the dot's expected position:
as in the paper, its nominal position (indices × pitch, Z_j) by default, or its true
centre (which adds the plate's tilt, bow, manufacturing and traverse errors, which no
calibration built on nominal positions can know);
d_X, d_Y, d_Z are the mean absolute components and d is the mean 3-D distance (the
paper's table uses the mean of |Δ|, not √(d_X² + d_Y² + d_Z²), docs/errata.md E6). It is in-sample:
the same dots built the calibration, so dot-centre noise dominates it when it is large.

Model error: random points inside the measurement volume are projected by the true
cameras without any detection noise and triangulated with the calibrations; it isolates
what the calibration model itself gets wrong.
"""

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ptv.calibration.model_free import PlaneObservation
from ptv.camera_model import CameraModel
from ptv.triangulate import triangulate
from simulator.optics import Camera
from simulator.particles import Box
from simulator.target import PhysicalPlate, PlateDesign


@dataclass(frozen=True)
class TraverseDots:
    """Dots one camera saw at one traverse position, identified by their grid indices
    (what a calibration is fitted on and Table 1 is measured with; unlike
    :class:`ptv.calibration.targets.PlaneDots`, it knows its traverse reading Z_j).

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
    """

    z: float
    indices: np.ndarray
    pixels: np.ndarray
    pitch: float

    def observation(self) -> PlaneObservation:
        """The correspondences a calibration is built from."""
        return PlaneObservation(self.z, self.pixels, self.indices * self.pitch)


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


def synthetic_plane_dots(
    cameras: Sequence[Camera],
    plate: PhysicalPlate,
    *,
    noise_px: float,
    rng: np.random.Generator | int | None = None,
) -> list[list[TraverseDots]]:
    """Dot observations without images: exact projections plus Gaussian centre noise.

    Parameters
    ----------
    cameras : sequence of Camera
        The true cameras.
    plate : PhysicalPlate
        The plate and its traverse.
    noise_px : float
        Standard deviation of the dot-centre noise per image axis, px.
    rng : numpy.random.Generator, int or None
        Noise source.

    Returns
    -------
    list (per camera) of list (per plane) of TraverseDots
        Dots whose centre projects onto the sensor.
    """
    rng = np.random.default_rng(rng)
    indices = plate.design.indices
    out = []
    for camera in cameras:
        planes = []
        for j, pose in enumerate(plate.poses):
            xy = camera.project(plate.dot_centres(j))
            seen = np.isfinite(xy).all(axis=1)
            noisy = xy[seen] + rng.normal(0.0, noise_px, (int(seen.sum()), 2))
            planes.append(TraverseDots(pose.z_nominal, indices[seen], noisy, plate.design.pitch))
        out.append(planes)
    return out


def nominal_positions(design: PlateDesign, z: Sequence[float]) -> np.ndarray:
    """Expected dot positions as the paper uses them: (indices × pitch, Z_j), (N_Z, D, 3)."""
    xy = design.nominal_xy
    return np.stack([np.column_stack([xy, np.full(len(xy), zj)]) for zj in z])


def true_positions(plate: PhysicalPlate) -> np.ndarray:
    """True dot centres (tilt, bow, manufacturing and traverse errors), (N_Z, D, 3)."""
    return np.stack([plate.dot_centres(j) for j in range(len(plate.poses))])


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


def model_errors(
    calibrations: Sequence[CameraModel],
    cameras: Sequence[Camera],
    volume: Box,
    *,
    points: int = 2000,
    rng: np.random.Generator | int | None = None,
) -> PositionErrors:
    """Pure model error at random points of ``volume`` seen by every true camera.

    Parameters
    ----------
    calibrations : sequence of CameraModel
        The calibrations under test.
    cameras : sequence of Camera
        The true cameras, in the same order.
    volume : Box
        Where the points are drawn, m.
    points : int
        Number of points drawn.
    rng : numpy.random.Generator, int or None
        Point positions.

    Returns
    -------
    PositionErrors
    """
    truth = volume.sample(points, np.random.default_rng(rng))
    pixels = [camera.project(truth) for camera in cameras]
    seen = np.all([np.isfinite(p).all(axis=1) for p in pixels], axis=0)
    tri = triangulate(calibrations, [p[seen] for p in pixels])
    return PositionErrors(truth[seen], tri.points - truth[seen], np.full(int(seen.sum()), -1))
