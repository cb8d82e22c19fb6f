"""What the image-stack claims measure on the rendered case, against the simulator's truth.

Each function compares the PTV stack's output on :class:`RenderedCase` with something it
shares no code with: the exact image of every particle centre and its spot (from the
renderer), the Cramér–Rao bound (:mod:`validation.truth.localisation_bound`), a
brute-force matcher (:mod:`validation.truth.brute_matching`) and the true positions.
"""

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree
from scipy.special import erf

from validation.claims.rendered_case import Exposure, RenderedCase
from validation.truth.brute_matching import brute_force_match
from validation.truth.localisation_bound import localisation_bound
from validation.truth.matching import assign_one_to_one

#: A detection within this distance of a particle's exact image is its detection, px.
ASSOCIATION_PX = 1.0
#: A particle is isolated when no other visible particle's image is this close, px
#: (the detector's 7 × 7 window, plus one pixel).
ISOLATION_PX = 4.0
#: Particles closer than this to the sensor's edge are left out of the detection
#: scores (the detector's window would be cut), px.
EDGE_PX = 3.0
#: A detected point within this distance of a true particle is that particle, m (one
#: object-side pixel of the paper-stereo rig).
VOXEL = 1e-4
#: Two matched points closer than this are the same point, m.
SAME_POINT = 1e-9


@dataclass(frozen=True)
class DetectionScores:
    """Detection errors of isolated particles.

    Attributes
    ----------
    errors : ndarray, shape (N, 2)
        Detected − exact centre of the isolated particles found, px.
    bound : ndarray, shape (N, 2)
        Their Cramér–Rao standard deviations, px.
    fraction : ndarray, shape (N, 2)
        Exact centre − nearest pixel centre, in [−½, ½), px.
    sigma : ndarray, shape (N,)
        Their spots' exact Gaussian σ, px.
    electrons : ndarray, shape (N,)
        Their spots' expected photo-electrons, e⁻.
    bright_found : int
        Isolated particles whose brightest pixel expects at least twice the detection
        threshold, found.
    bright : int
        Such particles.
    """

    errors: np.ndarray
    bound: np.ndarray
    fraction: np.ndarray
    sigma: np.ndarray
    electrons: np.ndarray
    bright_found: int
    bright: int


def _exposure_scores(exposure: Exposure, read_noise: float, threshold_e: float) -> tuple:
    """Errors, bounds, fractions, σ and photo-electrons of the isolated particles found;
    bright found, bright."""
    frame = exposure.frame
    rows, cols = frame.image.shape
    xy = frame.xy[frame.visible]
    sigma, electrons = frame.sigma[frame.visible], frame.electrons[frame.visible]
    neighbour, _ = cKDTree(xy).query(xy, k=2)
    interior = np.all(
        (xy >= EDGE_PX - 0.5) & (xy <= np.array([cols, rows]) - 0.5 - EDGE_PX), axis=1
    )
    isolated = (neighbour[:, 1] > ISOLATION_PX) & interior
    distance, nearest = cKDTree(exposure.detected.xy).query(xy, distance_upper_bound=ASSOCIATION_PX)
    found = np.isfinite(distance)
    peak = electrons * np.prod(_centre_pixel_fraction(xy - np.round(xy), sigma[:, None]), axis=1)
    bright = isolated & (peak >= 2.0 * threshold_e)
    keep = isolated & found
    errors = exposure.detected.xy[nearest[keep]] - xy[keep]
    bound = localisation_bound(xy[keep], sigma[keep], electrons[keep], read_noise)
    fraction = xy[keep] - np.round(xy[keep])
    spots = (sigma[keep], electrons[keep])
    return errors, bound, fraction, *spots, int(np.sum(bright & found)), int(np.sum(bright))


