"""Mutations of the simulator's optics (``simulator.optics``, ``simulator.rigs``).

The calibration claims cannot see these: the dots, the true cameras of the noise floor
and the truth all come from the same (mutated) cameras. The ``optics`` claims check the
simulator's rays against Snell's law with the indices the rig states, recomputed in plain
NumPy (:mod:`validation.truth.refraction`) and the focus of the sheet on Scheimpflug
mounts against the diffraction spot.
"""

import numpy as np

from simulator.rigs import load_rig
from validation.mutations.base import Mutation
from validation.mutations.patching import Patch, edited

#: A point near the centre of the light sheet, m.
_POINT = np.array([[0.01, 0.015, 0.002]])


def _projected():
    return np.concatenate([c.project(_POINT) for c in load_rig("paper-stereo").cameras])


def _index(name: str, wrong: float):
    """A ``flat_window`` that builds its windows with refractive index ``name`` = ``wrong``."""

    def make(original):
        def flat_window(*args, **options):
            return original(*args, **{**options, name: wrong})

        return flat_window

    return make


OPTICS_MUTATIONS: tuple[Mutation, ...] = (
    Mutation(
        "glass-index-1.52",
        "the simulator's windows refract with n = 1.52 (crown glass) instead of the rig's "
        "PMMA, 1.49",
        (Patch("simulator.optics.interfaces:flat_window", _index("n_glass", 1.52)),),
        ("optics.snell",),
        ("optics", "calib"),
        _projected,
    ),
    Mutation(
        "water-index-1.34",
        "the simulator's water refracts with n = 1.34 instead of 1.333",
        (Patch("simulator.optics.interfaces:flat_window", _index("n_water", 1.34)),),
        ("optics.snell",),
        ("optics", "calib"),
        _projected,
    ),
    Mutation(
        "scheimpflug-dropped",
        "the simulator builds every camera with an untilted sensor, whatever the rig "
        "file's scheimpflug = true",
        (
            Patch(
                "simulator.rigs:_camera",
                edited('tilt=table["scheimpflug"]', "tilt=False"),
            ),
        ),
        ("optics.sheet_in_focus",),
        ("optics", "calib"),
        _projected,
    ),
)
