"""What the rendered images show of themselves, against what their scenario specifies.

On every frame of a rendered case (:mod:`validation.claims.rendered_case`), measured from
the recorded images alone (:mod:`validation.truth.spot_fit`, sharing no code with the
renderer or the detector):

- the spots of isolated lit particles, each fitted with a pixel-integrated Gaussian on
  its 9 × 9 window: σ, the total DN above the background and the brightest pixel;
- the readings of the pixels no particle's specified light reaches: their histogram;
- the pixels at the saturated reading, on the case's frames and on one more exposure of
  its first particles, :data:`BRIGHT_ELECTRONS` bright, where the brightest pixels of
  most spots overfill the well.

The specification (:mod:`validation.truth.spot_spec`, :mod:`validation.truth.sensor_spec`)
gives each spot's σ and photo-electrons from the rig's optics and the case's lighting,
the background's exact distribution and each pixel's chance to saturate. The fitter's
own bias is taken out by fitting, the same way, spots that the specification's sensor
draws in plain NumPy with the same σ, electrons and sub-pixel centres
(:func:`validation.truth.sensor_spec.draw_spots`, :data:`REFERENCE_DRAWS` per spot):
the rendered spots and the drawn ones must agree within their standard errors.
"""

from dataclasses import dataclass, replace

import numpy as np
from scipy.spatial import cKDTree

from ptv.detect.background import estimate_background
from simulator.render.camera_frames import record_particles
from validation.claims.rendered_case import RenderedCase
from validation.truth.sensor_spec import (
    SensorSpec,
    background_moments,
    difference_mad_sigma,
    draw_spots,
    saturation_probability,
)
from validation.truth.spot_fit import SpotFits, fit_spots, fit_windows
from validation.truth.spot_spec import specified_image, specified_spots

#: A spot is isolated when no other lit particle's image is this close, px (its 9 × 9
#: window and a neighbour's 5σ reach, σ ≤ 1 px).
ISOLATION_PX = 9.0
#: Half-side of a spot's fitted window, px.
HALF_WINDOW = 4
#: Fewest specified photo-electrons of a fitted spot (its brightest pixel then reads
#: about seven times the read noise on the cases' sensor), e⁻.
MIN_ELECTRONS = 200.0
#: Isolated spots fitted per case, at most (a random choice among them): the medians'
#: standard errors are then about 0.1 % of σ and of the photo-electrons.
MAX_SPOTS = 3000
#: Spots drawn by the specification per rendered spot (the reference's standard error is
#: then half the measurement's).
REFERENCE_DRAWS = 4
#: A pixel is background when the specified light on it is below this, e⁻.
BACKGROUND_ELECTRONS = 1e-3
#: The sheet's edges: particles at least this fraction of its half-thickness from its
#: centre plane.
EDGE_FRACTION = 0.8
#: A pixel reads as saturated within this many read-noise σ of the full well's reading.
SATURATION_READ_SIGMAS = 5.0
#: Photo-electrons of a tracer on the sheet's centre plane in the saturated exposure
#: (the brightest pixels of its spots then expect two to three full wells).
BRIGHT_ELECTRONS = 1e5
#: Adjacent-pixel differences touched by a particle: either pixel expects at least this
#: many background σ of specified light (claim #50).
CONTAMINATION_SIGMAS = 0.5


@dataclass(frozen=True)
class SpotSample:
    """Fitted spots of one kind (rendered, or drawn by the specification).

    Attributes
    ----------
    sigma_ratio : ndarray, shape (K,)
        Fitted σ over the specified σ.
    amount_ratio : ndarray, shape (K,)
        Fitted total DN over gain × specified photo-electrons.
    peak_ratio : ndarray, shape (K,)
        Brightest pixel above the fitted background over gain × specified electrons.
    edge : ndarray of bool, shape (K,)
        Particle at the sheet's edges (:data:`EDGE_FRACTION`).
    """

    sigma_ratio: np.ndarray
    amount_ratio: np.ndarray
    peak_ratio: np.ndarray
    edge: np.ndarray


