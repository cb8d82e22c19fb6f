"""Particle frames as a camera of a rig records them, with the truth of every particle.

For each particle: the exact image of its centre through the camera's refracting window
(``Camera.project``), a spot whose diameter adds in quadrature the geometric image
M·d_p, the diffraction spot 2.44 f#(M+1)λ and the defocus blur computed by the optics
for that particle, and a brightness set by the laser-sheet profile. The sensor model
then records the expected photo-electrons as a uint16 image.

A rig's sheet may ask for a top-hat light (``profile = "top-hat"`` in its ``[sheet]``):
:func:`rig_lighting` then lights the particles uniformly over the sheet's thickness.
"""

from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from simulator.optics import Camera, defocus_blur
from simulator.render.particle_images import render_particles
from simulator.render.sensor import Sensor
from simulator.render.spot import LaserSheet, SpotOptics, gaussian_sigma, particle_electrons

if TYPE_CHECKING:
    from simulator.rigs import Rig


@dataclass(frozen=True)
class ParticleLighting:
    """Tracer particles and their illumination.

    Parameters
    ----------
    particle_diameter : float
        d_p, m (the paper's polystyrene tracers: 225 µm).
    sheet : LaserSheet
        Laser-sheet profile (centre and e⁻² half-width, m; or a top-hat slab).
    electrons_at_reference : float
        Photo-electrons collected from a particle of diameter d_p on the sheet's centre
        plane, e⁻.
    wavelength : float
        Laser wavelength, m.
    cutoff : float
        Particles further than ``cutoff`` e⁻² half-widths from the sheet centre are dark;
        under a top-hat sheet, also those outside its slab (beyond one half-width).
    aperture : ((float, float), (float, float)) or None
        The X and Y ranges, m, outside which particles are dark too (a volume lit through
        a rectangular aperture); None (default): a sheet, lit across all X and Y.

    Examples
    --------
    The default: the paper's 225 µm tracers in a Gaussian sheet of 5 mm e⁻² half-width,
    dark beyond 10 mm from its centre.

    >>> import numpy as np
    >>> import simulator
    >>> lighting = simulator.ParticleLighting()
    >>> lighting.sheet
    LaserSheet(center=0.0, half_width=0.005, profile='gaussian')
    >>> lighting.lit(np.array([0.0, 0.009, 0.011]))  # particles at these Z (m)
    array([ True,  True, False])
    """

    particle_diameter: float = 225e-6
    sheet: LaserSheet = field(default_factory=lambda: LaserSheet(center=0.0, half_width=5e-3))
    electrons_at_reference: float = 6000.0
    wavelength: float = 532e-9
    cutoff: float = 2.0
    aperture: tuple[tuple[float, float], tuple[float, float]] | None = None

    def __post_init__(self) -> None:
        for name in ("particle_diameter", "electrons_at_reference", "wavelength", "cutoff"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be > 0, got {value!r}")
        if self.aperture is not None:
            ranges = np.asarray(self.aperture, dtype=float)
            if ranges.shape != (2, 2) or not np.isfinite(ranges).all():
                raise ValueError(f"aperture must be ((x0, x1), (y0, y1)), m, got {self.aperture!r}")
            if not (ranges[:, 0] < ranges[:, 1]).all():
                raise ValueError(f"aperture ranges must increase, got {self.aperture!r}")

    def lit(self, z: np.ndarray) -> np.ndarray:
        """Whether particles at world Z (shape (N,), m) are lit (``cutoff``)."""
        reach = self.cutoff * self.sheet.half_width
        if self.sheet.profile == "top-hat":
            reach = min(reach, self.sheet.half_width)
        return np.abs(z - self.sheet.center) <= reach

    def lit_at(self, positions: np.ndarray) -> np.ndarray:
        """Whether particles at world positions (shape (N, 3), m) are lit: by the sheet
        (:meth:`lit`) and inside the ``aperture``."""
        positions = np.asarray(positions, dtype=float).reshape(-1, 3)
        lit = self.lit(positions[:, 2])
        if self.aperture is not None:
            for axis, (low, high) in enumerate(self.aperture):
                lit &= (positions[:, axis] >= low) & (positions[:, axis] <= high)
        return lit


def rig_lighting(lighting: ParticleLighting, rig: "Rig") -> ParticleLighting:
    """The lighting of ``rig``'s particles (``[sheet] profile`` of its rig file).

    Parameters
    ----------
    lighting : ParticleLighting
        The tracers and the default Gaussian sheet (a scenario's).
    rig : simulator.rigs.Rig
        The rig.

    Returns
    -------
    ParticleLighting
        ``lighting`` itself for the default ``"gaussian"`` profile; for ``"top-hat"``,
        ``lighting`` with a top-hat sheet over the rig's sheet (centre and half its
        thickness) and its aperture over the sheet's width and height: the rig's sheet
        is a volume lit uniformly, and dark outside.

    Examples
    --------
    The volume of ``lpt-challenge-small`` is 30 mm deep and lit uniformly:

    >>> import numpy as np
    >>> import simulator
    >>> rig = simulator.load_rig("lpt-challenge-small")
    >>> lighting = simulator.rig_lighting(simulator.ParticleLighting(), rig)
    >>> lighting.sheet
    LaserSheet(center=0.0, half_width=0.015, profile='top-hat')
    >>> lighting.lit(np.array([0.0, 0.014, 0.016]))  # particles at these Z (m)
    array([ True,  True, False])
    >>> lighting.aperture  # and at these X and Y (m)
    ((-0.01, 0.01), (-0.0125, 0.0125))
    >>> lighting.lit_at(np.array([[0.0, 0.0, 0.0], [0.011, 0.0, 0.0]]))
    array([ True, False])
    """
    if rig.sheet_profile == "gaussian":
        return lighting
    centre, size = rig.sheet.centre, rig.sheet.size
    sheet = LaserSheet(
        center=float(centre[2]), half_width=0.5 * float(size[2]), profile=rig.sheet_profile
    )
    aperture = tuple(
        (float(centre[a] - 0.5 * size[a]), float(centre[a] + 0.5 * size[a])) for a in (0, 1)
    )
    return replace(lighting, sheet=sheet, aperture=aperture)


@dataclass(frozen=True)
class ParticleFrame:
    """One recorded frame of one camera.

    Attributes
    ----------
    image : ndarray of uint16, shape (rows, cols)
        The recorded frame, DN.
    xy : ndarray, shape (P, 2)
        Exact image of each particle centre, px (NaN where not imaged).
    sigma : ndarray, shape (P,)
        Gaussian σ of each spot, px.
    electrons : ndarray, shape (P,)
        Expected photo-electrons of each spot, e⁻.
    visible : ndarray of bool, shape (P,)
        Particle lit and its spot (at least partly) on the sensor.
    """

    image: np.ndarray
    xy: np.ndarray
    sigma: np.ndarray
    electrons: np.ndarray
    visible: np.ndarray


def local_magnification(camera: Camera, points: np.ndarray, *, step: float = 1e-4) -> np.ndarray:
    """Lateral magnification at world points, from the image of a small step along Y.

    A central difference; at a point whose step on one side leaves the sensor (its image
    within a pixel of the edge), the one-sided difference on the other side.

    Parameters
    ----------
    camera : Camera
        The camera.
    points : ndarray, shape (P, 3)
        World points, m.
    step : float
        Step along world Y, m.

    Returns
    -------
    ndarray, shape (P,)
        M = (image displacement on the sensor) / (object displacement); NaN where the
        point itself is outside the view.
    """
    offset = np.array([0.0, step, 0.0])
    ahead, behind = camera.project(points + offset), camera.project(points - offset)
    derivative = (ahead - behind) / (2 * step)
    edge = np.flatnonzero(~np.isfinite(derivative).all(axis=1))
    if edge.size:  # rare: the centres are projected for these points only
        centre = camera.project(points[edge])
        for one_sided in ((ahead[edge] - centre) / step, (centre - behind[edge]) / step):
            missing = ~np.isfinite(derivative[edge]).all(axis=1)
            derivative[edge[missing]] = one_sided[missing]
    return np.linalg.norm(derivative, axis=1) * camera.lens.pixel_pitch


def record_particles(
    camera: Camera,
    positions: np.ndarray,
    *,
    lighting: ParticleLighting,
    sensor: Sensor,
    rng: np.random.Generator | int | None = None,
    brightness: np.ndarray | None = None,
) -> ParticleFrame:
    """Render and record the particles at ``positions`` as ``camera`` sees them.

    Parameters
    ----------
    camera : Camera
        A physical camera of a rig.
    positions : ndarray, shape (P, 3)
        Particle centres, m.
    lighting : ParticleLighting
        Particle size and laser sheet.
    sensor : Sensor
        Noise, gain and bit depth.
    rng : numpy.random.Generator, int or None
        Sensor noise.
    brightness : ndarray, shape (P,), optional
        Light each tracer scatters relative to one of ``lighting.particle_diameter``,
        >= 0 (a polydisperse seeding: about (d / d_p)² for the sizes here); None: all
        alike.

    Returns
    -------
    ParticleFrame

    Examples
    --------
    Three particles near the sheet centre as the paper-stereo rig's cameras record them
    (2048 × 1088 px each):

    >>> import numpy as np
    >>> import simulator
    >>> rig = simulator.load_rig("paper-stereo")
    >>> positions = np.array([[0.0, 0.0, 0.0], [1e-3, 5e-4, 0.0], [-1e-3, 0.0, 1e-3]])  # m
    >>> lighting = simulator.rig_lighting(simulator.ParticleLighting(), rig)
    >>> frames = [simulator.record_particles(camera, positions, lighting=lighting,
    ...                                      sensor=simulator.Sensor(), rng=0)
    ...           for camera in rig.cameras]
    >>> first = frames[0]
    >>> first.image.shape, first.image.dtype  # DN
    ((1088, 2048), dtype('uint16'))
    >>> first.xy.round(2)  # exact image of each centre through the window, px
    array([[1023.5 ,  543.5 ],
           [1031.55,  538.36],
           [1021.4 ,  543.8 ]])
    >>> first.sigma.round(2), first.visible  # spot σ (px), drawn on the sensor
    (array([0.62, 0.62, 0.62]), array([ True,  True,  True]))
    """
    positions = np.asarray(positions, dtype=float)
    if positions.ndim != 2 or positions.shape[1] != 3 or not np.isfinite(positions).all():
        raise ValueError(f"positions must be finite with shape (P, 3), got {positions.shape}")
    if brightness is not None:
        brightness = np.asarray(brightness, dtype=float)
        if brightness.shape != (len(positions),) or not (brightness >= 0).all():
            raise ValueError(
                f"brightness must be >= 0 with shape ({len(positions)},), got {brightness.shape}"
            )
    lens = camera.lens
    lit = lighting.lit_at(positions)
    xy = np.full((len(positions), 2), np.nan)
    sigma = np.full(len(positions), np.nan)
    electrons = np.zeros(len(positions))
    if lit.any():
        p = positions[lit]
        xy_lit = camera.project(p)
        seen = np.isfinite(xy_lit).all(axis=1)
        magnification = np.where(seen, local_magnification(camera, p), np.nan)
        optics = SpotOptics(
            magnification=float(np.nanmedian(magnification)) if seen.any() else 0.05,
            f_number=lens.f_number,
            wavelength=lighting.wavelength,
            pixel_pitch=lens.pixel_pitch,
        )
        geometric = magnification * lighting.particle_diameter / lens.pixel_pitch
        diffraction = optics.diffraction_diameter / lens.pixel_pitch
        blur = np.where(seen, defocus_blur(camera, p), np.nan)
        diameter = np.sqrt(geometric**2 + diffraction**2 + blur**2)
        xy[lit] = xy_lit
        sigma_lit = np.full(len(p), np.nan)  # a particle outside the view has no spot
        sigma_lit[seen] = gaussian_sigma(diameter[seen], convention=optics.convention)
        sigma[lit] = sigma_lit
        electrons[lit] = particle_electrons(
            lighting.particle_diameter,
            p[:, 2],
            sheet=lighting.sheet,
            electrons_at_reference=lighting.electrons_at_reference,
            reference_diameter=lighting.particle_diameter,
        )
        if brightness is not None:
            electrons[lit] *= brightness[lit]
    shape = (lens.sensor_size[1], lens.sensor_size[0])
    drawn = lit & np.isfinite(xy).all(axis=1)
    spots = render_particles(np.where(drawn[:, None], xy, np.nan), sigma, electrons, shape=shape)
    image = sensor.record(spots.image, rng)
    return ParticleFrame(
        image=image, xy=xy, sigma=sigma, electrons=electrons, visible=drawn & spots.visible
    )
