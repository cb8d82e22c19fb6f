"""The stereo matching tolerance, measured on the calibration and the particles it matches.

A match accepts a set of rays that all pass within the tolerance of their least-squares
point (:mod:`ptv.matching.stereo`). Two things spread the rays of one particle apart: the
calibration's triangulation error (the cameras' rays of one point do not quite meet) and
the detection error of the particle images mapped into the volume. A fixed tolerance in
metres suits one rig only: a poor calibration then loses most of its matches (a Tsai fit
of 3.6 px RMS on a Scheimpflug rig kept 1445 of 7600 matches at 150 µm), and a rig ten
times larger or smaller is cut or flooded. So, unless the user sets it, the tolerance is

    tolerance = max(PIXEL_FLOOR · p, SPREAD_PER_MEDIAN · median ray distance)

measured on frame a of the first snapshots:

- p is the pixel footprint: the distance, at the centre of the matching volume, between
  the rays through two neighbouring pixels, the largest over the cameras. Below about
  half a pixel the tolerance cuts real particles (those whose images overlap another's
  are off by tenths of a pixel): on the paper's 2-camera rig the matches of 5 frames
  fell from 10 882 at 0.5 px to 9 511 at 0.1 px, while 0.5–3 px kept 10 882–10 907
  (4 cameras, 3 per match: 7 923–7 976). :data:`PIXEL_FLOOR` = 1.5 px is the middle of
  that plateau, the 150 µm the paper's rig was matched with;
- the median ray distance of the matches (every ray of every match, distance to its
  point) measures the calibration's triangulation error on the particles themselves.
  With Gaussian errors, :data:`SPREAD_PER_MEDIAN` = 6 medians is 4σ of the half-normal
  distance of a 2-camera match and 5σ of the Rayleigh distance of a match of three or
  more; the median, unlike a high quantile, is not moved by a few per cent of stray
  matches. It is iterated from the floor: a tolerance that cuts the distribution's tail
  lowers its median less than 6-fold, so the next tolerance is wider, until it changes
  by less than :data:`CONVERGED`.

On every rendered rig with a good calibration the floor decides (the median ray
distance is 2–7 µm against a 1.5 px floor of 150 µm); a poor one is given the tolerance
its own errors need (the Tsai fit above: 0.8 mm, 7573 matches).
"""

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ptv.box import Box, check_box
from ptv.camera_model import CameraModel
from ptv.matching.stereo import match

__all__ = ["MatchTolerance", "match_tolerance", "pixel_footprint"]

#: The tolerance is never below this many pixel footprints.
PIXEL_FLOOR = 1.5
#: ... nor below this many median ray distances of the matches.
SPREAD_PER_MEDIAN = 6.0
#: Iterations stop when the tolerance changes by less than this fraction.
CONVERGED = 0.05
MAX_ITERATIONS = 10


@dataclass(frozen=True)
class MatchTolerance:
    """A matching tolerance, measured (see the module docstring).

    Attributes
    ----------
    tolerance : float
        max(PIXEL_FLOOR · pixel_footprint, SPREAD_PER_MEDIAN · median_ray_distance), m.
    pixel_footprint : float
        Distance between the rays of neighbouring pixels at the volume centre, the largest
        over the cameras, m.
    median_ray_distance : float
        Median distance of the matched rays from their points at the final tolerance, m.
    rays : int
        Matched rays the median rests on.
    frames : int
        Frames they come from.
    iterations : int
        Tolerances tried.
    """

    tolerance: float
    pixel_footprint: float
    median_ray_distance: float
    rays: int
    frames: int
    iterations: int

    def as_dict(self) -> dict:
        """JSON-able form (SI units)."""
        return {
            "tolerance": self.tolerance,
            "pixel_footprint": self.pixel_footprint,
            "median_ray_distance": self.median_ray_distance,
            "rays": self.rays,
            "frames": self.frames,
            "iterations": self.iterations,
        }


