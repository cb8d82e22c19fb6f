"""Dark particles on a structured back-lit background: inverted, background removed,
found where they were drawn."""

import json

import numpy as np
import pytest
import tifffile
from scipy.special import erf

from ptv.detect.frames import ImageDetector
from ptv.detect.preprocess import invert, median_background, tophat
from ptv.io.dataset import open_dataset
from ptv.settings import DetectorSettings

SHAPE = (96, 128)


def _spots(centres, sigma=1.0, amplitude=1.0):
    """Pixel-integrated Gaussian spots of total ``amplitude`` each, shape SHAPE."""
    rows, cols = SHAPE
    image = np.zeros(SHAPE)
    for x, y in centres:
        gx = 0.5 * (
            erf((np.arange(cols) + 0.5 - x) / (np.sqrt(2) * sigma))
            - erf((np.arange(cols) - 0.5 - x) / (np.sqrt(2) * sigma))
        )
        gy = 0.5 * (
            erf((np.arange(rows) + 0.5 - y) / (np.sqrt(2) * sigma))
            - erf((np.arange(rows) - 0.5 - y) / (np.sqrt(2) * sigma))
        )
        image += amplitude * np.outer(gy, gx)
    return image


def _backlit(centres, rng, structured=True, sigma=1.0):
    """A back-lit frame, 12 bits: a bright uneven background (with a dark scratch and a
    bright reflection that never move when ``structured``), particles as shadows of
    Gaussian width ``sigma``, px, read noise."""
    rows, cols = SHAPE
    yy, xx = np.mgrid[:rows, :cols]
    background = 3000.0 + 6.0 * xx - 4.0 * yy - 0.05 * (xx - 64.0) ** 2
    if structured:
        background[40:43, 10:110] -= 900.0  # a scratch on the window
        background += 600.0 * np.exp(-((xx - 100) ** 2 + (yy - 20) ** 2) / 30.0)  # a glint
    image = background - _spots(centres, sigma, 9000.0) + rng.normal(0.0, 6.0, SHAPE)
    return np.clip(np.round(image), 0, 4095).astype(np.uint16)


def _positions(n, frames, seed=5):
    start = np.random.default_rng(seed).uniform([8, 24], [SHAPE[1] - 36, SHAPE[0] - 8], size=(n, 2))
    return [start + f * np.array([1.7, -0.9]) for f in range(frames)]


def test_inverting_makes_the_saturation_level_zero():
    image = np.array([[0, 4095], [1000, 20]], dtype=np.uint16)
    np.testing.assert_array_equal(invert(image, 4095), [[4095, 0], [3095, 4075]])
    assert invert(image).max() == 65535


def test_a_tophat_removes_what_is_wider_than_its_disc_and_keeps_particles():
    rows, cols = SHAPE
    yy, xx = np.mgrid[:rows, :cols]
    smooth = 500.0 + 3.0 * xx + 0.01 * (yy - 40.0) ** 2
    spots = _spots([(30.3, 50.6), (90.2, 20.8)], amplitude=2000.0)
    removed = tophat(smooth + spots, 4)
    assert np.abs(removed - spots)[5:-5, 5:-5].max() < 0.05 * spots.max()


def test_the_temporal_median_of_moving_particles_is_the_background():
    background = np.linspace(100, 900, SHAPE[0] * SHAPE[1]).reshape(SHAPE)
    frames = [background + _spots(p, amplitude=5000.0) for p in _positions(15, 9)]
    # Wherever particles cover a pixel in fewer than half the frames: nearly everywhere.
    assert np.mean(np.abs(median_background(frames) - background) < 1.0) > 0.98
    with pytest.raises(ValueError, match="at least 3 frames"):
        median_background(frames[:2])


