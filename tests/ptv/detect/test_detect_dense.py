"""Detection on dense images against what an efficient detector could do there.

The images are rendered by ``benchmarks/bench_dense.py`` (pixel-integrated Gaussian
spots, σ 0.7–1.0 px, 800–8000 e⁻, shot and read noise, 12 bits), which shares no code
with :mod:`ptv`; the reference is its efficient detector, built from the truth and each
particle's Cramér–Rao bound among its neighbours (:mod:`validation.truth.crowded_bound`):
every particle at its bound, except that particles closer than a resolving distance are
one spot at their brightness-weighted centre. synptv must find at least as many
particles as such a detector resolving pairs from 1.5 px, and locate them at least as
well as one resolving pairs from 1.2 px; the margins are three standard errors of the
measured fraction and mean square error (sampling, on one 512 × 512 image).
"""

import numpy as np
import pytest

from benchmarks.bench_dense import (
    SHAPE,
    bound,
    efficient_detector,
    match,
    record,
    rejecting_oracle,
    render,
    spots,
)
from ptv.detect import detect_particles


def _dense_image(ppp: float, seed: int) -> tuple:
    rng = np.random.default_rng(seed)
    xy, sigma, electrons = spots(ppp, SHAPE, rng)
    image = record(render(xy, sigma, electrons, SHAPE), rng)
    return xy, electrons, bound(xy, sigma, electrons), image


@pytest.mark.parametrize("ppp", [0.002, 0.01, 0.03])
def test_dense_images_are_detected_as_an_efficient_detector_would(ppp):
    xy, electrons, limit, image = _dense_image(ppp, seed=11)
    found = detect_particles(image).xy
    t, f = match(xy, found)
    square = ((found[f] - xy[t]) ** 2).sum(axis=1)
    fraction = len(t) / len(xy)
    coarse = efficient_detector([xy], [electrons], [limit], merge=1.5)
    assert fraction >= coarse["found"] - 3.0 * np.sqrt(fraction * (1.0 - fraction) / len(xy))
    if ppp <= 0.01:  # from 0.02 on synptv resolves fewer close pairs (docs/ptv.md)
        fine = efficient_detector([xy], [electrons], [limit], merge=1.2)
        margin = 3.0 * square.std() / np.sqrt(len(square))
        assert square.mean() <= fine["rms_px"] ** 2 + margin


def test_the_rejecting_oracle_drops_exactly_the_particles_with_a_close_neighbour():
    # Two particles 0.9 px apart, one 1.3 px from the nearer of them, one alone:
    # dropping pairs closer than 1.2 px leaves the last two, closer than 1.5 px the last.
    xy = np.array([[10.0, 10.0], [10.9, 10.0], [12.2, 10.0], [30.0, 30.0]])
    limit = np.array([0.5, 0.5, 0.03, 0.04])
    kept = rejecting_oracle([xy], [limit], merge=1.2)
    assert kept == {"found": 0.5, "rms_px": round(float(np.sqrt((0.03**2 + 0.04**2) / 2)), 4)}
    assert rejecting_oracle([xy], [limit], merge=1.5) == {"found": 0.25, "rms_px": 0.04}