def _centre_pixel_fraction(offset: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """Fraction of a Gaussian spot on its centre pixel, per axis, offset in px."""
    s = np.sqrt(2.0) * sigma
    return 0.5 * (erf((0.5 - offset) / s) + erf((0.5 + offset) / s))


def detection_scores(case: RenderedCase, threshold_sigmas: float) -> DetectionScores:
    """:class:`DetectionScores` over every exposure of the case.

    ``threshold_sigmas`` is the detector's threshold in noise units; a particle counts
    as bright when its brightest pixel expects twice that many read-noise σ.
    """
    noise = float(np.hypot(case.sensor.read_noise, np.sqrt(case.sensor.background)))
    parts = [
        _exposure_scores(e, noise, threshold_sigmas * noise)
        for snapshot in case.exposures
        for frame in snapshot
        for e in frame
    ]
    return DetectionScores(
        errors=np.concatenate([p[0] for p in parts]),
        bound=np.concatenate([p[1] for p in parts]),
        fraction=np.concatenate([p[2] for p in parts]),
        sigma=np.concatenate([p[3] for p in parts]),
        electrons=np.concatenate([p[4] for p in parts]),
        bright_found=sum(p[5] for p in parts),
        bright=sum(p[6] for p in parts),
    )


def harmonic_bias(errors: np.ndarray, fraction: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Peak locking: the first harmonic of the error against the fractional position.

    For each axis, e ≈ a sin 2πφ + b cos 2πφ with a = 2⟨e sin 2πφ⟩ and b = 2⟨e cos 2πφ⟩
    (φ uniform over the pixel); the amplitude is √(a² + b²).

    Parameters
    ----------
    errors, fraction : ndarray, shape (N, 2)
        Errors and fractional positions of the exact centres, px.

    Returns
    -------
    amplitude, standard_error : ndarray, shape (2,)
        Per axis, px (the standard error is the larger of a's and b's).
    """
    coefficients, errors_of = [], []
    for basis in (np.sin, np.cos):
        terms = 2.0 * errors * basis(2 * np.pi * fraction)
        coefficients.append(terms.mean(axis=0))
        errors_of.append(terms.std(axis=0) / np.sqrt(len(terms)))
    return np.hypot(*coefficients), np.maximum(*errors_of)


def matching_differences(case: RenderedCase) -> tuple[int, int]:
    """Matched points of the stack without an equal point of the brute-force matcher,
    and the reverse, summed, and the points of both, summed, over every frame."""
    differ = total = 0
    for m, measurement in enumerate(case.measurements):
        for f, points in enumerate(measurement.matched):
            rays = tuple(
                camera.pixel_to_ray(e.detected.xy)
                for camera, e in zip(case.rig.cameras, case.exposures[m][f], strict=True)
            )
            reference = brute_force_match(rays, case.settings.volume, case.settings.tolerance)
            differ += _unpaired(points, reference) + _unpaired(reference, points)
            total += len(points) + len(reference)
    return differ, total


def _unpaired(points: np.ndarray, others: np.ndarray) -> int:
    """Points with no point of ``others`` within :data:`SAME_POINT`."""
    if not len(others):
        return len(points)
    distance, _ = cKDTree(others).query(points)
    return int(np.sum(distance > SAME_POINT))


def position_errors(case: RenderedCase) -> np.ndarray:
    """Matched − true position of every matched point paired with a particle, (N, 3), m."""
    errors = []
    for m, measurement in enumerate(case.measurements):
        for f, points in enumerate(measurement.matched):
            truth = case.positions[m, f]
            partner = assign_one_to_one(points, truth, VOXEL)
            errors.append(points[partner >= 0] - truth[partner[partner >= 0]])
    return np.concatenate(errors)


@dataclass(frozen=True)
class LinkingScores:
    """Links between particles matched in both frames.

    Attributes
    ----------
    linkable : int
        Particles matched (paired with a point) in frame a and in frame b.
    failed : int
        Of those, not linked to their own frame-b point.
    expected : float
        Failures expected when a competitor closer than the particle's own displacement
        takes its place: Σ 2[1 − exp(−n·(4/3)π|ΔX|³)], n the density of matched points.
    """

    linkable: int
    failed: int
    expected: float


def linking_scores(case: RenderedCase) -> LinkingScores:
    """:class:`LinkingScores` over every snapshot of the case."""
    lower, upper = (np.asarray(c) for c in case.settings.volume)
    volume = float(np.prod(upper - lower))
    linkable = failed = 0
    expected = 0.0
    for m, measurement in enumerate(case.measurements):
        points_a, points_b = measurement.matched
        true_a, true_b = case.positions[m]
        a = assign_one_to_one(points_a, true_a, VOXEL)
        b = assign_one_to_one(points_b, true_b, VOXEL)
        both = np.intersect1d(a[a >= 0], b[b >= 0])
        start = assign_one_to_one(measurement.positions, true_a, VOXEL)
        end = assign_one_to_one(measurement.positions + measurement.displacements, true_b, VOXEL)
        correct = np.intersect1d(start[(start >= 0) & (start == end)], both)
        linkable += len(both)
        failed += len(both) - len(correct)
        density = 0.5 * (len(points_a) + len(points_b)) / volume
        move = np.linalg.norm(true_b[both] - true_a[both], axis=1)
        expected += float(np.sum(2.0 * -np.expm1(-density * 4.0 / 3.0 * np.pi * move**3)))
    return LinkingScores(linkable, failed, expected)
