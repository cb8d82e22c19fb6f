"""A dense volumetric case for the claims on iterative particle reconstruction (#55, #56).

``lpt-challenge-small`` (four cameras at −30°, −10°, +10°, +30° behind a glass wall,
512 × 512 px, a voxel of 60 µm, f/16) records :data:`PARTICLES` tracers of
:data:`DIAMETER` uniform in its 20 × 25 × 30 mm volume, lit uniformly through its depth
(its rig file's top-hat sheet and aperture, :func:`simulator.render.camera_frames.
rig_lighting`), with the default sensor: about 0.05 particles per pixel on every
camera. The seeding is polydisperse, as a laboratory's is: each tracer scatters a
brightness drawn uniformly from :data:`BRIGHTNESS` times :data:`ELECTRONS` (diameters of
about 14–24 µm), so that IPR must keep the faint real particles while it removes the
faint ghosts. The stack then does what ``synptv run`` does on such images:
the OTF of each camera measured on snapshot 0 by the run's own function
(:func:`ptv.pipeline.reconstructed.measure_run_otf`: from the isolated particle images,
then per depth slab from the particles reconstructed there); then every snapshot is
reconstructed with that OTF through the rig's true cameras and the default
:class:`ptv.reconstruct.IPRSettings`.

Apart from the stack:

- **the OTF's specification**: each particle's σ = d_τ/4 from the optics
  (:func:`validation.truth.spot_spec.specified_spots`, written apart from the renderer);
  per camera and slab, the median σ of the lit particles whose image is isolated as the
  stack isolates them (no other lit particle's image within :data:`ISOLATION_PX`), the
  population the OTF's median samples;
- **the spread of the fitted images**: the same isolated images fitted one by one with a
  pixel-integrated Gaussian on the stack's 7 × 7 window by
  :func:`validation.truth.spot_fit.fit_spots` (not the stack's fitter); their robust
  standard deviation per cell sets the standard error of the OTF's median of n fitted
  images, 1.2533 s/√n;
- **the defocus law's reference**: the middle depth slab's specified median σ, against
  which the stack's :func:`ptv.reconstruct.defocus_law` fitted to the outer slabs'
  isolated images (fitted as above) is compared; its standard error and what the law
  itself misses on this rig (the same law fitted to the outer slabs' specified σ) from
  a plain least-squares fit written here;
- **the reconstruction's score**, as the LPT Challenge's: points paired one to one with
  the true particles within one voxel (:func:`validation.truth.matching.assign_one_to_one`),
  ``found`` over the lit particles imaged on every sensor, ``ghosts`` the unpaired points,
  the projected error through the true cameras against each particle's exact image.
"""

import time
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ptv.pipeline.reconstructed import measure_run_otf
from ptv.reconstruct import IPRSettings, defocus_law, reconstruct
from simulator.render.camera_frames import ParticleLighting, record_particles, rig_lighting
from simulator.render.sensor import Sensor
from simulator.rigs import load_rig
from validation.truth.matching import assign_one_to_one
from validation.truth.spot_fit import fit_spots
from validation.truth.spot_spec import specified_spots

#: The rig.
RIG = "lpt-challenge-small"
#: Tracers in the volume: about 0.05 particles per pixel of the volume's image on each
#: camera (it covers about 1.9·10⁵ px of a sensor; 0.035 per sensor pixel).
PARTICLES = 9300
#: Tracer diameter, m (their images are set by diffraction: σ ≈ 0.6–0.8 px).
DIAMETER = 20e-6
#: Photo-electrons per tracer of :data:`DIAMETER`, e⁻ (the whole volume lit alike).
ELECTRONS = 6000.0
#: Range of each tracer's brightness relative to :data:`ELECTRONS` (uniform): the
#: faintest real particle is half the typical one, above IPR's ghost threshold (0.35)
#: by a margin and below twice it.
BRIGHTNESS = (0.5, 1.5)
#: A particle image is isolated when no other lit particle's image is this close, px (the
#: stack's ``isolation``).
ISOLATION_PX = 5.0
#: Half-width of the fitted window, px (the stack's ``window``).
HALF_WINDOW = 3
#: A median's standard error per robust standard deviation, times √n (normal law).
MEDIAN_EFFICIENCY = 1.2533
#: Gaussian σ per median absolute deviation.
MAD_TO_SIGMA = 1.4826