def _backlit_dataset(folder, positions, structured=True, sigma=1.0):
    """One camera pair, 2 Δt × 4 frame pairs, frames numbered in time order."""
    spec = {
        "cameras": {c: {"image_size": [SHAPE[1], SHAPE[0]]} for c in ("c1", "c2")},
        "dt": [1e-3, 2e-3],
        "frames_per_dt": 4,
        "bit_depth": 12,
        "particle_images": "img/{camera}/{k}_{m}{a|b}.tif",
    }
    folder.mkdir()
    (folder / "experiment.json").write_text(json.dumps(spec))
    rng = np.random.default_rng(6)
    n = 0
    for k in range(2):
        for m in range(4):
            for f in "ab":
                for c in ("c1", "c2"):
                    path = folder / "img" / c / f"{k}_{m}{f}.tif"
                    path.parent.mkdir(parents=True, exist_ok=True)
                    tifffile.imwrite(path, _backlit(positions[n], rng, structured, sigma))
                n += 1
    return open_dataset(folder)


@pytest.mark.parametrize(
    ("background", "structured"),
    [("median", True), ("tophat", False)],  # a top-hat keeps particle-sized structure
)
def test_dark_particles_are_found_where_they_were_drawn(tmp_path, background, structured):
    positions = _positions(20, 16)
    dataset = _backlit_dataset(tmp_path / "ds", positions, structured)
    settings = DetectorSettings(particles="dark", background=background, tophat_radius=4)
    found = ImageDetector(dataset, settings).detections(1, 2, "b")[0]
    truth = positions[1 * 8 + 2 * 2 + 1]  # frame b of snapshot 2 at Δt_1
    distance = np.linalg.norm(found[:, None, :] - truth[None, :, :], axis=2)
    nearest = distance.min(axis=1)
    # Nothing on the scratch, the glint or the edges: every detection is a particle, or
    # two particles drawn within a spot width, detected as one between them.
    assert np.all(nearest < 2.5)
    assert np.sum(nearest < 0.1) >= 0.9 * len(truth)


def _scattered(n, exposures, gap, seed=7):
    """n positions per exposure, uniform at least ``gap`` px apart and from the edges."""
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < exposures:
        xy = rng.uniform([gap / 2, gap / 2], [SHAPE[1] - gap / 2, SHAPE[0] - gap / 2], (n, 2))
        if np.min(np.linalg.norm(xy[:, None] - xy[None], axis=2) + 1e9 * np.eye(n)) > gap:
            out.append(xy)
    return out


def test_shadows_15_px_across_are_one_detection_each(tmp_path):
    """The issue's back-lit recording: shadows 15 px across (e⁻² diameter, σ 3.75 px),
    about 100 DN deep on 6 DN of read noise, on the structured background, with the
    median of the sequence removed. Given their diameter, each is one detection, and
    nothing else is detected (without it: 88 % are one detection, 0.58 px rms).

    Centres: their Cramér–Rao bound is about 0.07 px (2-D; read noise only), and
    0.075 px rms is measured against the true background; the median of 16 frames keeps
    a trace of every shadow that crossed a pixel (an order-statistic step, ~0.16 σ_n,
    where a shadow is deeper than the noise), as wide as the particles, which moves the
    centres further (measured 0.11–0.14 px over two draws and 3–6 shadows per frame):
    twice the issue's 0.1 px of clean images is allowed."""
    diameter = 15.0
    positions = _scattered(6, 16, gap=1.6 * diameter)
    dataset = _backlit_dataset(tmp_path / "ds", positions, sigma=diameter / 4)
    settings = DetectorSettings(particles="dark", background="median", diameter=diameter)
    detector = ImageDetector(dataset, settings)
    one, errors, extra = [], [], 0
    for n, (k, m, frame) in enumerate((k, m, f) for k in range(2) for m in range(4) for f in "ab"):
        for found in detector.detections(k, m, frame):
            distance = np.linalg.norm(found[:, None, :] - positions[n][None, :, :], axis=2)
            near = distance < diameter / 2
            alone = near.sum(axis=0) == 1
            one.extend(alone)
            errors.extend(found[np.argmax(near[:, alone], axis=0)] - positions[n][alone])
            extra += int(np.sum(~near.any(axis=1)))
    assert np.mean(one) >= 0.95 and extra == 0
    assert np.sqrt(np.mean(np.sum(np.square(errors), axis=1))) <= 0.2


