"""Iterative particle reconstruction (IPR) on a four-camera rig like the LPT Challenge's.

The rig (written here, no preset): four cameras in one plane (XZ) at azimuths −30°,
−10°, +10°, +30°, 0.70 m from the volume's centre, f = 100 mm at f/16, 10 µm pixels,
Scheimpflug mounts focused on Z = 0, no windows (air), 1920 × 1200 px (``--quick``:
960 × 600 px and a volume of half the width and height). The volume is
100 × 50 × 30 mm³ (X × Y × Z, Z the depth): one pixel images about 61 µm (a voxel).
Particle images: diffraction and defocus give σ = 0.61–0.91 px (median 0.68) with
20 µm tracers. Lighting: a Gaussian volume of e⁻² half-width 40 mm centred on Z = 0
(brightness 0.76–1 over the depth), 6000 e⁻ at the centre; default sensor (12 bits,
gain 0.4 DN/e⁻, 8 e⁻ read noise).

Density: N = ppp × the mean over the cameras of the image area onto which the volume
projects (the LPT Challenge's images are filled by its volume), at 0.005, 0.025, 0.05,
0.08, 0.12 and 0.16 particles per pixel. The OTF of each camera is measured on a
separate sparse recording (0.005 ppp), as a laboratory would: per image region from its
isolated particle images (:func:`ptv.reconstruct.measure_otf`), then per region and
depth slab from the particles IPR reconstructs on it (:func:`ptv.reconstruct.refine_otf`,
as Schanz et al. 2013 calibrate the OTF per sub-volume: defocus widens the images away
from Z = 0 and the light volume dims them). IPR runs through the true cameras with the
default :class:`ptv.reconstruct.IPRSettings`.

Scoring, as the LPT Challenge: a reconstructed particle is a true positive when it lies
within one voxel (61 µm) of a true particle on each axis, one to one (minimum-cost
assignment on the candidate pairs); ``found`` = true positives / true particles,
``ghosts`` = unmatched reconstructed / reconstructed; errors are rms over the true
positives, in µm (3-D) and in px (the projected error, rms over the cameras of the 2-D
distance). Time: wall time of ``reconstruct`` (numba compiled beforehand); memory: the
peak traced by ``tracemalloc`` during it (NumPy arrays allocated by Python; arrays made
inside compiled kernels are not traced), and the process's largest resident set so
far (``process_max_rss_mb``, growing over the run).

Run time on the shared 2-core development machine: ``--quick`` (0.005, 0.05, 0.12)
about 10 minutes; the six densities at full size about two hours, most of it at 0.12
and 0.16 particles per pixel (40–60 outer iterations of 0.2–0.3 million particles).
"""

import logging
import resource
import time
import tracemalloc

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from benchmarks.machine import machine
from ptv.reconstruct import IPRSettings, measure_otf, reconstruct, refine_otf
from validation.studies.density import image_area

DENSITIES = (0.005, 0.025, 0.05, 0.08, 0.12, 0.16)
QUICK_DENSITIES = (0.005, 0.05, 0.12)
VOLUME = (0.100, 0.050, 0.030)
SENSOR = (1920, 1200)
SHEET_HALF_WIDTH = 0.040
OTF_PPP = 0.005