@dataclass(frozen=True)
class FormationScores:
    """A rendered case's images against their specification.

    Attributes
    ----------
    rendered : SpotSample
        The isolated spots of the simulator's images.
    reference : SpotSample
        The same spots drawn by the specification, :data:`REFERENCE_DRAWS` times each.
    blur, geometric, diffraction : ndarray, shape (K,)
        The three diameters each rendered spot's specified d_τ adds, px.
    background_histogram : ndarray, shape (2^B,)
        Readings of the background pixels, counted per DN.
    background_specified : tuple of float
        The specified mean and standard deviation of a background reading, DN.
    saturated : int
        Pixels reading within :attr:`saturation_band`.
    saturated_expected, saturated_variance : float
        Their specified expected number and its variance.
    saturation_band : (int, int)
        The readings of a full well, DN: its mean reading ± 5 read-noise σ, clipped to
        the ADC's range.
    noise_estimates : ndarray, shape (N,)
        The detector's background noise estimate of each image, DN
        (:func:`ptv.detect.background.estimate_background`, one tile).
    contamination : ndarray, shape (N,)
        Fraction of each image's horizontally adjacent pixel pairs that a particle's
        specified light touches (:data:`CONTAMINATION_SIGMAS`).
    background_mad_sigma : float
        What that estimate gives on the exact background distribution, DN
        (:func:`validation.truth.sensor_spec.difference_mad_sigma`).
    """

    rendered: SpotSample
    reference: SpotSample
    blur: np.ndarray
    geometric: np.ndarray
    diffraction: np.ndarray
    background_histogram: np.ndarray
    background_specified: tuple[float, float]
    saturated: int
    saturated_expected: float
    saturated_variance: float
    saturation_band: tuple[int, int]
    noise_estimates: np.ndarray
    contamination: np.ndarray
    background_mad_sigma: float


def sensor_spec(case: RenderedCase) -> SensorSpec:
    """The case's sensor as its stated numbers."""
    s = case.sensor
    return SensorSpec(s.gain, s.read_noise, s.offset, s.full_well, s.bit_depth, s.background)


def formation_scores(case: RenderedCase, *, seed: int) -> FormationScores:
    """Measure the case's images and draw their reference (module docstring).

    Parameters
    ----------
    case : RenderedCase
        The rendered frames, with the particles' true positions.
    seed : int
        The choice of spots and the noise of the reference's drawn ones.

    Returns
    -------
    FormationScores
    """
    sensor = sensor_spec(case)
    full = sensor.gain * sensor.full_well + sensor.offset
    spread = SATURATION_READ_SIGMAS * sensor.gain * sensor.read_noise
    band = (int(min(np.ceil(full - spread), sensor.max_dn)), int(min(full + spread, sensor.max_dn)))
    half_thickness = case.rig.sheet.size[2] / 2
    images, candidates, noise, contamination = [], [], [], []
    specified = background_moments(sensor)
    lit_dn = CONTAMINATION_SIGMAS * specified[1]
    histogram = np.zeros(sensor.max_dn + 1, dtype=np.int64)
    saturation = np.zeros(3)
    for m, pair in enumerate(case.exposures):
        for f, frame in enumerate(pair):
            points = case.positions[m, f]
            edge = np.abs(points[:, 2] - case.lighting.sheet.center) >= (
                EDGE_FRACTION * half_thickness
            )
            for camera, exposure in zip(case.rig.cameras, frame, strict=True):
                image = exposure.frame.image
                spec = specified_spots(camera, points, case.lighting)
                light = specified_image(spec, image.shape)
                histogram += np.bincount(
                    image[light < BACKGROUND_ELECTRONS].ravel(), minlength=sensor.max_dn + 1
                )[: sensor.max_dn + 1]
                saturation += _saturation(image, light, sensor, band)
                noise.append(float(estimate_background(image).noise[0, 0]))
                lit = sensor.gain * light >= lit_dn
                contamination.append(float(np.mean(lit[:, 1:] | lit[:, :-1])))
                chosen = _isolated(spec, image.shape)
                candidates.append(_spot_table(spec, chosen, edge, len(images)))
                images.append(image)
    saturation += _bright_saturation(case, sensor, band, seed)
    spots = _choose(candidates, np.random.default_rng(seed))
    fits = _fit(images, spots)
    rng = np.random.default_rng([seed, 1])
    repeat = lambda a: np.repeat(a, REFERENCE_DRAWS, axis=0)  # noqa: E731
    sigma, electrons = repeat(spots["sigma"]), repeat(spots["electrons"])
    fraction = repeat(spots["xy"] - np.rint(spots["xy"]))
    windows = draw_spots(sigma, electrons, fraction, sensor, rng, half_width=HALF_WINDOW)
    drawn = fit_windows(windows, np.zeros((len(windows), 2)))
    return FormationScores(
        rendered=_sample(fits, spots["sigma"], spots["electrons"], spots["edge"], sensor.gain),
        reference=_sample(drawn, sigma, electrons, repeat(spots["edge"]), sensor.gain),
        blur=spots["blur"],
        geometric=spots["geometric"],
        diffraction=spots["diffraction"],
        background_histogram=histogram,
        background_specified=specified,
        saturated=int(saturation[0]),
        saturated_expected=float(saturation[1]),
        saturated_variance=float(saturation[2]),
        saturation_band=band,
        noise_estimates=np.array(noise),
        contamination=np.array(contamination),
        background_mad_sigma=difference_mad_sigma(sensor),
    )