@dataclass(frozen=True)
class IprScores:
    """The dense case's OTF and reconstruction against the truth.

    Attributes
    ----------
    otf_sigma : ndarray, shape (C, S, 2)
        The measured OTF's σ_x and σ_y per camera and depth slab, px.
    otf_counts : ndarray of int, shape (C, S)
        The fitted images each cell's median was taken over.
    slab_centres : ndarray, shape (C, S)
        Each slab's centre, world Z, m.
    specified_sigma : ndarray, shape (C, S)
        Median specified σ of the lit particles in the slab whose images are isolated, px.
    fitted_spread : ndarray, shape (C, S)
        Robust standard deviation of those images' σ fitted apart from the stack, px.
    isolated : ndarray of int, shape (C, S)
        Those images (fitted apart from the stack).
    law_sigma : ndarray, shape (C,)
        σ of the middle slab's isolated images from the stack's defocus law
        (:func:`ptv.reconstruct.defocus_law`) fitted to the outer slabs' images (fitted
        apart from the stack), median over the images, px: what the stack fills a middle
        slab without images with.
    law_se : ndarray, shape (C,)
        Its standard error, px.
    law_model_error : ndarray, shape (C,)
        What the law itself misses on this rig: σ² = a + b·z + c·z² fitted apart from the
        stack to the outer slabs' *specified* σ, its median σ at the middle slab's
        isolated particles less their specified median, px (the law holds σ along the
        depth only, while an oblique camera's magnification, hence its defocus blur,
        also changes across its image).
    found, ghosts : float
        Fraction of the reference particles paired with a point; of the points paired
        with no particle.
    rms_px : float
        Projected error of the paired reference particles, rms over them and the
        cameras, px.
    rms_um : float
        Their 3-D error, rms, µm.
    particles, points : int
        Reference particles (lit, imaged on every sensor) and points, over the snapshots.
    ppp : float
        Lit particles imaged per pixel, mean over the cameras and snapshots.
    seconds : float
        Wall time of the reconstructions of the snapshots with the measured OTF, s.
    """

    otf_sigma: np.ndarray
    otf_counts: np.ndarray
    slab_centres: np.ndarray
    specified_sigma: np.ndarray
    fitted_spread: np.ndarray
    isolated: np.ndarray
    law_sigma: np.ndarray
    law_se: np.ndarray
    law_model_error: np.ndarray
    found: float
    ghosts: float
    rms_px: float
    rms_um: float
    particles: int
    points: int
    ppp: float
    seconds: float


def _on_sensor(xy: np.ndarray, shape: tuple[int, int], margin: float) -> np.ndarray:
    """Image points at least ``margin`` px inside the sensor, shape (P,)."""
    rows, columns = shape
    inside = np.isfinite(xy).all(axis=1)
    with np.errstate(invalid="ignore"):
        inside &= (xy[:, 0] >= margin - 0.5) & (xy[:, 0] <= columns - 0.5 - margin)
        inside &= (xy[:, 1] >= margin - 0.5) & (xy[:, 1] <= rows - 0.5 - margin)
    return inside


def _slab_of(z: np.ndarray, centres: np.ndarray) -> np.ndarray:
    """Slab index of depths z, shape (P,), between equal slabs' centres (the outer slabs
    reaching beyond, as :func:`ptv.reconstruct.refine_otf` bins them)."""
    return np.clip(np.searchsorted(0.5 * (centres[1:] + centres[:-1]), z), 0, len(centres) - 1)


def _specification(camera, image, positions, lit, lighting, centres):
    """Per slab: the specified median σ of the lit particles whose images are isolated,
    the robust spread of those images' fitted σ and their number (module docstring);
    for the middle slab, the σ of the stack's defocus law fitted to the outer slabs'
    images, its standard error and the law's own miss (:class:`IprScores`)."""
    spec = specified_spots(camera, positions, lighting)
    imaged = np.flatnonzero(lit & _on_sensor(spec.xy, image.shape, 0.0))
    nearest = cKDTree(spec.xy[imaged]).query(spec.xy[imaged], k=2)[0][:, 1]
    alone = imaged[(nearest > ISOLATION_PX) & _on_sensor(spec.xy[imaged], image.shape, 4.0)]
    fits = fit_spots(image.astype(np.float64), spec.xy[alone], half_width=HALF_WINDOW)
    slab = _slab_of(positions[alone, 2], centres)
    median, spread, count = np.zeros(len(centres)), np.zeros(len(centres)), []
    for k in range(len(centres)):
        sigma = fits.sigma[(slab == k) & fits.converged]
        median[k] = np.median(spec.sigma[alone[slab == k]])
        spread[k] = MAD_TO_SIGMA * np.median(np.abs(sigma - np.median(sigma)))
        count.append(len(sigma))
    middle = len(centres) // 2
    outer, inner = (slab != middle) & fits.converged, alone[slab == middle]
    z_outer, z_inner = positions[alone[outer], 2], positions[inner, 2]
    law = float(np.median(defocus_law(z_outer, fits.sigma[outer], z_inner)))
    law_se = _quadratic_law(z_outer, fits.sigma[outer], z_inner)[1]
    on_spec = _quadratic_law(z_outer, spec.sigma[alone[outer]], z_inner)[0]
    model = on_spec - float(np.median(spec.sigma[inner]))
    return median, spread, np.array(count), law, law_se, model


