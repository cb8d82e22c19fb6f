"""What the stack did on the crowded case, against references that share no code with it
(docs/claims.md #42–#45).

On the default rig and flow with twice the tracers and three times the largest Δt
(:data:`validation.claims.rendered_case.CROWDED_CASE`), each camera ray meets more than
one candidate and each particle has neighbours within the link radius. The references:

- yield and ghosts of the matched points in the analysis box (0.7 × 0.7 × 0.8 of the
  sheet), paired one-to-one with the true particles within one voxel
  (:func:`validation.truth.matching.assign_one_to_one`);
- the links against the minimum-cost one-to-one links of the same matched points in the
  radius the settings give, solved densely (:func:`validation.truth.optimal_links.
  optimal_links`);
- the outlier flags against the normalised median test with the documented defaults
  (threshold 4, 8 neighbours, ε₀ = 30 µm), written apart from the stack
  (:func:`validation.truth.optimal_links.median_test`).
"""

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from validation.claims.image_scores import SAME_POINT, VOXEL
from validation.claims.rendered_case import RenderedCase
from validation.run.derived_ptv import SHEET_FRACTION
from validation.truth.matching import assign_one_to_one
from validation.truth.optimal_links import median_test, optimal_links

#: The documented defaults of the median test (docs/ptv.md §4) and of the position noise
#: in the link radius.
MEDIAN_THRESHOLD = 4.0
MEDIAN_NEIGHBOURS = 8
POSITION_NOISE = 30e-6


@dataclass(frozen=True)
class CrowdedScores:
    """What the stack did on the crowded case, summed over its frame pairs.

    Attributes
    ----------
    particles, found : int
        True particles in the analysis box (frames a and b), and those paired with a
        matched point.
    matched, ghosts : int
        Matched points in the box, and those paired with no particle.
    links, wrong, wrong_kept, outliers : int
        Links starting in the box from a paired point; those ending elsewhere than the
        same particle's point; of them, those the median test kept; links it flagged.
    links_differ : int
        Links of the stack not among the reference's, and the reverse.
    reference_links : int
        The reference's links.
    flags_differ : int
        Links whose outlier flag differs from the reference test's.
    all_links : int
        Every link of the stack.
    """

    particles: int
    found: int
    matched: int
    ghosts: int
    links: int
    wrong: int
    wrong_kept: int
    outliers: int
    links_differ: int
    reference_links: int
    flags_differ: int
    all_links: int


def crowded_scores(case: RenderedCase) -> CrowdedScores:
    """:class:`CrowdedScores` of the case (module docstring)."""
    centre = np.asarray(case.rig.sheet.centre)
    size = np.asarray(SHEET_FRACTION) * np.asarray(case.rig.sheet.size)  # the run's box
    lower, upper = (
        centre - 0.5 * size,
        centre + 0.5 * size,
    )
    inside = lambda p: np.all((p >= lower) & (p <= upper), axis=1)  # noqa: E731
    radius = case.settings.max_speed * case.dt + 5 * POSITION_NOISE
    totals = dict.fromkeys(CrowdedScores.__dataclass_fields__, 0)
    for m, measurement in enumerate(case.measurements):
        for f, points in enumerate(measurement.matched):
            truth = case.positions[m, f]
            partner = assign_one_to_one(points, truth, VOXEL)
            totals["particles"] += int(inside(truth).sum())
            totals["found"] += int(np.isin(np.flatnonzero(inside(truth)), partner).sum())
            totals["matched"] += int(inside(points).sum())
            totals["ghosts"] += int((inside(points) & (partner < 0)).sum())
        start = assign_one_to_one(measurement.positions, case.positions[m, 0], VOXEL)
        end = assign_one_to_one(
            measurement.positions + measurement.displacements, case.positions[m, 1], VOXEL
        )
        counted = inside(measurement.positions) & (start >= 0)
        wrong = counted & (start != end)
        totals["links"] += int(counted.sum())
        totals["wrong"] += int(wrong.sum())
        totals["wrong_kept"] += int((wrong & ~measurement.outlier).sum())
        totals["outliers"] += int((counted & measurement.outlier).sum())
        differ, reference_links = _link_differences(measurement, radius)
        totals["links_differ"] += differ
        totals["reference_links"] += reference_links
        reference = median_test(
            measurement.positions,
            measurement.displacements,
            threshold=MEDIAN_THRESHOLD,
            noise=POSITION_NOISE,
            neighbours=MEDIAN_NEIGHBOURS,
        )
        totals["flags_differ"] += int((reference != measurement.outlier).sum())
        totals["all_links"] += len(measurement.positions)
    return CrowdedScores(**totals)


def _link_differences(measurement, radius: float) -> tuple[int, int]:
    """Links of the stack and of the reference that the other lacks, and the reference's."""
    a, b = measurement.matched
    index_a, index_b = optimal_links(a, b, radius)
    start = _rows(a, measurement.positions)
    end = _rows(b, measurement.positions + measurement.displacements)
    stack = set(zip(start.tolist(), end.tolist(), strict=True))
    reference = set(zip(index_a.tolist(), index_b.tolist(), strict=True))
    return len(stack ^ reference), len(reference)


def _rows(points: np.ndarray, of: np.ndarray) -> np.ndarray:
    """The row of ``points`` each point of ``of`` is (−1 if none is within SAME_POINT)."""
    if not len(of):
        return np.empty(0, dtype=np.int64)
    distance, row = cKDTree(points).query(of)
    return np.where(distance <= SAME_POINT, row, -1)