def _saturation(image, light, sensor: SensorSpec, band) -> np.ndarray:
    """Pixels reading in the band, and their specified expected number and variance."""
    needed = (band[0] - 0.5 - sensor.offset) / sensor.gain
    reach = needed - 10 * np.sqrt(needed) - 10 * sensor.read_noise
    p = saturation_probability(light[light + sensor.background >= reach], sensor, band)
    count = np.count_nonzero((image >= band[0]) & (image <= band[1]))
    return np.array([count, p.sum(), (p * (1 - p)).sum()])


def _bright_saturation(case: RenderedCase, sensor: SensorSpec, band, seed: int) -> np.ndarray:
    """:func:`_saturation` on the first particles recorded :data:`BRIGHT_ELECTRONS` bright."""
    camera, points = case.rig.cameras[0], case.positions[0, 0]
    lighting = replace(case.lighting, electrons_at_reference=BRIGHT_ELECTRONS)
    rng = np.random.default_rng([seed, 2])
    image = record_particles(camera, points, lighting=lighting, sensor=case.sensor, rng=rng).image
    light = specified_image(specified_spots(camera, points, lighting), image.shape)
    return _saturation(image, light, sensor, band)


def _isolated(spec, shape) -> np.ndarray:
    """Indices of the lit spots bright enough, alone, and wholly on the sensor."""
    lit = np.flatnonzero(np.isfinite(spec.xy).all(axis=1) & (spec.electrons > 0))
    xy = spec.xy[lit]
    if len(lit) > 1:
        neighbours = cKDTree(xy).query(xy, k=2)[0][:, 1]
    else:
        neighbours = np.full(len(lit), np.inf)
    margin = HALF_WINDOW + 1
    inside = (xy >= margin).all(axis=1)
    inside &= (xy[:, 0] <= shape[1] - 1 - margin) & (xy[:, 1] <= shape[0] - 1 - margin)
    keep = inside & (neighbours >= ISOLATION_PX) & (spec.electrons[lit] >= MIN_ELECTRONS)
    return lit[keep]


def _spot_table(spec, chosen: np.ndarray, edge: np.ndarray, image: int) -> dict:
    """The specified spots ``chosen`` of one image, as columns."""
    return {
        "image": np.full(len(chosen), image),
        "xy": spec.xy[chosen],
        "sigma": spec.sigma[chosen],
        "electrons": spec.electrons[chosen],
        "edge": edge[chosen],
        "geometric": spec.geometric[chosen],
        "diffraction": spec.diffraction[chosen],
        "blur": spec.blur[chosen],
    }


def _choose(tables: list[dict], rng: np.random.Generator) -> dict:
    """At most :data:`MAX_SPOTS` rows of the tables, at random, in image order."""
    table = {key: np.concatenate([t[key] for t in tables]) for key in tables[0]}
    count = len(table["image"])
    keep = np.sort(rng.choice(count, size=min(count, MAX_SPOTS), replace=False))
    return {key: column[keep] for key, column in table.items()}


def _fit(images: list[np.ndarray], spots: dict) -> SpotFits:
    """Fit the chosen spots on their images, in the table's order."""
    fits = [
        fit_spots(image, spots["xy"][spots["image"] == n], half_width=HALF_WINDOW)
        for n, image in enumerate(images)
    ]
    return SpotFits(
        *(
            np.concatenate([getattr(f, name) for f in fits])
            for name in SpotFits.__dataclass_fields__
        )
    )


def _sample(fits: SpotFits, sigma, electrons, edge, gain) -> SpotSample:
    light = gain * electrons
    return SpotSample(fits.sigma / sigma, fits.amount / light, fits.peak / light, edge)
