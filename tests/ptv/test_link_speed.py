"""The link radius from the data: max_speed measured on the links of the smallest Δt, and
the ambiguity of the links named when the radius reaches past the particle spacing.

The particles are a slow laboratory flow's: 1500 in a 100 × 100 × 10 mm sheet (about
2.6 mm to the nearest neighbour), Gaussian velocities of u′ = 0.05 m/s per component
plus a uniform mean flow, and Δt = 1.3–6.3 ms (0.04–0.2 τ_η at ε = 10⁻³ m²/s³).
"""

import logging

import numpy as np
import pytest

from ptv.pipeline.double_frame import (
    AMBIGUITY_WARNING,
    SnapshotMeasurement,
    ambiguity_message,
    run_particles,
)
from ptv.pipeline.link_radii import link_radius
from ptv.pipeline.resolve import settings_with_measured_speed
from ptv.settings import PipelineSettings
from ptv.tracking.link_speed import SPEED_SIGMAS, link_speed, nearest_spacing
from ptv.tracking.linking import link

SHEET = np.array([0.1, 0.1, 0.01])
U_RMS = 0.05
MEAN = np.array([0.02, -0.01, 0.0])
DT = np.array([0.04, 0.08, 0.12, 0.16, 0.2]) * 0.031623
NOISE = 10e-6


def _snapshot(rng, dt, count=1500):
    """Frames a and b of one snapshot (true partner of a[i] is b[i]) and the positions."""
    a = (rng.random((count, 3)) - 0.5) * SHEET
    velocity = MEAN + U_RMS * rng.standard_normal((count, 3))
    b = a + velocity * dt
    return a + NOISE * rng.standard_normal(a.shape), b + NOISE * rng.standard_normal(b.shape)


def test_max_speed_is_measured_as_the_mean_plus_five_rms_of_the_velocity():
    rng = np.random.default_rng(1)
    frames = [_snapshot(rng, DT[0]) for _ in range(5)]
    measured = link_speed(frames, DT[0], position_noise=NOISE)
    # rms of one component of ΔX/Δt: u′ with the noise of two positions over Δt
    rms = np.hypot(U_RMS, np.sqrt(2) * NOISE / DT[0])
    expected = np.linalg.norm(MEAN) + SPEED_SIGMAS * rms
    # the median absolute deviation of n = 7500 Gaussian values has a relative standard
    # error 1.17/√n = 1.4 %; the largest of three components sits about one of those above
    assert measured.max_speed == pytest.approx(expected, rel=3 * 1.17 / np.sqrt(7500) + 0.014)
    assert np.allclose(measured.mean_velocity, MEAN, atol=4 * rms / np.sqrt(7500))
    assert measured.links > 0.95 * 7500
    # the spacing against a brute-force nearest neighbour over every pair of each frame a
    brute = []
    for a, _ in frames:
        distance = np.linalg.norm(a[:, None, :] - a[None, :, :], axis=2)
        np.fill_diagonal(distance, np.inf)
        brute.append(np.median(distance.min(axis=1)))
    assert measured.spacing == pytest.approx(np.median(brute), rel=1e-12)


def test_a_first_radius_that_cuts_the_distribution_grows_until_it_does_not():
    rng = np.random.default_rng(2)
    dt = DT[-1] * 3  # displacements of 0.45 spacing rms: half the spacing cuts them
    frames = [_snapshot(rng, dt, count=300) for _ in range(5)]
    measured = link_speed(frames, dt, position_noise=NOISE)
    assert measured.iterations > 1
    expected = np.linalg.norm(MEAN) + SPEED_SIGMAS * U_RMS
    assert measured.max_speed == pytest.approx(expected, rel=0.1)


def test_too_few_particles_ask_for_max_speed():
    with pytest.raises(ValueError, match=r"set \[linking\] max_speed"):
        link_speed([(np.zeros((1, 3)), np.zeros((1, 3)))], 1e-3, position_noise=NOISE)
    rng = np.random.default_rng(3)
    with pytest.raises(ValueError, match="too few to measure"):
        link_speed([_snapshot(rng, DT[0], count=5)], DT[0], position_noise=NOISE)


def _run(settings, rng):
    """The runs at every Δt of 5 snapshots, linked as the pipeline links them, and the
    fraction of links that join a particle to its own partner."""
    runs, correct = [], []
    for k, dt in enumerate(DT):
        measured = []
        for m in range(5):
            a, b = _snapshot(rng, dt)
            links = link(a, b, radius=link_radius(dt, settings))
            correct.append(np.mean(links.index_a == links.index_b))
            measured.append(
                SnapshotMeasurement(
                    k=k,
                    m=m,
                    detections=np.zeros((2, 1), dtype=np.int64),
                    matches=np.array([len(a), len(b)]),
                    links=len(links),
                    positions=links.positions,
                    displacements=links.displacements,
                    outlier=np.zeros(len(links), dtype=bool),
                    ambiguous=links.ambiguous,
                    spacing=nearest_spacing(a),
                )
            )
        runs.append(run_particles(k, dt, measured, 1, settings))
    return runs, np.array(correct)


def test_the_measured_radius_links_a_slow_flow_without_ambiguity(caplog):
    rng = np.random.default_rng(4)
    settings, measured = settings_with_measured_speed(
        PipelineSettings(position_noise=NOISE),
        [_snapshot(rng, DT[0]) for _ in range(5)],
        0,
        DT[0],
    )
    assert measured.max_speed < 0.4  # about 5 u′ + |U|, not the paper flow's 1.5 m/s
    with caplog.at_level(logging.WARNING):
        runs, correct = _run(settings, rng)
    assert all(run.ambiguity < AMBIGUITY_WARNING for run in runs)
    assert "ambiguous" not in caplog.text
    # Mislinks are no more than the links for which a stranger lies closer than the true
    # partner, n·(4π/3)·⟨|ΔX|³⟩ of them (⟨|ΔX|³⟩ sampled from the same motion), within
    # the Poisson scatter of their count over 5 snapshots.
    density = 1500 / np.prod(SHEET)
    for k, dt in enumerate(DT):
        sample = MEAN * dt + U_RMS * dt * rng.standard_normal((100_000, 3))
        sample += np.sqrt(2) * NOISE * rng.standard_normal(sample.shape)
        expected = 7500 * density * 4 * np.pi / 3 * np.mean(np.linalg.norm(sample, axis=1) ** 3)
        wrong = 7500 * (1 - correct[5 * k : 5 * k + 5].mean())
        assert wrong <= expected + 3 * np.sqrt(expected) + 3, (k, wrong, expected)


def test_a_max_speed_ten_times_too_high_is_warned_about_by_name(caplog):
    rng = np.random.default_rng(5)
    appropriate = np.linalg.norm(MEAN) + SPEED_SIGMAS * U_RMS
    settings = PipelineSettings(max_speed=10 * appropriate, position_noise=NOISE)
    with caplog.at_level(logging.WARNING):
        runs, _ = _run(settings, rng)
    ambiguous = [run for run in runs if run.ambiguity > AMBIGUITY_WARNING]
    assert len(ambiguous) == len(runs), [run.ambiguity for run in runs]  # every Δt named
    for run in ambiguous:
        message = ambiguity_message(run, settings, speed_measured=False)
        assert f"Δt_{run.k} = {run.dt:.4g} s" in message
        assert "max_speed" in message and "was given" in message
        assert message in caplog.text
