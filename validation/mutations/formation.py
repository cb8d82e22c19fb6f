"""Mutations of the simulator's image formation (``simulator.render``).

The PTV claims do not see these: the detector is robust to a spot of another size or a
raised background. The ``image.*`` claims of the images against their specification
(docs/claims.md #37–#41) do.
"""

from dataclasses import replace

import numpy as np

from simulator.render.camera_frames import ParticleLighting, record_particles
from simulator.render.sensor import Sensor
from simulator.rigs import load_rig
from validation.mutations.base import Mutation
from validation.mutations.patching import Patch, edited

#: Particles near the sheet's centre and edge, m.
_POINTS = np.array([[0.01, 0.015, 0.0], [-0.02, 0.01, 0.0045]])
#: Stray light the mutated sensor adds, e⁻ per pixel (8 DN on the default gain).
STRAY_ELECTRONS = 20.0
#: The mutated sensor's well, as a fraction of the stated one.
WELL_FRACTION = 0.02


def _recorded():
    """σ, photo-electrons, the image's total and centroid of two bright particles (their
    spots overfill the well) on a box-4cam camera."""
    camera = load_rig("box-4cam").cameras[0]
    frame = record_particles(
        camera,
        _POINTS,
        lighting=ParticleLighting(electrons_at_reference=1e5),
        sensor=Sensor(),
        rng=0,
    )
    light = frame.image.astype(float) - Sensor().offset
    rows, columns = np.indices(light.shape)
    centroid = [(light * columns).sum() / light.sum(), (light * rows).sum() / light.sum()]
    return np.concatenate([frame.sigma, frame.electrons, [light.sum()], centroid])


def _stray_light(original):
    def record(self, electrons, rng=None, **options):
        return original(self, np.asarray(electrons) + STRAY_ELECTRONS, rng, **options)

    return record


def _sensor_changed(**changes):
    """A Sensor.record that records with the sensor's ``changes`` (a function of it)."""

    def make(original):
        def record(self, electrons, rng=None, **options):
            changed = replace(self, **{k: f(self) for k, f in changes.items()})
            return original(changed, electrons, rng, **options)

        return record

    return make


_RECORD = "simulator.render.camera_frames:record_particles"

_RECORD_SENSOR = "simulator.render.sensor:Sensor.record"

FORMATION_MUTATIONS: tuple[Mutation, ...] = (
    Mutation(
        "spots-airy-width",
        "particle images drawn with the Airy-matched Gaussian (σ = d_τ/5.42), not the e⁻² "
        "width the scenario states (σ = d_τ/4)",
        (Patch(_RECORD, edited("convention=optics.convention", 'convention="airy"')),),
        ("image.spot_diameter", "image.defocus_at_edges"),
        ("image",),
        _recorded,
    ),
    Mutation(
        "spots-ten-percent-wide",
        "particle images 10 % wider than d_τ/4",
        (
            Patch(
                _RECORD,
                edited(
                    "sigma_lit[seen] = gaussian_sigma(", "sigma_lit[seen] = 1.1 * gaussian_sigma("
                ),
            ),
        ),
        ("image.spot_diameter",),
        ("image",),
        _recorded,
    ),
    Mutation(
        "defocus-dropped",
        "particle images drawn without the optics' defocus blur",
        (
            Patch(
                _RECORD,
                edited(
                    "blur = np.where(seen, defocus_blur(camera, p), np.nan)",
                    "blur = np.where(seen, 0.0, np.nan)",
                ),
            ),
        ),
        ("image.defocus_at_edges",),
        ("image",),
        _recorded,
    ),
    Mutation(
        "tracers-ten-percent-dim",
        "particle images carry 10 % less light than the sheet and tracers specify",
        (
            Patch(
                _RECORD,
                edited(
                    "electrons[lit] = particle_electrons(",
                    "electrons[lit] = 0.9 * particle_electrons(",
                ),
            ),
        ),
        ("image.spot_brightness",),
        ("image",),
        _recorded,
    ),
    Mutation(
        "stray-light",
        f"the sensor records {STRAY_ELECTRONS:g} e⁻ of stray light per pixel that the "
        "scenario does not state",
        (Patch(_RECORD_SENSOR, _stray_light),),
        ("image.background",),
        ("image",),
        _recorded,
    ),
    Mutation(
        "sheet-twenty-percent-wide",
        "the laser sheet's intensity profile 20 % wider than the scenario states",
        (
            Patch(
                _RECORD,
                edited(
                    "sheet=lighting.sheet,",
                    "sheet=type(lighting.sheet)(lighting.sheet.center, "
                    "1.2 * lighting.sheet.half_width),",
                ),
            ),
        ),
        ("image.spot_brightness",),
        ("image",),
        _recorded,
    ),
    Mutation(
        "spots-quarter-pixel-right",
        "particle images drawn a quarter pixel to the right of the particles' images",
        (
            Patch(
                _RECORD,
                edited(
                    "np.where(drawn[:, None], xy, np.nan)",
                    "np.where(drawn[:, None], xy + [0.25, 0.0], np.nan)",
                ),
            ),
        ),
        ("image.detection_rms", "image.position_bias"),
        ("image",),
        _recorded,
    ),
    Mutation(
        "read-noise-doubled",
        "the sensor's read noise twice the scenario's",
        (Patch(_RECORD_SENSOR, _sensor_changed(read_noise=lambda s: 2 * s.read_noise)),),
        ("image.background",),
        ("image",),
        _recorded,
    ),
    Mutation(
        "black-level-shifted",
        "the sensor's black level 5 DN above the scenario's offset",
        (Patch(_RECORD_SENSOR, _sensor_changed(offset=lambda s: s.offset + 5)),),
        ("image.background",),
        ("image",),
        _recorded,
    ),
    Mutation(
        "well-never-fills",
        "the sensor's well never saturates (a full well a thousand times the stated one)",
        (Patch(_RECORD_SENSOR, _sensor_changed(full_well=lambda s: 1000 * s.full_well)),),
        ("image.saturation",),
        ("image",),
        _recorded,
    ),
    Mutation(
        "well-fifty-times-small",
        "the sensor saturates at a fiftieth of the full well the scenario states",
        (Patch(_RECORD_SENSOR, _sensor_changed(full_well=lambda s: WELL_FRACTION * s.full_well)),),
        ("image.saturation",),
        ("image",),
        _recorded,
    ),
)
