"""The crowded-case references: optimal links and the median test, against enumeration and
hand-made cases."""

from itertools import permutations

import numpy as np

from validation.truth.optimal_links import median_test, optimal_links


def _best_by_enumeration(a, b, radius):
    """Max Σ(2 − (d/r)²) over every one-to-one choice of links, by brute force."""
    best, best_links = 0.0, set()
    n = max(len(a), len(b))
    for order in permutations(range(n)):
        links, score = set(), 0.0
        for i, j in enumerate(order):
            if i < len(a) and j < len(b):
                d = np.linalg.norm(a[i] - b[j])
                if d <= radius:
                    links.add((i, j))
                    score += 2.0 - (d / radius) ** 2
        if score > best + 1e-12:
            best, best_links = score, links
    return best_links


def test_optimal_links_are_the_best_choice_by_enumeration():
    rng = np.random.default_rng(0)
    for _ in range(20):
        a, b = rng.random((5, 3)), rng.random((6, 3))
        index_a, index_b = optimal_links(a, b, radius=0.5)
        assert set(zip(index_a.tolist(), index_b.tolist(), strict=True)) == (
            _best_by_enumeration(a, b, 0.5)
        )


def test_optimal_links_avoid_the_nearest_pair_trap():
    # The nearest pair (a1, b0) would leave a0 without a partner: both are linked instead.
    a = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    b = np.array([[0.6, 0.0, 0.0], [1.7, 0.0, 0.0]])
    index_a, index_b = optimal_links(a, b, radius=1.0)
    assert index_a.tolist() == [0, 1] and index_b.tolist() == [0, 1]


def test_the_median_test_flags_a_link_against_its_neighbours():
    rng = np.random.default_rng(1)
    positions = rng.random((200, 3))
    displacements = np.tile([1e-3, 0.0, 0.0], (200, 1)) + rng.normal(0, 1e-5, (200, 3))
    displacements[17] += [0.0, 5e-4, 0.0]
    flags = median_test(positions, displacements, threshold=4.0, noise=1e-6, neighbours=8)
    assert np.flatnonzero(flags).tolist() == [17]


def test_the_median_test_needs_four_links():
    flags = median_test(np.zeros((3, 3)), np.ones((3, 3)), threshold=4.0, noise=0.0, neighbours=8)
    assert not flags.any()
