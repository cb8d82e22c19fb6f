"""What a scenario specifies for its particle images, written apart from the renderer.

For a particle at world point X seen by a camera (docs/imaging.md §1–3):

- its image centre, ``camera.project(X)``;
- the lateral magnification M, the image displacement on the sensor per object
  displacement along world Y (the axis every rig's cameras see square-on), by a central
  difference of the projection;
- the image diameter d_τ = √((M d_p)² + d_diff² + d_blur²), d_diff = 2.44 f#(M + 1)λ,
  d_blur the defocus blur of the optics (``simulator.optics.defocus_blur``, the optics'
  business), and the Gaussian σ = d_τ/4 (the e⁻² convention);
- its photo-electrons N = N_ref exp(−2(Z − Z₀)²/w²) (tracers of the reference diameter)
  inside the lit slab |Z − Z₀| ≤ cutoff · w, none outside;
- its expected electrons per pixel, N times the pixel-integrated Gaussian, spots adding.
"""

from dataclasses import dataclass

import numpy as np

from simulator.optics import defocus_blur
from validation.truth.spot_fit import pixel_integrated

__all__ = ["SpotSpecification", "specified_image", "specified_spots"]

#: Object-side step of the magnification's central difference, m.
MAGNIFICATION_STEP = 2e-5
#: d_τ per Gaussian σ in the e⁻² convention.
E2_DIAMETER_PER_SIGMA = 4.0
#: Half-side of the square each spot of the expected image covers, in σ (the light
#: beyond it is below 1e-6 of the spot's).
IMAGE_SIGMAS = 5.0


@dataclass(frozen=True)
class SpotSpecification:
    """The specified image of each particle on one camera.

    Attributes
    ----------
    xy : ndarray, shape (P, 2)
        Image centre (x = column, y = row), px; NaN where not imaged.
    sigma : ndarray, shape (P,)
        Gaussian σ, px.
    electrons : ndarray, shape (P,)
        Photo-electrons N, e⁻ (0 outside the lit slab).
    geometric, diffraction, blur : ndarray, shape (P,)
        M d_p, d_diff and d_blur, px.
    """

    xy: np.ndarray
    sigma: np.ndarray
    electrons: np.ndarray
    geometric: np.ndarray
    diffraction: np.ndarray
    blur: np.ndarray


def specified_spots(camera, positions: np.ndarray, lighting) -> SpotSpecification:
    """The specified spot of each particle (module docstring).

    Parameters
    ----------
    camera : simulator.optics.Camera
        The camera (its lens' f-number and pixel pitch; its projection).
    positions : ndarray, shape (P, 3)
        Particle centres, m.
    lighting : simulator.render.camera_frames.ParticleLighting
        Tracer diameter, wavelength, sheet (Z₀, w), cutoff and N_ref, read as stated
        numbers.

    Returns
    -------
    SpotSpecification
    """
    positions = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    pitch, f_number = camera.lens.pixel_pitch, camera.lens.f_number
    xy = camera.project(positions)
    step = np.array([0.0, MAGNIFICATION_STEP, 0.0])
    stretch = (camera.project(positions + step) - camera.project(positions - step)) / (
        2 * MAGNIFICATION_STEP
    )
    magnification = np.linalg.norm(stretch, axis=1) * pitch
    geometric = magnification * lighting.particle_diameter / pitch
    diffraction = 2.44 * f_number * (magnification + 1.0) * lighting.wavelength / pitch
    blur = defocus_blur(camera, positions)
    sigma = np.sqrt(geometric**2 + diffraction**2 + blur**2) / E2_DIAMETER_PER_SIGMA
    offset = positions[:, 2] - lighting.sheet.center
    width = lighting.sheet.half_width
    electrons = np.where(
        np.abs(offset) <= lighting.cutoff * width,
        lighting.electrons_at_reference * np.exp(-2.0 * offset**2 / width**2),
        0.0,
    )
    return SpotSpecification(xy, sigma, electrons, geometric, diffraction, blur)


def specified_image(spots: SpotSpecification, shape: tuple[int, int]) -> np.ndarray:
    """Expected photo-electrons per pixel of the specified spots, before the sensor.

    Parameters
    ----------
    spots : SpotSpecification
        The spots (those with NaN centres or no electrons are left out).
    shape : (H, W)
        Sensor rows and columns.

    Returns
    -------
    ndarray, shape (H, W)
        e⁻.
    """
    image = np.zeros(shape)
    drawn = np.isfinite(spots.xy).all(axis=1) & (spots.electrons > 0)
    if not drawn.any():
        return image
    xy, sigma, electrons = spots.xy[drawn], spots.sigma[drawn], spots.electrons[drawn]
    half = int(np.ceil(IMAGE_SIGMAS * sigma.max()))
    offsets = np.arange(-half, half + 1)
    columns = np.rint(xy[:, 0])[:, None] + offsets
    rows = np.rint(xy[:, 1])[:, None] + offsets
    light = (
        electrons[:, None, None]
        * pixel_integrated(xy[:, 1], sigma, rows)[:, :, None]
        * pixel_integrated(xy[:, 0], sigma, columns)[:, None, :]
    )
    row_index = np.broadcast_to(rows[:, :, None], light.shape).astype(np.int64)
    column_index = np.broadcast_to(columns[:, None, :], light.shape).astype(np.int64)
    inside = (row_index >= 0) & (row_index < shape[0]) & (column_index >= 0)
    inside &= column_index < shape[1]
    np.add.at(image, (row_index[inside], column_index[inside]), light[inside])
    return image
