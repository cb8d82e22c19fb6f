"""Hypothesis: the Kabsch fit recovers a rigid motion and always returns a proper rotation."""

import numpy as np
from hypothesis import assume, given
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from validation.truth.matching import rigid_fit

seeds = st.integers(0, 2**32 - 1)


def point_set(rng, n, spread):
    """n points with spread ``spread`` (m) about a random centre, not near a line."""
    points = rng.normal(size=3) * 0.05 + rng.normal(size=(n, 3)) * spread
    singular = np.linalg.svd(points - points.mean(axis=0), compute_uv=False)
    assume(singular[1] > 0.1 * singular[0])
    return points


@given(seed=seeds, n=st.integers(4, 60), spread=st.floats(1e-3, 0.1))
def test_an_exact_rigid_motion_is_recovered(seed, n, spread):
    rng = np.random.default_rng(seed)
    rotation = Rotation.random(random_state=rng).as_matrix()
    translation = rng.normal(size=3) * 0.05
    source = point_set(rng, n, spread)
    target = source @ rotation.T + translation
    fitted_rotation, fitted_translation = rigid_fit(source, target)
    assert np.abs(fitted_rotation - rotation).max() < 1e-9
    assert np.abs(fitted_translation - translation).max() < 1e-9


@given(seed=seeds, n=st.integers(4, 60), noise=st.floats(0.0, 3.0), mirror=st.booleans())
def test_the_fit_is_a_proper_rotation_even_for_noisy_or_mirrored_points(seed, n, noise, mirror):
    rng = np.random.default_rng(seed)
    rotation = Rotation.random(random_state=rng).as_matrix()
    source = point_set(rng, n, 0.01)
    target = source @ rotation.T + rng.normal(size=(n, 3)) * noise * 0.01
    if mirror:  # the best orthogonal map is then a reflection; the fit must not return it
        target = target * np.array([1.0, 1.0, -1.0])
    fitted_rotation, fitted_translation = rigid_fit(source, target)
    assert np.allclose(fitted_rotation.T @ fitted_rotation, np.eye(3), atol=1e-12)
    assert np.linalg.det(fitted_rotation) > 0.0
    assert abs(np.linalg.det(fitted_rotation) - 1.0) < 1e-12
    assert fitted_translation.shape == (3,) and np.all(np.isfinite(fitted_translation))


@given(seed=seeds, n=st.integers(4, 40))
def test_the_fit_minimises_the_squared_misfit(seed, n):
    rng = np.random.default_rng(seed)
    source = point_set(rng, n, 0.01)
    target = source @ Rotation.random(random_state=rng).as_matrix().T
    target = target + rng.normal(size=(n, 3)) * 2e-3
    fitted_rotation, fitted_translation = rigid_fit(source, target)

    def misfit(rotation, translation):
        return np.sum((source @ rotation.T + translation - target) ** 2)

    best = misfit(fitted_rotation, fitted_translation)
    for _ in range(10):  # any nearby rigid motion fits worse
        nudge = Rotation.from_rotvec(rng.normal(size=3) * 1e-3).as_matrix()
        assert misfit(nudge @ fitted_rotation, fitted_translation) >= best
        assert misfit(fitted_rotation, fitted_translation + rng.normal(size=3) * 1e-5) >= best
