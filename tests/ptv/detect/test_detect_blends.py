"""Blended particle images split by the model test (ptv.detect, docs/ptv.md §1).

The images are made here, independently of :mod:`simulator` and of :mod:`ptv`: each
particle is a pixel-integrated Gaussian spot (erf differences), recorded with Poisson
shot noise on signal plus 5 e⁻ of background, 8 e⁻ rms of read noise, a gain of
0.4 DN/e⁻, an offset of 10 DN and rounding to a 12-bit uint16.

Tolerance of the split centres: the Cramér–Rao bound σ_CR of each coordinate, from the
Fisher information of the pair alone, Jᵀ·diag(1/σ_p²)·J (J: derivatives of the pixels'
expected DN with respect to the 9 parameters A, x₀, y₀, σ of each spot and the
background, by central differences; σ_p² = gain²·(read² + background) + gain·signal).
An efficient estimator has errors of about σ_CR: the rms of error/σ_CR over the pairs
must stay below 1.5 and no error may exceed 5 σ_CR (6 at 1.2 px). Measured over five
other seeds per case: rms 0.85–1.18, largest 5.4 σ_CR (1.2 px apart, 1 : 0.5), at most
one pair in 60 not split, at most one single spot in 60 split.
"""

import numpy as np
import pytest
from scipy.spatial import cKDTree
from scipy.special import erf

from ptv.detect import DetectionFlag, detect_particles, locate

GAIN, READ_NOISE, BACKGROUND, OFFSET = 0.4, 8.0, 5.0, 10.0
SIGMA = 0.8
ELECTRONS = 4000.0
#: Stated false-split rate (locate's module docstring): below 10⁻³ per isolated spot.
FALSE_SPLIT_RATE = 1e-3


def _masses(first: np.ndarray, centre: float, sigma: float) -> np.ndarray:
    """Share of a unit Gaussian (width σ, px) falling on pixels ``first`` … (integers)."""
    root2s = np.sqrt(2.0) * sigma
    return 0.5 * (erf((first + 0.5 - centre) / root2s) - erf((first - 0.5 - centre) / root2s))


def render(xy: np.ndarray, sigma: np.ndarray, electrons: np.ndarray, shape: tuple) -> np.ndarray:
    """Expected photo-electrons per pixel, (H, W), of spots at ``xy`` (N, 2), px."""
    image = np.zeros(shape)
    for (x, y), s, e in zip(xy, sigma, electrons, strict=True):
        cols = np.arange(round(x) - 5, round(x) + 6)
        rows = np.arange(round(y) - 5, round(y) + 6)
        image[np.ix_(rows, cols)] += e * np.outer(_masses(rows, y, s), _masses(cols, x, s))
    return image


