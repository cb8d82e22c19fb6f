"""Mutations of matching, linking and the median test that bind only where particles crowd.

On the sparse cases every camera ray meets one candidate and every particle one
neighbour, so a plainly worse algorithm or a tolerance many times too wide changes no
claim there. The crowded case's claims (docs/claims.md #42–#45) catch them.
"""

import numpy as np

from ptv.matching import tolerance as matching_tolerance
from ptv.tracking import linking as track
from ptv.tracking.outliers import median_test_outliers
from validation.mutations.base import Mutation
from validation.mutations.patching import Patch
from validation.mutations.probes import POINTS, stereo_pair

#: The pixel-footprint floor of the matching tolerance, ten times the stack's 1.5.
WIDE_FLOOR = 15.0


def _greedy(original):
    """Links taken nearest first, each particle once: the greedy linker."""

    def link_step(predicted, radius, targets, continuation=None):
        i, j, d = track._candidates(predicted, radius, targets)
        cost = (d / radius[i]) ** 2
        if continuation is not None and len(i):
            cost = (cost + continuation(i, j)) / 2
        taken_a = np.zeros(len(predicted), dtype=bool)
        taken_b = np.zeros(len(targets), dtype=bool)
        chosen = []
        for edge in np.argsort(cost, kind="stable"):
            if not (taken_a[i[edge]] or taken_b[j[edge]]):
                taken_a[i[edge]] = taken_b[j[edge]] = True
                chosen.append(edge)
        chosen = np.array(sorted(chosen, key=lambda e: i[e]), dtype=np.int64)
        ambiguous = int(np.sum(np.bincount(i, minlength=len(predicted))[i[chosen]] > 1))
        return i[chosen], j[chosen], d[chosen], ambiguous, len(i)

    return link_step


def _greedy_assignment(original):
    """The shared assignment solved greedily: cheapest edge first, each item once."""

    def assign(rows, cols, cost, shape, *, unmatched_cost=1.0):
        taken_rows = np.zeros(shape[0], dtype=bool)
        taken_cols = np.zeros(shape[1], dtype=bool)
        chosen = []
        for edge in np.argsort(cost, kind="stable"):
            if cost[edge] < 2 * unmatched_cost and not (
                taken_rows[rows[edge]] or taken_cols[cols[edge]]
            ):
                taken_rows[rows[edge]] = taken_cols[cols[edge]] = True
                chosen.append(edge)
        return np.array(sorted(chosen), dtype=np.int64)

    return assign


def _flags_nothing(original):
    def median_test(positions, displacements, **options):
        return np.zeros(len(positions), dtype=bool)

    return median_test


def _threshold_doubled(original):
    def median_test(positions, displacements, *, threshold, **options):
        return original(positions, displacements, threshold=2 * threshold, **options)

    return median_test


def _neighbours_halved(original):
    def median_test(positions, displacements, *, neighbours=8, **options):
        return original(positions, displacements, neighbours=neighbours // 2, **options)

    return median_test


def _linked():
    """Links of two particles whose nearest pair is a trap for a greedy linker."""
    a = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    b = np.array([[0.6, 0.0, 0.0], [1.7, 0.0, 0.0]])
    return np.array([len(track.link(a, b, radius=1.0))])


def _tolerance():
    cameras = stereo_pair()
    volume = (np.array([-0.1, -0.1, 0.2]), np.array([0.1, 0.1, 0.4]))
    pixels = [[c.project(POINTS) for c in cameras]]
    measured = matching_tolerance.match_tolerance(cameras, pixels, volume, min_cameras=2)
    return np.array([measured.tolerance])


def _flagged():
    rng = np.random.default_rng(0)
    positions = rng.random((50, 3))
    displacements = 1e-3 + rng.normal(0.0, 1e-5, (50, 3))
    displacements[::10] += 1e-4
    return median_test_outliers(positions, displacements, threshold=4.0, noise=1e-6)


_MEDIAN_TEST = "ptv.tracking.outliers:median_test_outliers"

CROWDING_MUTATIONS: tuple[Mutation, ...] = (
    Mutation(
        "linking-greedy",
        "links taken nearest first, each particle once, in place of the minimum-cost "
        "one-to-one assignment",
        (Patch("ptv.tracking.linking:_link_step", _greedy),),
        ("image.crowded_linking",),
        ("image",),
        _linked,
    ),
    Mutation(
        "assignment-greedy",
        "the one-to-one assignment that matching and linking share solved greedily, "
        "cheapest edge first",
        (Patch("ptv._assign:assign", _greedy_assignment),),
        ("image.matching_reference", "image.crowded_linking"),
        ("image",),
        _linked,
    ),
    Mutation(
        "match-tolerance-ten-times",
        "the matching tolerance's floor is 15 pixel footprints, ten times the stack's",
        (Patch("ptv.matching.tolerance:PIXEL_FLOOR", lambda _: WIDE_FLOOR),),
        ("image.crowded_yield", "image.crowded_ghosts"),
        ("image",),
        _tolerance,
    ),
    Mutation(
        "outlier-test-off",
        "the normalised median test flags no link",
        (Patch(_MEDIAN_TEST, _flags_nothing),),
        ("image.crowded_outliers",),
        ("image",),
        _flagged,
    ),
    Mutation(
        "median-test-four-neighbours",
        "the normalised median test compares each link with half the neighbours it is given",
        (Patch(_MEDIAN_TEST, _neighbours_halved),),
        ("image.crowded_outliers",),
        ("image",),
        _flagged,
    ),
    Mutation(
        "outlier-threshold-doubled",
        "the normalised median test runs at twice the threshold it is given",
        (Patch(_MEDIAN_TEST, _threshold_doubled),),
        ("image.crowded_outliers",),
        ("image",),
        _flagged,
    ),
)
