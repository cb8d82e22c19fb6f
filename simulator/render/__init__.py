"""Images as a camera would record them: particle spots and the sensor (docs/imaging.md).

- :mod:`simulator.render.spot`: particle-image size (diffraction, geometry, defocus,
  Gaussian σ convention) and brightness (Mie ∝ d_p², laser-sheet profile).
- :mod:`simulator.render.particle_images`: pixel-integrated Gaussian spots in per-particle
  ROIs, with the truth of every particle.
- :mod:`simulator.render.sensor`: shot noise, read noise, full well, gain, offset and
  bit depth.
"""

from simulator.render.particle_images import ParticleImage, fraction_on_sensor, render_particles
from simulator.render.sensor import Sensor
from simulator.render.spot import (
    LaserSheet,
    SpotOptics,
    defocus_diameter,
    diffraction_diameter,
    gaussian_sigma,
    geometric_diameter,
    image_diameter,
    mie_scale,
    particle_electrons,
)

__all__ = [
    "LaserSheet",
    "ParticleImage",
    "Sensor",
    "SpotOptics",
    "defocus_diameter",
    "diffraction_diameter",
    "fraction_on_sensor",
    "gaussian_sigma",
    "geometric_diameter",
    "image_diameter",
    "mie_scale",
    "particle_electrons",
    "render_particles",
]