def pixel_footprint(cameras: Sequence[CameraModel], volume: Box) -> float:
    """Distance between the rays through neighbouring pixels at the centre of a volume,
    the largest over the cameras, m.

    For each camera, the rays through the image (x, y) of the volume's centre and through
    (x + 1, y) and (x, y + 1) are taken; the footprint is the larger distance from the
    point of the first ray nearest the centre to the other two rays.

    Parameters
    ----------
    cameras : sequence of CameraModel
        Calibrations.
    volume : (lower, upper)
        Matching volume, m.

    Raises
    ------
    ValueError
        A camera does not image the volume's centre.
    """
    lower, upper = (np.asarray(v, dtype=np.float64) for v in check_box("volume", volume))
    centre = 0.5 * (lower + upper)
    footprints = []
    for c, camera in enumerate(cameras):
        xy = np.asarray(camera.project(centre[None]), dtype=np.float64).reshape(2)
        rays = camera.pixel_to_ray(xy + np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]))
        origins = np.asarray(rays.origins, dtype=np.float64)
        directions = np.asarray(rays.directions, dtype=np.float64)
        if not (np.isfinite(origins).all() and np.isfinite(directions).all()):
            raise ValueError(
                f"camera {c} does not image the centre of the matching volume "
                f"{np.round(centre, 4).tolist()} m: check the volume and the calibration"
            )
        directions = directions / np.linalg.norm(directions, axis=1, keepdims=True)
        nearest = origins[0] + np.dot(centre - origins[0], directions[0]) * directions[0]
        offsets = nearest - origins[1:]
        along = np.sum(offsets * directions[1:], axis=1, keepdims=True)
        footprints.append(np.linalg.norm(offsets - along * directions[1:], axis=1).max())
    return float(max(footprints))


def _ray_distances(
    cameras: Sequence[CameraModel],
    frames: Sequence[Sequence[np.ndarray]],
    volume: Box,
    tolerance: float,
    min_cameras: int,
) -> np.ndarray:
    """Distances of every matched ray from its point, over all frames, m."""
    distances = [
        match(cameras, list(xy), volume, tolerance=tolerance, min_cameras=min_cameras).ray_distances
        for xy in frames
    ]
    flat = np.concatenate([d.ravel() for d in distances]) if distances else np.empty(0)
    return flat[np.isfinite(flat)]


def match_tolerance(
    cameras: Sequence[CameraModel],
    frames: Sequence[Sequence[np.ndarray]],
    volume: Box,
    *,
    min_cameras: int,
) -> MatchTolerance:
    """The matching tolerance of a rig, measured on some of its frames (module docstring).

    Parameters
    ----------
    cameras : sequence of C CameraModel
        Calibrations.
    frames : sequence of (sequence of C ndarray, shape (N_c, 2))
        Detected centres of each camera on some frames, px.
    volume : (lower, upper)
        Matching volume, m.
    min_cameras : int
        Fewest cameras per match.

    Returns
    -------
    MatchTolerance

    Raises
    ------
    ValueError
        A camera does not image the volume's centre, or no particle matched on the frames
        at the pixel-footprint floor.
    """
    footprint = pixel_footprint(cameras, volume)
    floor = PIXEL_FLOOR * footprint
    tolerance, iterations = floor, 0
    while iterations < MAX_ITERATIONS:
        iterations += 1
        distances = _ray_distances(cameras, frames, volume, tolerance, min_cameras)
        if len(distances) == 0:
            detected = [sum(len(xy[c]) for xy in frames) for c in range(len(cameras))]
            raise ValueError(
                f"no particle matched on {len(frames)} frame(s) within {tolerance * 1e6:.3g} µm "
                f"({tolerance / footprint:.3g} px; detections per camera {detected}): check "
                "the images, that the calibration is of this rig and the matching volume, or "
                "set the tolerance"
            )
        median = float(np.median(distances))
        wanted = max(floor, SPREAD_PER_MEDIAN * median)
        converged = abs(wanted / tolerance - 1.0) < CONVERGED
        tolerance = wanted
        if converged:
            break
    return MatchTolerance(
        tolerance=tolerance,
        pixel_footprint=footprint,
        median_ray_distance=median,
        rays=len(distances),
        frames=len(frames),
        iterations=iterations,
    )
