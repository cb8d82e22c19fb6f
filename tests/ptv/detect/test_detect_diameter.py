"""Particle images of any size: given their diameter, the detector works at their scale
(ptv.detect._blocks; docs/ptv.md §1).

Images from ``simulator.render``: pixel-integrated Gaussian spots of e⁻² diameter d
(σ = d/4) recorded by a 12-bit sensor (gain 0.4 DN/e⁻, 8 e⁻ read noise, 5 e⁻ of
background, 10 DN offset). Every spot peaks at about 300 e⁻ (peak SNR ≈ 16, the faint
end of real recordings), where the detector at its own scale (about 3 px) cuts 15 px
spots up (measured without the diameter: 86 % of them one detection, 2-D rms error
0.49 px; at 20 px, 42 % and 0.86 px).

Tolerance of the centres: the Cramér–Rao bound σ_CR of each centre, 2-D
(√(σ_x² + σ_y²)), from the Fisher information Jᵀ·diag(1/σ_p²)·J of what the detector
fits: the sums of b × b pixels (b = ⌊d/3⌋; the pixels below 6 px), J the derivatives
of their expected values with respect to amplitude, x₀, y₀ and σ of every spot and the
background, σ_p² = b²·(read² + background) + signal, e⁻². Summing the pixels raises
the pixels' bound by 8–11 % for a lone spot, 9–13 % for two spots a diameter apart and
17–30 % for two half a diameter apart. An efficient estimator's rms error is σ_CR; as
for the blends (test_detect_blends.py), it may be up to 1.5 σ_CR. Measured over three
draws: 1.03–1.14 σ_CR for lone spots of 2–20 px, all of them one detection (0.054–0.061
px rms; at 15 px, 0.061 px, where the issue asks for 0.1 px); over eight draws of 100
pairs of 10–20 px, 0.90–1.20 σ_CR, and 98–100 % split.
"""

from pathlib import Path

import numpy as np
import pytest
import tifffile
from scipy.spatial import cKDTree
from scipy.special import erf

from ptv.detect import DetectionFlag, _refine, detect_particles, estimate_background
from simulator.render.camera_frames import ParticleLighting, local_magnification, record_particles
from simulator.render.particle_images import render_particles
from simulator.render.sensor import Sensor
from simulator.rigs import load_rig

EXAMPLE = Path(__file__).parents[3] / "examples" / "test-cavity"
GAIN, READ_NOISE, BACKGROUND = 0.4, 8.0, 5.0
SENSOR = Sensor(
    gain=GAIN,
    read_noise=READ_NOISE,
    offset=10.0,
    full_well=10000,
    bit_depth=12,
    background=BACKGROUND,
)
#: Expected photo-electrons on the brightest pixel of a centred spot.
PEAK = 300.0
#: Efficiency asked of the centres: rms error / σ_CR.
EFFICIENCY = 1.5


def electrons(diameter: float) -> float:
    """Photo-electrons of a spot of ``diameter`` px peaking at :data:`PEAK` when centred."""
    return PEAK / erf(0.5 / (np.sqrt(2.0) * diameter / 4.0)) ** 2