def lpt_rig(*, quick: bool = False, f_number: float = 16.0):
    """The four-camera rig of the module docstring and its volume (lower, upper) m."""
    from simulator.rigs import rig_from_dict

    size = (SENSOR[0] // 2, SENSOR[1] // 2) if quick else SENSOR
    volume = (VOLUME[0] / 2, VOLUME[1] / 2, VOLUME[2]) if quick else VOLUME
    cameras = [
        {
            "name": f"cam{i + 1}",
            "azimuth_deg": float(az),
            "distance": 0.70,
            "focal_length": 0.100,
            "f_number": f_number,
            "pixel_pitch": 10e-6,
            "sensor_size": list(size),
            "scheimpflug": True,
        }
        for i, az in enumerate((-30, -10, 10, 30))
    ]
    spec = {
        "name": "lpt-like",
        "description": "four cameras in a plane, LPT-Challenge-like",
        "sheet": {"width": volume[0], "height": volume[1], "thickness": volume[2]},
        "tank": {"kind": "free"},
        "cameras": cameras,
    }
    half = 0.5 * np.asarray(volume)
    return rig_from_dict(spec), (tuple(-half), tuple(half))


def lighting():
    from simulator.render.camera_frames import ParticleLighting
    from simulator.render.spot import LaserSheet

    return ParticleLighting(
        particle_diameter=20e-6,
        sheet=LaserSheet(center=0.0, half_width=SHEET_HALF_WIDTH),
        electrons_at_reference=6000.0,
        cutoff=3.0,
    )


def render(rig, box, n: int, rng: np.random.Generator):
    """Particles uniform in the volume and every camera's recorded frame."""
    from simulator.render.camera_frames import record_particles
    from simulator.render.sensor import Sensor

    lower, upper = (np.asarray(v) for v in box)
    positions = rng.uniform(lower, upper, (n, 3))
    frames = [
        record_particles(cam, positions, lighting=lighting(), sensor=Sensor(), rng=rng)
        for cam in rig.cameras
    ]
    return positions, frames


def score(truth: np.ndarray, found: np.ndarray, voxel: float, cameras) -> dict:
    """One-to-one matching within one voxel on each axis (module docstring)."""
    if len(found) == 0:
        return {"found": 0.0, "ghosts": 0.0, "rms_um": None, "rms_px": None, "reconstructed": 0}
    pairs = cKDTree(found).query_ball_point(truth, voxel, p=np.inf)
    rows = np.repeat(np.arange(len(truth)), [len(p) for p in pairs])
    cols = np.concatenate([np.asarray(p, dtype=np.int64) for p in pairs]) if len(rows) else rows
    matched_t, matched_f = [], []
    if len(rows):
        graph = coo_matrix(
            (np.ones(len(rows)), (rows, len(truth) + cols)),
            shape=(len(truth) + len(found),) * 2,
        )
        _, label = connected_components(graph, directed=False)
        comp = label[rows]
        for k in np.unique(comp):
            sel = comp == k
            r, c = rows[sel], cols[sel]
            ur, ri = np.unique(r, return_inverse=True)
            uc, ci = np.unique(c, return_inverse=True)
            if len(ur) == 1 or len(uc) == 1:
                d = np.linalg.norm(truth[r] - found[c], axis=1)
                best = np.argmin(d)
                matched_t.append(r[best])
                matched_f.append(c[best])
                continue
            cost = np.full((len(ur), len(uc)), 1e6)
            cost[ri, ci] = np.linalg.norm(truth[r] - found[c], axis=1) / voxel
            a, b = linear_sum_assignment(cost)
            ok = cost[a, b] < 1e6
            matched_t.extend(ur[a[ok]])
            matched_f.extend(uc[b[ok]])
    t = np.asarray(matched_t, dtype=np.int64)
    f = np.asarray(matched_f, dtype=np.int64)
    err = found[f] - truth[t]
    px = []
    for cam in cameras:
        d = cam.project(found[f]) - cam.project(truth[t])
        px.append(np.sum(d**2, axis=1))
    px = np.nanmean(np.stack(px), axis=0) if len(t) else np.empty(0)
    return {
        "found": round(len(t) / len(truth), 4),
        "ghosts": round(1 - len(f) / len(found), 4),
        "rms_um": round(float(np.sqrt(np.mean(np.sum(err**2, axis=1)))) * 1e6, 2),
        "rms_px": round(float(np.sqrt(np.mean(px))), 4),
        "reconstructed": len(found),
    }


def measure(rig, box, otfs, ppp: float, area: float, seed: int, settings: IPRSettings) -> dict:
    """Render one snapshot at ``ppp`` and reconstruct it."""
    rng = np.random.default_rng(seed)
    n = round(ppp * area)
    truth, frames = render(rig, box, n, rng)
    images = [f.image for f in frames]
    tracemalloc.start()
    t0 = time.perf_counter()
    result = reconstruct(images, rig.cameras, otfs, box, settings=settings)
    seconds = time.perf_counter() - t0
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    d = result.diagnostics
    row = {
        "ppp": ppp,
        "particles": n,
        **score(truth, result.positions, d.voxel, rig.cameras),
        "seconds": round(seconds, 1),
        "peak_memory_mb": round(peak / 2**20, 1),
        "process_max_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1),
        "iterations": d.iterations,
        "particles_per_iteration": d.particles.tolist(),
        "added_per_iteration": d.added.tolist(),
        "residual_energy": [round(float(e), 4) for e in d.residual_energy],
        "project_points": d.points_projected,
        "project_seconds": round(d.seconds_project, 2),
    }
    logging.getLogger(__name__).info("%s", row)
    return row


def calibrate_otf(rig, box, area: float, *, quick: bool) -> list:
    """OTFs per region and depth slab from a sparse recording (module docstring)."""
    _, sparse = render(rig, box, int(OTF_PPP * area), np.random.default_rng(2))
    images = [f.image for f in sparse]
    flat = measure_otf(images, regions=(2, 3) if quick else (3, 4))
    first = reconstruct(images, rig.cameras, flat, box)
    return refine_otf(images, first.positions, first.xy, flat, depth_slabs=5)


def run(quick: bool, densities: tuple[float, ...] | None = None) -> dict:
    rig, box = lpt_rig(quick=quick)
    rng = np.random.default_rng(1)
    area = image_area(rig.cameras, box, rng=rng)
    otfs = calibrate_otf(rig, box, area, quick=quick)
    settings = IPRSettings()
    # (the kernels were compiled by the calibration's reconstruction)
    rows = [
        measure(rig, box, otfs, ppp, area, 100 + i, settings)
        for i, ppp in enumerate(densities or (QUICK_DENSITIES if quick else DENSITIES))
    ]
    return {
        "machine": machine(),
        "rig": f"4 cameras (-30, -10, 10, 30 deg), {rig.cameras[0].lens.sensor_size} px, "
        f"volume {np.subtract(box[1], box[0]).round(4).tolist()} m",
        "footprint_px": round(area),
        "otf_sigma_x_px_per_depth_slab": [
            np.round(np.median(o.sigma_x, axis=(1, 2)), 3).tolist() for o in otfs
        ],
        "settings": {k: getattr(settings, k) for k in settings.__dataclass_fields__},
        "densities": rows,
    }
