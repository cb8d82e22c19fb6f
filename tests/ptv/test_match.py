"""Stereo matching through model-free calibrations, against the simulator's truth."""

import copy
import tomllib
from importlib import resources

import numpy as np
import pytest

from ptv.calibration.model_free import PlaneObservation, calibrate_model_free
from ptv.matching.stereo import DEFAULT_TOLERANCE, Matches, match, match_rays
from ptv.rays import Rays
from ptv.triangulate import closest_points
from simulator.particles import SHEET
from simulator.rigs import load_rig, rig_from_dict
from simulator.target import PlateDesign, build_plate, traverse_positions

DESIGN = PlateDesign()
Z = traverse_positions()
#: The illuminated slab with a margin of about the tolerance.
VOLUME = (
    np.asarray(SHEET.centre) - 0.5 * np.asarray(SHEET.size) - 2e-4,
    np.asarray(SHEET.centre) + 0.5 * np.asarray(SHEET.size) + 2e-4,
)
VOXEL = 1e-4  # a true positive lies within one voxel of its particle


def calibrate(camera, plate):
    obs = []
    for j in range(len(Z)):
        px = camera.project(plate.dot_centres(j))
        ok = np.isfinite(px).all(axis=1)
        obs.append(PlaneObservation(Z[j], px[ok], DESIGN.nominal_xy[ok]))
    return calibrate_model_free(obs, camera.lens.sensor_size)


@pytest.fixture(scope="module")
def rig():
    return load_rig("paper-stereo")


@pytest.fixture(scope="module")
def calibrations(rig):
    plate = build_plate(DESIGN, Z, rng=0)
    return [calibrate(c, plate) for c in rig.cameras]


@pytest.fixture(scope="module")
def rig3():
    """The paper's rig plus a third camera looking down at 30° elevation."""
    spec = tomllib.loads(
        (resources.files("simulator") / "rig_presets" / "paper-stereo.toml").read_text()
    )
    third = copy.deepcopy(spec["cameras"][0])
    third.update(name="cam3", azimuth_deg=0.0, elevation_deg=30.0)
    spec["cameras"].append(third)
    rig = rig_from_dict(spec, source="paper-stereo + cam3")
    plate = build_plate(DESIGN, Z, rng=0)
    return rig, [calibrate(c, plate) for c in rig.cameras]


def detections(cameras, points, rng, *, noise=0.1, drop=0.0):
    """Shuffled noisy detections per camera and the true particle of each."""
    pixels, ids = [], []
    for cam in cameras:
        px = cam.project(points)
        seen = np.flatnonzero(np.isfinite(px).all(axis=1))
        seen = seen[rng.random(len(seen)) >= drop]
        order = rng.permutation(seen)
        pixels.append(px[order] + rng.normal(0.0, noise, (len(order), 2)))
        ids.append(order)
    return pixels, ids


def score(m: Matches, ids, points, *, need=2):
    """Yield over particles seen by ``need`` or more cameras, and the ghost fraction."""
    seen = np.zeros(len(points), dtype=int)
    for i in ids:
        seen[i] += 1
    truth = np.full(m.indices.shape, -1)
    for c, i in enumerate(ids):
        has = m.indices[:, c] >= 0
        truth[has, c] = i[m.indices[has, c]]
    first = truth.max(axis=1)
    consistent = np.all((truth == first[:, None]) | (truth < 0), axis=1)
    near = np.linalg.norm(m.points - points[first], axis=1) < VOXEL
    right = consistent & near
    return right.sum() / np.sum(seen >= need), 1.0 - right.mean()


@pytest.mark.parametrize("n", [1000, 2000])
def test_two_cameras_match_almost_every_particle_with_few_ghosts(rig, calibrations, n):
    rng = np.random.default_rng(n)
    points = SHEET.sample(n, rng)
    pixels, ids = detections(rig.cameras, points, rng)
    m = match(calibrations, pixels, VOLUME)
    yield_, ghosts = score(m, ids, points)
    assert yield_ >= 0.95
    assert ghosts <= 0.05
    assert m.indices.shape == (len(m), 2) and m.ray_distances.shape == (len(m), 2)
    for c in range(2):  # one-to-one
        assert len(np.unique(m.indices[:, c])) == len(m)
    assert np.all(m.ray_distances < DEFAULT_TOLERANCE)
    assert np.all((m.points >= VOLUME[0]) & (m.points <= VOLUME[1]))
    assert m.candidates >= len(m) and np.all(m.ambiguous > 0)