def cramer_rao(xy: np.ndarray, diameter: float, block: int = 1) -> np.ndarray:
    """2-D σ_CR of the centres of spots at ``xy`` (K, 2), px, fitted together from the
    sums of ``block`` × ``block`` pixels (1: from the pixels), px: shape (K,)."""
    sigma, n_e = diameter / 4.0, electrons(diameter)
    half = block * (int(5.0 * sigma + np.ptp(xy, axis=0).max()) // block + 2)
    shape = (2 * half + block, 2 * half + block)
    centred = xy - xy.mean(axis=0) + half + 0.5 * (block - 1)
    start = np.concatenate([[n_e, x, y, sigma] for x, y in centred])

    def sums(p: np.ndarray) -> np.ndarray:
        spots = p.reshape(-1, 4)
        image = render_particles(spots[:, 1:3], spots[:, 3], spots[:, 0], shape=shape).image
        n = shape[0] // block
        return image.reshape(n, block, n, block).sum(axis=(1, 3)).ravel()

    columns = []
    for i in range(start.size):
        step = np.zeros(start.size)
        step[i] = 1e-3 * n_e if i % 4 == 0 else 1e-4
        columns.append((sums(start + step) - sums(start - step)) / (2.0 * step[i]))
    jac = np.column_stack((*columns, np.ones(columns[0].size)))
    variance = block**2 * (READ_NOISE**2 + BACKGROUND) + sums(start)
    inverse = np.linalg.inv(jac.T @ (jac / variance[:, None]))
    centre = np.diag(inverse)[:-1].reshape(-1, 4)
    return np.sqrt(centre[:, 1] + centre[:, 2])


def block(diameter: float) -> int:
    """Pixels per side of the blocks the detector sums for ``diameter`` (docs/ptv.md §1:
    ⌊diameter / 3⌋, at least 1)."""
    return max(1, int(diameter // 3))


def grid_frame(diameter: float, offsets: np.ndarray, seed: int):
    """A recorded frame of spots of ``diameter`` px: around each of N sites of a grid 4
    diameters apart (at least 16 px), moved by a uniform sub-pixel shift, K spots at
    ``offsets`` (N, K, 2), px. Returns the true centres (N·K, 2) and the frame, DN."""
    rng = np.random.default_rng(seed)
    pitch = max(16, int(4 * diameter))
    site = np.arange(len(offsets))
    origin = np.column_stack((site % 10, site // 10)) * float(pitch) + pitch
    xy = (origin + rng.uniform(0.0, 1.0, (len(site), 2)))[:, None, :] + offsets
    xy = xy.reshape(-1, 2)
    shape = (int(xy[:, 1].max()) + pitch, int(xy[:, 0].max()) + pitch)
    image = render_particles(xy, diameter / 4.0, electrons(diameter), shape=shape).image
    return xy, SENSOR.record(image, rng)


@pytest.mark.parametrize("diameter", [2.0, 5.0, 10.0, 15.0, 20.0])
def test_a_spot_of_any_size_is_one_detection_near_the_cramer_rao_bound(diameter):
    truth, frame = grid_frame(diameter, np.zeros((100, 1, 2)), seed=int(10 * diameter))
    found = detect_particles(frame, diameter=diameter)
    near = cKDTree(found.xy).query_ball_point(truth, max(1.0, diameter / 2))
    one = np.array([len(k) == 1 for k in near])
    assert one.mean() >= 0.95 and len(found) == sum(len(k) for k in near)  # nothing else
    error = np.array([found.xy[k[0]] - t for k, t in zip(near, truth, strict=True) if len(k) == 1])
    rms = np.sqrt(np.mean(np.sum(error**2, axis=1)))
    assert rms <= EFFICIENCY * cramer_rao(np.zeros((1, 2)), diameter, block(diameter))[0]
    if diameter == 15.0:  # the figure: 2 σ_CR of the pixels
        assert rms <= 0.1


def test_block_sums_leave_no_sub_pixel_bias():
    """Noise-free 15 px spots at 36 positions across a block of 5 px: the sum of
    pixel-integrated Gaussians over a block is the Gaussian integrated over the block,
    the model the refinement fits, so the centres are exact up to its convergence test
    (_refine._TOLERANCE, in blocks here)."""
    diameter = 15.0
    phases = np.stack(np.meshgrid(*2 * [np.arange(6) * block(diameter) / 6]), -1)
    truth, frame = grid_frame(diameter, phases.reshape(-1, 1, 2), seed=0)
    image = render_particles(truth, diameter / 4, electrons(diameter), shape=frame.shape).image
    found = detect_particles(image + 20.0, diameter=diameter)
    distance, _ = cKDTree(found.xy).query(truth)
    assert len(found) == len(truth)
    assert distance.max() <= block(diameter) * _refine._TOLERANCE


def test_a_background_estimated_on_the_pixels_serves_the_blocks():
    """The estimate of the pixels, given (as after a top-hat), becomes that of the block
    sums (level × b², noise × b): the same detections, and centres the same up to the
    fits' convergence test, since the fits refit the background."""
    truth, frame = grid_frame(15.0, np.zeros((30, 1, 2)), seed=3)
    own = detect_particles(frame, diameter=15.0)
    given = detect_particles(frame, diameter=15.0, background=estimate_background(frame))
    assert len(own) == len(given) == len(truth)
    assert np.abs(own.xy - given.xy).max() <= block(15.0) * _refine._TOLERANCE


def test_peaks_and_flags_of_large_particles_are_those_of_their_pixels():
    """A faint, a saturated (at the sensor's full well, 4010 DN) and a border-cut 15 px
    spot: the peak is the brightest pixel above the background, within the noise of the
    brightest of the b² pixels around the centre (4 σ_p); the saturated one is flagged
    and centred within its saturated core (a symmetric spot's centre lies in it); the
    cut one is flagged EDGE."""
    xy = np.array([[40.3, 40.7], [120.6, 41.2], [203.1, 40.2]])
    sigma, n_e = 15.0 / 4, np.array([1e5, 2e6, 1e5])
    rendered = render_particles(xy, sigma, n_e, shape=(117, 206)).image
    frame = SENSOR.record(rendered, np.random.default_rng(4))
    found = detect_particles(frame, diameter=15.0, saturation=4000)
    assert len(found) == 3
    order = np.argsort(found.xy[:, 0])
    faint, saturated, cut = (found.select([i]) for i in order)
    expected = GAIN * rendered[:, :80].max()
    assert abs(faint.peak[0] - expected) < 4 * GAIN * np.sqrt(
        READ_NOISE**2 + BACKGROUND + expected / GAIN
    )
    assert faint.flags[0] == 0
    assert saturated.has(DetectionFlag.SATURATED)[0]
    core = np.argwhere(frame >= 4000)[:, ::-1]
    assert np.all((saturated.xy[0] >= core.min(axis=0)) & (saturated.xy[0] <= core.max(axis=0)))
    assert cut.has(DetectionFlag.EDGE)[0]


def split_pairs(diameter: float, separation: float, seed: int):
    """100 pairs of spots ``separation`` px apart at random angles: for each pair found
    as two detections, each within a quarter diameter (at least 1 px) of its own, the
    errors; and the share of pairs so found."""
    rng = np.random.default_rng(seed)
    angle = rng.uniform(0.0, np.pi, 100)
    half = 0.5 * separation * np.column_stack((np.cos(angle), np.sin(angle)))
    truth, frame = grid_frame(diameter, np.stack((-half, half), axis=1), seed)
    pairs = truth.reshape(-1, 2, 2)
    found = detect_particles(frame, diameter=diameter).xy
    reach = max(1.0, diameter / 4)
    errors = []
    centres = pairs.mean(axis=1)
    nearby = cKDTree(found).query_ball_point(centres, 0.5 * separation + reach)
    for pair, near in zip(pairs, nearby, strict=True):
        if len(near) != 2:
            continue
        xy = found[near]
        if np.abs(xy[::-1] - pair).sum() < np.abs(xy - pair).sum():
            xy = xy[::-1]
        if np.hypot(*(xy - pair).T).max() <= reach:
            errors.append(xy - pair)
    return np.reshape(errors, (-1, 2)), len(errors) / len(pairs)


@pytest.mark.parametrize("overlap", [0.5, 1.0])
@pytest.mark.parametrize("diameter", [10.0, 15.0, 20.0])
def test_two_large_spots_a_diameter_or_half_of_one_apart_are_split(diameter, overlap):
    separation = overlap * diameter
    errors, split = split_pairs(diameter, separation, seed=int(diameter + 10 * overlap))
    assert split >= 0.95
    bound = cramer_rao(np.array([[0.0, 0.0], [separation, 0.0]]), diameter, block(diameter))[0]
    assert np.sqrt(np.mean(np.sum(errors**2, axis=1))) <= EFFICIENCY * bound


def test_a_large_particle_of_a_real_recording_is_one_detection():
    """examples/test-cavity, cam1, frame 10000: a particle image with a saturated core of
    6 × 6 px (255 DN; columns 693–698, rows 485–490) in a dimmer halo about 15 px
    across. At the detector's own scale (with the example's settings, 6σ and 4 px or
    more) the halo is cut up: 2 detections within 10 px of the core, 5 within 15 px.
    Given a diameter of 15 px (or 9–20 px), it is one detection, on its core (a
    saturated core holds the centre of the light)."""
    image = tifffile.imread(EXAMPLE / "img_1" / "cam1.10000.tif")
    found = detect_particles(image, threshold_sigmas=6.0, min_size=4, diameter=15.0)
    near = found.xy[np.hypot(*(found.xy - [695.5, 487.5]).T) < 10.0]
    assert len(near) == 1
    assert np.all((near[0] >= [693, 485]) & (near[0] <= [698, 490]))


def test_15_px_tracers_seen_by_a_rig_camera_are_found_once_each():
    """The issue's figure on an image rendered as datasets are (``synptv render``, a
    scenario's ``[particles] diameter``): the paper-stereo rig's first camera (0.1 mm per
    pixel, Scheimpflug) sees tracers 1.5 mm across, 6 mm apart in X and Y, within 4 mm
    of the centre of a 1 cm sheet: images of 14.7–15.4 px (geometry, diffraction and
    defocus) that peak at 300–1200 e⁻. Of those at least a diameter from any other (the
    depth brings some closer; blends are the other tests'), at least 95 % are one
    detection each, with a 2-D rms error within 0.1 px (their Cramér–Rao bound is
    0.025–0.05 px; measured over eight draws: 99–100 % and 0.031–0.037 px, against
    98–100 % and 0.30–0.44 px without the diameter)."""
    camera = load_rig("paper-stereo").cameras[0]
    rng = np.random.default_rng(8)
    grid = np.stack(np.meshgrid(np.arange(-7, 8), np.arange(-5, 6)), -1).reshape(-1, 2)
    xy = grid * 6e-3 + rng.uniform(-1e-3, 1e-3, grid.shape)
    positions = np.column_stack((xy, rng.uniform(-4e-3, 4e-3, len(xy))))
    pixel = camera.lens.pixel_pitch / local_magnification(camera, np.zeros((1, 3)))[0]
    lighting = ParticleLighting(particle_diameter=15 * pixel, electrons_at_reference=1e5)
    frame = record_particles(camera, positions, lighting=lighting, sensor=SENSOR, rng=rng)
    truth = frame.xy[frame.visible]
    assert np.all(np.abs(4 * frame.sigma[frame.visible] - 15.0) < 0.5)
    isolated = truth[cKDTree(truth).query(truth, k=2)[0][:, 1] >= 15.0]
    found = detect_particles(frame.image, diameter=15.0, saturation=4000)
    near = cKDTree(found.xy).query_ball_point(isolated, 7.5)
    one = np.array([len(k) == 1 for k in near])
    assert len(isolated) > 100 and one.mean() >= 0.95
    error = np.array(
        [found.xy[k[0]] - t for k, t in zip(near, isolated, strict=True) if len(k) == 1]
    )
    assert np.sqrt(np.mean(np.sum(error**2, axis=1))) <= 0.1