def record(electrons: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A 12-bit frame: shot noise, read noise, gain, offset, rounding; uint16 DN."""
    counts = rng.poisson(electrons + BACKGROUND) + rng.normal(0.0, READ_NOISE, electrons.shape)
    return np.clip(np.rint(GAIN * counts + OFFSET), 0, 4095).astype(np.uint16)


def cramer_rao(pair: np.ndarray, electrons: np.ndarray) -> np.ndarray:
    """σ_CR of x₀, y₀ of both spots of ``pair`` (2, 2), px: shape (2, 2)."""
    shape = (24, 24)
    shift = np.array([12.0, 12.0]) - pair.mean(axis=0)
    start = np.concatenate([[e, *xy, SIGMA] for e, xy in zip(electrons, pair + shift, strict=True)])

    def pixels(p: np.ndarray) -> np.ndarray:
        spots = p.reshape(2, 4)
        return GAIN * render(spots[:, 1:3], spots[:, 3], spots[:, 0], shape).ravel()

    columns = []
    for i in range(8):
        h = 1e-3 * start[i] if i % 4 == 0 else 1e-4
        step = np.zeros(8)
        step[i] = h
        columns.append((pixels(start + step) - pixels(start - step)) / (2.0 * h))
    jac = np.column_stack((*columns, np.ones(shape[0] * shape[1])))
    variance = GAIN**2 * (READ_NOISE**2 + BACKGROUND) + GAIN * pixels(start)
    fisher = jac.T @ (jac / variance[:, None])
    return np.sqrt(np.diag(np.linalg.inv(fisher))[[1, 2, 5, 6]]).reshape(2, 2)


def pairs_and_singles(separation: float, ratio: float, seed: int):
    """60 pairs ``separation`` px apart at random angles (brightness 1 : ratio) and 60
    single spots, on a grid 16 px apart: the pairs (60, 2, 2), the singles and the frame."""
    rng = np.random.default_rng(seed)
    site = np.arange(120)
    centre = np.column_stack((site % 12, site // 12)) * 16.0 + 10.0 + rng.uniform(0, 1, (120, 2))
    angle = rng.uniform(0.0, np.pi, 60)
    half = 0.5 * separation * np.column_stack((np.cos(angle), np.sin(angle)))
    pairs = np.stack((centre[:60] - half, centre[:60] + half), axis=1)
    singles = centre[60:]
    xy = np.concatenate((pairs.reshape(-1, 2), singles))
    electrons = np.concatenate(
        (np.tile([ELECTRONS, ratio * ELECTRONS], 60), np.full(60, ELECTRONS))
    )
    shape = (int(xy[:, 1].max()) + 11, int(xy[:, 0].max()) + 11)
    frame = record(render(xy, np.full(len(xy), SIGMA), electrons, shape), rng)
    return pairs, singles, frame


@pytest.mark.parametrize("ratio", [1.0, 0.5])
@pytest.mark.parametrize("separation", [1.2, 1.5, 1.8])
def test_unresolved_pairs_are_split_into_their_two_particles(separation, ratio):
    pairs, singles, frame = pairs_and_singles(separation, ratio, seed=int(100 * separation))
    det = detect_particles(frame)
    tree = cKDTree(det.xy)
    # The single spots stay one detection each, clean (at the stated false-split rate,
    # below 10⁻³, one in 60 split is already unlikely: measured, 2 in 1800).
    near_single = tree.query_ball_point(singles, 2.5)
    assert min(len(k) for k in near_single) == 1
    alone = [k[0] for k in near_single if len(k) == 1]
    assert len(alone) >= len(singles) - 1
    assert not det.has(DetectionFlag.OVERLAP)[alone].any()
    z, split = [], 0
    for pair in pairs:
        near = tree.query_ball_point(pair.mean(axis=0), separation / 2 + 2.0)
        if len(near) != 2:
            continue
        found = det.xy[near]
        if np.abs(found[::-1] - pair).sum() < np.abs(found - pair).sum():
            found = found[::-1]
        if np.hypot(*(found - pair).T).max() > 1.0:
            continue
        split += 1
        assert det.has(DetectionFlag.OVERLAP)[near].all()
        assert not det.has(DetectionFlag.ELONGATED)[near].any()
        # σ_CR of each coordinate depends on the pair's angle.
        z.append((found - pair) / cramer_rao(pair, np.array([ELECTRONS, ratio * ELECTRONS])))
    assert split >= 57  # 95 % of the pairs (the power measured: 59–60 of 60)
    z = np.array(z)
    assert np.sqrt(np.mean(z**2)) < 1.5
    assert np.abs(z).max() < (6.0 if separation < 1.5 else 5.0)


def test_noise_elongated_single_spots_are_not_split():
    """Faint, wide single spots, far apart, over 30 noise seeds: about 2 % look elongated
    (the detector flags them ELONGATED and tries a split); the split is refused for
    almost all (measured over 150 seeds: 10 of 1022 split), and the extra detections
    stay within the stated false-split rate (measured: 25 in 60000 spots)."""
    spots = extra = elongated = 0
    for seed in range(30):
        rng = np.random.default_rng(seed)
        grid = np.arange(20) * 14.0 + 10.0
        xy = np.stack(np.meshgrid(grid, grid), axis=-1).reshape(-1, 2)
        xy += rng.uniform(0, 1, xy.shape)
        sigma = rng.uniform(0.85, 1.0, len(xy))
        electrons = np.exp(rng.uniform(np.log(800.0), np.log(2000.0), len(xy)))
        frame = record(render(xy, sigma, electrons, (292, 292)), rng)
        det = detect_particles(frame)
        near = cKDTree(det.xy).query_ball_point(xy, 3.0)
        assert all(len(k) >= 1 for k in near)  # every spot found
        spots += len(xy)
        extra += sum(len(k) - 1 for k in near)
        elongated += int(det.has(DetectionFlag.ELONGATED).sum())
    assert elongated >= 0.01 * spots  # kept as one particle, the flag kept
    # Poisson with mean ≤ 12 (10⁻³ × 12000): above 24 with probability < 10⁻³.
    assert extra <= 2 * FALSE_SPLIT_RATE * spots


def test_a_particle_split_off_twice_is_kept_once():
    """The split stage tries neighbouring groups side by side, so two of them can each
    split off a spot for one hidden particle, or put one on a detection: closer than
    MIN_SEPARATION, spots are one particle. Two new ones become one at their mean, one
    on a detection is dropped, and a detection moved onto another is put back."""
    fitted = np.array([[900.0, 10.0, 10.0, 0.8], [900.0, 20.0, 10.0, 0.8]])
    spots = fitted.copy()
    spots[1, 1:3] = [10.3, 10.2]  # moved by the split stage onto the first
    new = np.array([[15.0, 10.0], [15.4, 10.2], [20.5, 10.0], [30.0, 30.0]])
    kept = locate._undouble(spots, fitted, new)
    np.testing.assert_array_equal(spots, fitted)
    np.testing.assert_allclose(kept[0], [15.2, 10.1])
    assert np.isnan(kept[1:3]).all()
    np.testing.assert_array_equal(kept[3], new[3])
    np.testing.assert_array_equal(new[1], [15.4, 10.2])  # the caller's array is untouched