def test_lost_detections_leave_few_ghosts(rig, calibrations):
    # 5 % of the particle images lost in each camera (overlaps, dim particles): their
    # partners must mostly stay unmatched rather than pair with a stranger.
    rng = np.random.default_rng(7)
    points = SHEET.sample(2000, rng)
    pixels, ids = detections(rig.cameras, points, rng, drop=0.05)
    m = match(calibrations, pixels, VOLUME)
    yield_, ghosts = score(m, ids, points)
    assert yield_ >= 0.9
    assert ghosts <= 0.05


def test_points_are_as_accurate_as_triangulation(rig, calibrations):
    rng = np.random.default_rng(3)
    points = SHEET.sample(300, rng)
    pixels, ids = detections(rig.cameras, points, rng, noise=0.05)
    m = match(calibrations, pixels, VOLUME)
    truth = ids[0][m.indices[:, 0]]
    right = truth == ids[1][m.indices[:, 1]]
    assert len(m) == 300 and right.mean() >= 0.99
    err = np.linalg.norm(m.points[right] - points[truth[right]], axis=1)
    assert np.median(err) < 1.5e-5


def test_candidate_pruning_misses_nothing(rig, calibrations):
    # All-pairs brute force on a small set must give exactly the candidates found.
    rng = np.random.default_rng(4)
    points = SHEET.sample(400, rng)
    pixels, _ = detections(rig.cameras, points, rng)
    rays = [cal.pixel_to_ray(p) for cal, p in zip(calibrations, pixels, strict=True)]
    for tol in (DEFAULT_TOLERANCE, 1e-3):
        n1, n2 = len(pixels[0]), len(pixels[1])
        i, j = np.meshgrid(np.arange(n1), np.arange(n2), indexing="ij")
        i, j = i.ravel(), j.ravel()
        tri = closest_points(
            np.stack([rays[0].origins[i], rays[1].origins[j]]),
            np.stack([rays[0].directions[i], rays[1].directions[j]]),
        )
        skew = tri.ray_distances.sum(axis=0)
        inside = np.all((tri.points >= VOLUME[0]) & (tri.points <= VOLUME[1]), axis=1)
        expected = int(np.sum((skew < tol) & inside))
        assert match_rays(rays, VOLUME, tolerance=tol).candidates == expected


def test_third_camera_removes_ghosts(rig3):
    rig, cals = rig3
    rng = np.random.default_rng(5)
    points = SHEET.sample(4000, rng)
    pixels, ids = detections(rig.cameras, points, rng, drop=0.05)
    m3 = match(cals, pixels, VOLUME, min_cameras=3)
    assert np.all((m3.indices >= 0).sum(axis=1) == 3)
    yield3, ghosts3 = score(m3, ids, points, need=3)
    assert yield3 >= 0.97
    assert ghosts3 <= 0.005
    m2 = match(cals[:2], pixels[:2], VOLUME)
    _, ghosts2 = score(m2, ids[:2], points)
    assert ghosts2 > 5 * ghosts3
    # The default accepts pairs as well, which recovers particles that one camera lost,
    # and still matches a particle seen by all three with all three.
    m23 = match(cals, pixels, VOLUME)
    yield23, ghosts23 = score(m23, ids, points, need=2)
    assert len(m23) > len(m3) and yield23 >= 0.97 and ghosts23 <= 0.02
    seen_by_all = set(ids[0]) & set(ids[1]) & set(ids[2])
    triples = m23.indices[(m23.indices >= 0).all(axis=1)]
    particle = [ids[c][triples[:, c]] for c in range(3)]
    true_triples = (particle[0] == particle[1]) & (particle[1] == particle[2])
    assert np.sum(true_triples) >= 0.97 * len(seen_by_all)
    for c in range(3):
        used = m23.indices[:, c][m23.indices[:, c] >= 0]
        assert len(np.unique(used)) == len(used)
    assert np.all(np.isnan(m23.ray_distances) == (m23.indices < 0))


def _parallel_rays(points, direction):
    """Rays along ``direction`` (3,) through ``points`` (N, 3), m, their origins 0.5 m
    back along it: a camera far away."""
    direction = np.asarray(direction, dtype=float) / np.linalg.norm(direction)
    directions = np.tile(direction, (len(points), 1))
    return Rays(points - 0.5 * directions, directions)


