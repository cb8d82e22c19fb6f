"""Options of the iterative particle reconstruction, validated on construction."""

from dataclasses import dataclass

import numpy as np


def _int(name: str, value: object, low: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < low:
        raise ValueError(f"{name} must be an integer >= {low}, got {value!r}")
    return int(value)


def _float(name: str, value: object, low: float, *, strict: bool = True, high=np.inf) -> float:
    ok = isinstance(value, int | float | np.integer | np.floating) and not isinstance(value, bool)
    if not ok or not np.isfinite(value) or value < low or (strict and value == low) or value > high:
        bound = f"> {low}" if strict else f">= {low}"
        raise ValueError(f"{name} must be a finite number {bound} and <= {high}, got {value!r}")
    return float(value)


@dataclass(frozen=True)
class IPRSettings:
    """How :func:`ptv.reconstruct.reconstruct` works (Wieneke 2013; Jahn et al. 2021).

    Attributes
    ----------
    outer_iterations : int
        Outer iterations (peaks → triangulation → shaking → removal) at most, >= 0.
    reduced_iterations : int
        The last ones of these triangulate with one camera fewer too (a particle whose
        image is hidden in one camera) if that has not begun before, >= 0.
    reduce_below : float
        Triangulation with one camera fewer begins once an iteration increases the
        number of particles by less than this fraction, >= 0.
    converged : float
        The iterations stop when, after at least two with one camera fewer, one adds at
        most this fraction of the particles, >= 0.
    shake_iterations : int
        Shaking passes per outer iteration, >= 0 (0: no shaking).
    final_shakes : int
        Shaking passes after the last outer iteration, >= 0.
    tolerance : float
        Largest distance between a candidate's projection and its peak in each camera,
        px, > 0.
    tolerance_start : float
        The tolerance of the first iteration, px, > 0, at most ``tolerance``; it grows
        linearly to ``tolerance`` over ``tolerance_ramp`` iterations (the first
        particles, taken with a tight tolerance, are the surest: fewer ghosts borrow
        the light of particles not yet found).
    tolerance_ramp : int
        Iterations over which the tolerance grows, >= 0.
    peak_threshold : float
        Peaks of the residual below this fraction of a typical particle image's peak
        (from the OTF) are ignored, >= 0.
    noise_threshold : float
        … and below this many background noise σ, >= 0.
    shake_step : float
        Shaking step of the first pass of each outer iteration, as the image motion it
        causes, px (rms over the cameras; about one voxel per px laterally), > 0.
    shake_step_min : float
        Step of the last pass of each outer iteration (geometric in between), px, > 0,
        at most ``shake_step``.
    intensity_threshold : float
        Particles whose intensity falls below this fraction of a typical particle's
        (the OTF's intensity, E = 1) are removed after the shaking (ghosts are faint),
        >= 0 and < 1. The reference is the OTF's, not the mean of the reconstructed
        particles, which ghosts drag down at high density.
    camera_ratio : float
        Particles whose intensity seen by one camera alone is below this fraction of
        their intensity are removed (a ghost borrows light in some cameras only),
        >= 0 and < 1 (0: no such test).
    peak_uses : int
        A peak may serve this many new candidates of one iteration at most
        (:func:`ptv.reconstruct.triangulation.select_candidates`), >= 1.
    merge_distance : float
        Particles closer than this are merged into one, voxels, >= 0.
    epipolar_samples : int
        Points along each reference ray whose projections form the epipolar polylines,
        >= 2.
    radius_sigmas : float
        Half-width of a particle image's window, in its σ, >= 2.5.
    margin : float
        Particles may lie this far outside the measurement volume, voxels, >= 0.
    min_cameras : int
        Particles seen by fewer cameras are removed, >= 2.
    mapping_grid : float
        0: the cameras' ``project`` is called directly. > 0: it is interpolated from a
        grid of this step, voxels (:class:`ptv.reconstruct.mapping.GridMapping`), for
        calibrations whose ``project`` is slow (model-free: about 6·10³ points/s);
        32 voxels (about 2 mm at 60 µm) interpolate to 2·10⁻⁵ px.
    """

    outer_iterations: int = 60
    reduced_iterations: int = 4
    reduce_below: float = 0.05
    converged: float = 0.005
    shake_iterations: int = 4
    final_shakes: int = 4
    tolerance: float = 1.0
    tolerance_start: float = 1.0
    tolerance_ramp: int = 0
    peak_threshold: float = 0.1
    noise_threshold: float = 4.0
    shake_step: float = 0.5
    shake_step_min: float = 0.05
    intensity_threshold: float = 0.35
    camera_ratio: float = 0.5
    peak_uses: int = 1
    merge_distance: float = 1.0
    epipolar_samples: int = 9
    radius_sigmas: float = 3.5
    margin: float = 2.0
    min_cameras: int = 3
    mapping_grid: float = 0.0

    def __post_init__(self) -> None:
        _int("outer_iterations", self.outer_iterations, 0)
        _int("reduced_iterations", self.reduced_iterations, 0)
        _int("shake_iterations", self.shake_iterations, 0)
        _int("final_shakes", self.final_shakes, 0)
        _int("epipolar_samples", self.epipolar_samples, 2)
        _int("min_cameras", self.min_cameras, 2)
        _int("peak_uses", self.peak_uses, 1)
        _float("tolerance", self.tolerance, 0.0)
        _float("tolerance_start", self.tolerance_start, 0.0, high=self.tolerance)
        _int("tolerance_ramp", self.tolerance_ramp, 0)
        _float("peak_threshold", self.peak_threshold, 0.0, strict=False)
        _float("noise_threshold", self.noise_threshold, 0.0, strict=False)
        _float("shake_step", self.shake_step, 0.0)
        _float("shake_step_min", self.shake_step_min, 0.0, high=self.shake_step)
        _float("intensity_threshold", self.intensity_threshold, 0.0, strict=False, high=0.999)
        _float("reduce_below", self.reduce_below, 0.0, strict=False)
        _float("converged", self.converged, 0.0, strict=False)
        _float("camera_ratio", self.camera_ratio, 0.0, strict=False, high=0.999)
        _float("merge_distance", self.merge_distance, 0.0, strict=False)
        _float("radius_sigmas", self.radius_sigmas, 2.5, strict=False, high=8.0)
        _float("margin", self.margin, 0.0, strict=False)
        _float("mapping_grid", self.mapping_grid, 0.0, strict=False)
