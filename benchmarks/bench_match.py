"""Stereo matching speed: 2000 detections per camera, the paper's two-camera rig.

Target (docs/performance.md): ≤ 50 ms for 2000 particles per camera. Set-up: model-free
calibrations of the two ``paper-stereo`` cameras from exact dot projections; 2000
particles uniform in the 100 × 100 × 10 mm sheet, projected by the true cameras with
0.1 px detection noise, shuffled per camera. ``match_rays_ms`` times the matching
itself from the rays (candidate search, skew distances, assignment);
``pixel_to_ray_ms`` is the calibration's own cost of turning both cameras' pixels into
rays, and ``match_ms`` the whole ``ptv.matching.stereo.match`` call (both together). Best and
median over the repeats, after a warm-up call. Yield and ghost fraction are given
against the truth (a true positive pairs the right detections and lies within 0.1 mm
of its particle).
"""

import time

import numpy as np

from ptv.calibration.model_free import PlaneObservation, calibrate_model_free
from ptv.matching.stereo import match, match_rays
from simulator.particles import SHEET
from simulator.rigs import load_rig
from simulator.target import PlateDesign, build_plate, traverse_positions

TARGET_MS = 50.0
PARTICLES = 2000


def _calibrations(rig):
    design, z = PlateDesign(), traverse_positions()
    plate = build_plate(design, z, rng=0)
    cals = []
    for cam in rig.cameras:
        obs = []
        for j in range(len(z)):
            px = cam.project(plate.dot_centres(j))
            ok = np.isfinite(px).all(axis=1)
            obs.append(PlaneObservation(z[j], px[ok], design.nominal_xy[ok]))
        cals.append(calibrate_model_free(obs, cam.lens.sensor_size))
    return cals


def _times(fn, repeats):
    fn()
    out = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        out.append(time.perf_counter() - start)
    return 1e3 * min(out), 1e3 * float(np.median(out))


def run(quick: bool) -> dict:
    """Time matching of 2000 detections per camera; report yield and ghosts."""
    rig = load_rig("paper-stereo")
    cals = _calibrations(rig)
    rng = np.random.default_rng(0)
    points = SHEET.sample(PARTICLES, rng)
    pixels, ids = [], []
    for cam in rig.cameras:
        px = cam.project(points)
        order = rng.permutation(np.flatnonzero(np.isfinite(px).all(axis=1)))
        pixels.append(px[order] + rng.normal(0.0, 0.1, (len(order), 2)))
        ids.append(order)
    half = 0.5 * np.asarray(SHEET.size) + 2e-4
    volume = (np.asarray(SHEET.centre) - half, np.asarray(SHEET.centre) + half)
    rays = [cal.pixel_to_ray(p) for cal, p in zip(cals, pixels, strict=True)]
    repeats = 5 if quick else 20

    core = _times(lambda: match_rays(rays, volume), repeats)
    to_rays = _times(
        lambda: [cal.pixel_to_ray(p) for cal, p in zip(cals, pixels, strict=True)], repeats
    )
    whole = _times(lambda: match(cals, pixels, volume), repeats)

    m = match_rays(rays, volume)
    a, b = ids[0][m.indices[:, 0]], ids[1][m.indices[:, 1]]
    right = (a == b) & (np.linalg.norm(m.points - points[a], axis=1) < 1e-4)
    seen_both = len(np.intersect1d(ids[0], ids[1]))
    return {
        "detections_per_camera": [len(p) for p in pixels],
        "match_rays_ms_best": core[0],
        "match_rays_ms_median": core[1],
        "pixel_to_ray_ms_best": to_rays[0],
        "match_ms_best": whole[0],
        "match_ms_median": whole[1],
        "target_ms": TARGET_MS,
        "candidates": int(m.candidates),
        "matches": len(m),
        "yield": float(right.sum() / seen_both),
        "ghost_fraction": float(1.0 - right.mean()),
    }