def _quadratic_law(depth, sigma, at) -> tuple[float, float]:
    """σ² = a + b·z + c·z² fitted by plain least squares apart from the stack: the median
    of its σ at depths ``at``, px, and that σ's standard error at their median depth
    (the fit's covariance scaled by the residuals' robust variance), px."""
    scale = float(np.ptp(depth))
    design = np.stack([np.ones_like(depth), depth / scale, (depth / scale) ** 2], axis=1)
    target = sigma**2
    coef = np.linalg.lstsq(design, target, rcond=None)[0]
    residual = target - design @ coef
    spread = MAD_TO_SIGMA * np.median(np.abs(residual - np.median(residual)))
    z = np.asarray(at) / scale
    value = float(np.median(np.sqrt(coef[0] + coef[1] * z + coef[2] * z * z)))
    at_median = np.array([1.0, np.median(z), np.median(z) ** 2])
    variance = spread**2 * at_median @ np.linalg.inv(design.T @ design) @ at_median
    return value, float(np.sqrt(variance)) / (2 * value)


def _score(found_points, positions, reference, cameras, exact_xy, voxel):
    """Paired reference particles, points, ghosts and squared errors of one snapshot."""
    partner = assign_one_to_one(found_points, positions, voxel)
    hit = partner >= 0
    paired = hit & reference[np.maximum(partner, 0)]
    particles = partner[paired]
    px = [
        np.sum((camera.project(found_points[paired]) - xy[particles]) ** 2, axis=1)
        for camera, xy in zip(cameras, exact_xy, strict=True)
    ]
    um = np.sum((found_points[paired] - positions[particles]) ** 2, axis=1)
    return len(particles), int((~hit).sum()), np.concatenate(px), um


def ipr_scores(snapshots: int, *, seed: int) -> IprScores:
    """Render the dense case, measure its OTF, reconstruct it, score both (module
    docstring).

    Parameters
    ----------
    snapshots : int
        Snapshots recorded and reconstructed, >= 1 (the OTF is measured on the first).
    seed : int
        Seed of the particles and the sensor noise.

    Returns
    -------
    IprScores
    """
    rig = load_rig(RIG)
    cameras = rig.cameras
    lighting = rig_lighting(
        ParticleLighting(particle_diameter=DIAMETER, electrons_at_reference=ELECTRONS), rig
    )
    centre, size = np.asarray(rig.sheet.centre), np.asarray(rig.sheet.size)
    box = (tuple(centre - size / 2), tuple(centre + size / 2))
    sensor = Sensor()
    settings = IPRSettings()
    rng = np.random.default_rng(seed)
    otfs, specified = None, None
    found = reference_total = points = ghosts = imaged = 0
    err_px, err_um, seconds = [], [], 0.0
    for _ in range(snapshots):
        positions = rng.uniform(box[0], box[1], (PARTICLES, 3))
        brightness = rng.uniform(*BRIGHTNESS, PARTICLES)
        images = [
            record_particles(
                c, positions, lighting=lighting, sensor=sensor, rng=rng, brightness=brightness
            ).image
            for c in cameras
        ]
        lit = lighting.lit_at(positions)
        exact_xy = [c.project(positions) for c in cameras]
        on_sensor = [_on_sensor(xy, im.shape, 0.0) for xy, im in zip(exact_xy, images, strict=True)]
        imaged += sum(int((lit & inside).sum()) for inside in on_sensor)
        if otfs is None:  # the OTF as synptv run measures it
            saturation = float(2**sensor.bit_depth - 1)
            otfs = measure_run_otf([images], cameras, box, settings, saturation=saturation)
            specified = [
                _specification(c, im, positions, lit, lighting, otf.grid_z)
                for c, im, otf in zip(cameras, images, otfs, strict=True)
            ]
        t0 = time.perf_counter()
        result = reconstruct(images, cameras, otfs, box, settings=settings)
        seconds += time.perf_counter() - t0
        reference = lit & np.logical_and.reduce(on_sensor)
        paired, unpaired, px, um = _score(
            result.positions, positions, reference, cameras, exact_xy, result.diagnostics.voxel
        )
        found += paired
        reference_total += int(reference.sum())
        points += len(result.positions)
        ghosts += unpaired
        err_px.append(px)
        err_um.append(um)
    px, um = np.concatenate(err_px), np.concatenate(err_um)
    median, spread, count, law, law_se, model = (
        np.array([s[i] for s in specified]) for i in range(6)
    )
    return IprScores(
        otf_sigma=np.stack([np.stack([o.sigma_x[:, 0, 0], o.sigma_y[:, 0, 0]], 1) for o in otfs]),
        otf_counts=np.stack([o.counts[:, 0, 0] for o in otfs]),
        slab_centres=np.stack([o.grid_z for o in otfs]),
        specified_sigma=median,
        fitted_spread=spread,
        isolated=count,
        law_sigma=law,
        law_se=law_se,
        law_model_error=model,
        found=found / max(reference_total, 1),
        ghosts=ghosts / max(points, 1),
        rms_px=float(np.sqrt(np.mean(px))),
        rms_um=float(np.sqrt(np.mean(um))) * 1e6,
        particles=reference_total,
        points=points,
        ppp=imaged / (snapshots * len(cameras) * images[0].size),
        seconds=seconds,
    )