@pytest.mark.parametrize("n_cam", [3, 4])
def test_a_particle_missed_by_one_camera_keeps_its_pair_when_a_neighbour_takes_the_ray(n_cam):
    """Camera 2 (and 3) merged particle A's image with its neighbour S's, so its only
    ray there is S's, passing 0.4 tolerance from A. S is seen by every camera; A by the
    others. Extending A's pair with S's ray makes a tuple S's own tuple outbids: A must
    still be matched from the cameras that saw it (enough: n_cam − 1 ≥ min_cameras)."""
    tol = 1.5e-4
    a = np.array([0.004, -0.003, 0.001])
    views = [(-0.6, 0.0, 1.0), (0.6, 0.0, 1.0), (0.0, 0.55, 1.0), (0.0, -0.55, 1.0)][:n_cam]
    hidden = 2  # the camera that lost A
    v = np.asarray(views[hidden]) / np.linalg.norm(views[hidden])
    across = np.cross(v, [1.0, 0.0, 0.0])
    s = a + 2e-3 * v + 0.4 * tol * across / np.linalg.norm(across)  # S's ray in camera 2
    both = np.array([a, s])
    rays = [_parallel_rays(both if c != hidden else s[None], views[c]) for c in range(n_cam)]
    m = match_rays(rays, VOLUME, tolerance=tol, min_cameras=n_cam - 1)
    assert len(m) == 2
    row_a = np.flatnonzero(m.indices[:, 0] == 0)[0]
    expected = [0 if c != hidden else -1 for c in range(n_cam)]
    assert m.indices[row_a].tolist() == expected
    assert np.linalg.norm(m.points[row_a] - a) < 1e-9  # exact rays meet at A
    assert m.indices[1 - row_a].tolist() == [1 if c != hidden else 0 for c in range(n_cam)]


def test_detections_outside_the_calibration_or_nan_are_never_matched(rig, calibrations):
    rng = np.random.default_rng(6)
    points = SHEET.sample(50, rng)
    pixels, ids = detections(rig.cameras, points, rng)
    extra = np.array([[np.nan, 5.0], [2.0, 3.0]])  # NaN; a corner pixel with no dots
    pixels = [np.vstack([extra, pixels[0]]), pixels[1]]
    m = match(calibrations, pixels, VOLUME)
    assert len(m) == 50
    assert m.indices[:, 0].min() >= 2
    assert np.array_equal(ids[0][m.indices[:, 0] - 2], ids[1][m.indices[:, 1]])


def test_empty_detections_give_empty_matches(calibrations):
    some = np.array([[1000.0, 500.0], [1100.0, 600.0]])
    for pixels in ([np.empty((0, 2)), some], [some, np.empty((0, 2))]):
        m = match(calibrations, pixels, VOLUME)
        assert len(m) == 0 and m.indices.shape == (0, 2) and m.points.shape == (0, 3)
        assert m.ambiguous.tolist() == [0, 0] and m.candidates == 0


def test_bad_input_is_a_clear_error(calibrations):
    px = np.array([[1000.0, 500.0]])
    with pytest.raises(ValueError, match="at least two cameras"):
        match(calibrations[:1], [px], VOLUME)
    with pytest.raises(ValueError, match="one pixel array per camera"):
        match(calibrations, [px], VOLUME)
    with pytest.raises(ValueError, match=r"camera 1: pixels must have shape \(N, 2\)"):
        match(calibrations, [px, np.ones((3, 3))], VOLUME)
    with pytest.raises(ValueError, match="lower < upper"):
        match(calibrations, [px, px], (VOLUME[1], VOLUME[0]))
    with pytest.raises(ValueError, match="volume corners must have 3 entries"):
        match(calibrations, [px, px], (np.zeros(2), np.ones(2)))
    with pytest.raises(ValueError, match="tolerance"):
        match(calibrations, [px, px], VOLUME, tolerance=0.0)
    with pytest.raises(ValueError, match="min_cameras"):
        match(calibrations, [px, px], VOLUME, min_cameras=3)
    rays = Rays(np.zeros((2, 3)), np.zeros((3, 3)))
    with pytest.raises(ValueError, match="camera 0: ray origins and directions"):
        match_rays([rays, rays], VOLUME)
    with pytest.raises(ValueError, match="at least two cameras"):
        match_rays([], VOLUME)