@pytest.mark.parametrize("step_px", [0.0, 0.02])
def test_a_median_of_slow_particles_is_said_to_erase_them(tmp_path, step_px):
    # The particles (4 px across) move 0 or 0.02 px a frame: over the median's frames
    # they never leave their pixels, so the median holds them and the frames lose them.
    start = _positions(20, 1)[0]
    positions = [start + f * step_px * np.array([1.0, -0.5]) for f in range(16)]
    dataset = _backlit_dataset(tmp_path / "ds", positions)
    settings = DetectorSettings(particles="dark", background="median", median_frames=5)
    detector = ImageDetector(dataset, settings)
    detector.detections(0, 2, "a")
    assert [line.split(":")[0] for line in detector.warnings] == ["c1", "c2"]
    assert all("of the 5 frames of the temporal median shows" in line for line in detector.warnings)
    assert "move less than their size" in detector.warnings[0]


def test_a_median_of_moving_particles_says_nothing(tmp_path):
    dataset = _backlit_dataset(tmp_path / "ds", _positions(20, 16))  # 1.9 px a frame
    settings = DetectorSettings(particles="dark", background="median")
    detector = ImageDetector(dataset, settings)
    detector.detections(0, 2, "a")
    assert detector.warnings == []


def test_without_the_options_a_backlit_frame_gives_no_particle(tmp_path):
    positions = _positions(20, 16)
    dataset = _backlit_dataset(tmp_path / "ds", positions)
    found = ImageDetector(dataset).detections(0, 0, "a")[0]
    truth = positions[0]
    distance = np.linalg.norm(found[:, None, :] - truth[None, :, :], axis=2)
    assert not np.any(distance < 1.0)


def test_min_peak_and_min_size_drop_faint_and_small_particles(tmp_path):
    positions = _positions(20, 16)
    dataset = _backlit_dataset(tmp_path / "ds", positions)
    base = DetectorSettings(particles="dark", background="median")
    every = ImageDetector(dataset, base).detect(0, 1, "a")[0]
    strict = DetectorSettings(particles="dark", background="median", min_peak=1e9)
    assert len(every) > 0 and len(ImageDetector(dataset, strict).detect(0, 1, "a")[0]) == 0
    bigger = DetectorSettings(particles="dark", background="median", min_size=int(every.size.max()))
    kept = ImageDetector(dataset, bigger).detect(0, 1, "a")[0]
    assert 0 < len(kept) < len(every) and kept.size.min() >= every.size.max()


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("particles", "grey", "particles must be 'bright' or 'dark'"),
        ("background", "rolling", "background must be one of none, tophat, median"),
        ("tophat_radius", 0, "tophat_radius must be an integer >= 1"),
        ("median_frames", 2, "median_frames must be an integer >= 3"),
        ("min_peak", -1.0, "min_peak must be a number >= 0"),
        ("min_size", 0, "min_size must be an integer >= 1"),
        ("diameter", 0.0, "diameter must be a finite number > 0"),
        ("diameter", "15", "diameter must be a finite number > 0"),
        ("diameter", float("inf"), "diameter must be a finite number > 0"),
    ],
)
def test_bad_detection_options_are_named(field, value, message):
    with pytest.raises(ValueError, match=message):
        DetectorSettings(**{field: value})


def test_a_diameter_wider_than_the_tophat_disc_is_refused():
    with pytest.raises(ValueError, match=r"diameter 15\.0 px is wider than the top-hat's disc"):
        DetectorSettings(background="tophat", tophat_radius=7, diameter=15.0)
    assert DetectorSettings(background="tophat", tophat_radius=8, diameter=15.0).diameter == 15.0


def test_the_detector_record_holds_the_diameter_only_when_given():
    # Without it, the record of a run (detections.json, results.h5) is as before it.
    assert "diameter" not in DetectorSettings().as_dict()
    assert DetectorSettings(diameter=15.0).as_dict()["diameter"] == 15.0
