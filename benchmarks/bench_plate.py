"""Plate image 2048 × 1088, 4 × 4 supersampling, through an oblique window (target ≤ 3 s).

Rig (as ``bench_optics``): f = 50 mm, 5.5 µm pixels, mild distortion, camera 35° off
the Z axis at 0.9 m, 15 mm PMMA window 10° oblique about a diagonal, 0.3 m of water,
Scheimpflug tilt on the sheet Z = 0. Plate: the default design (21 × 21 dots, 5 mm
pitch) with the ``REALISTIC`` imperfections, 13 traverse planes 1 mm apart. Times are
per image (``render_plate``, expected electrons, no sensor), after a warm-up call
(numba compilation not counted), best and median over the planes rendered.
"""

import time

import numpy as np

from simulator.optics.lens import Lens
from simulator.optics.placement import WindowSpec, look_at_camera
from simulator.optics.scheimpflug import focus_on_plane
from simulator.render.plate import render_plate
from simulator.target import REALISTIC, PlateDesign, build_plate, traverse_positions

TARGET_S = 3.0


def _camera():
    lens = Lens(0.05, 5.5e-6, k1=-0.08, k2=0.3, p1=2e-4, p2=-1e-4, f_number=8.0)
    window = WindowSpec(0.3, 0.015, np.radians(10.0), np.pi / 4)
    camera = look_at_camera([0.0, 0.0, 0.0], lens, distance=0.9, azimuth=np.radians(35.0),
                            window=window)
    return focus_on_plane(camera)


def run(quick: bool) -> dict:
    camera = _camera()
    plate = build_plate(PlateDesign(), traverse_positions(), imperfections=REALISTIC, rng=0)
    planes = [6] if quick else [0, 3, 6, 9, 12]
    render_plate(plate, camera, planes[0])  # warm-up: numba compilation
    times = []
    for plane in planes:
        start = time.perf_counter()
        result = render_plate(plate, camera, plane)
        times.append(time.perf_counter() - start)
    start = time.perf_counter()
    render_plate(plate, camera, planes[-1], defocus=True)
    t_defocus = time.perf_counter() - start
    rows, cols = result.shape
    return {
        "image": f"{cols}x{rows}",
        "supersampling": "4x4",
        "seconds_per_image_best": round(min(times), 3),
        "seconds_per_image_median": round(float(np.median(times)), 3),
        "target_s": TARGET_S,
        "seconds_with_defocus": round(t_defocus, 3),
        "planes_timed": len(times),
        "supersampled_pixel_fraction": round(result.supersampled_pixels / (rows * cols), 4),
        "dots_lit": int(result.visible.sum()),
        "dots_on_sensor": int(result.on_sensor.sum()),
        "bias_px_median": round(float(np.median(np.linalg.norm(
            result.bias[result.on_sensor], axis=1))), 4),
    }
