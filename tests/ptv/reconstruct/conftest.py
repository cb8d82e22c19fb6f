"""A small four-camera rig like the LPT Challenge's (cameras at −30°, −10°, +10°, +30°
in one plane, about 60 µm per pixel) and particle images rendered by the simulator."""

import numpy as np
import pytest

from simulator.render.camera_frames import ParticleLighting, record_particles
from simulator.render.sensor import Sensor
from simulator.render.spot import LaserSheet
from simulator.rigs import rig_from_dict

#: Sensor (width, height), px, and the measurement volume (X, Y, Z), m.
SENSOR = (320, 256)
VOLUME = (0.012, 0.010, 0.010)


def small_rig(n_cameras: int = 4):
    azimuths = (-30, -10, 10, 30)[:n_cameras]
    cameras = [
        {
            "name": f"cam{i + 1}",
            "azimuth_deg": float(az),
            "distance": 0.70,
            "focal_length": 0.100,
            "f_number": 16.0,
            "pixel_pitch": 10e-6,
            "sensor_size": list(SENSOR),
            "scheimpflug": True,
        }
        for i, az in enumerate(azimuths)
    ]
    spec = {
        "name": "small-lpt",
        "description": "",
        "sheet": {"width": VOLUME[0], "height": VOLUME[1], "thickness": VOLUME[2]},
        "tank": {"kind": "free"},
        "cameras": cameras,
    }
    half = 0.5 * np.asarray(VOLUME)
    return rig_from_dict(spec), (tuple(-half), tuple(half))


def lighting() -> ParticleLighting:
    """A lit volume: a Gaussian profile 40 mm wide (e⁻²) over a 10 mm deep volume."""
    return ParticleLighting(
        particle_diameter=20e-6,
        sheet=LaserSheet(center=0.0, half_width=0.04),
        electrons_at_reference=6000.0,
        cutoff=3.0,
    )


def render(rig, box, n: int, seed: int):
    """n particles uniform in the box; every camera's frame."""
    rng = np.random.default_rng(seed)
    lower, upper = (np.asarray(v) for v in box)
    positions = rng.uniform(lower, upper, (n, 3))
    frames = [
        record_particles(cam, positions, lighting=lighting(), sensor=Sensor(), rng=rng)
        for cam in rig.cameras
    ]
    return positions, frames


@pytest.fixture(scope="session")
def rig_and_box():
    return small_rig()


@pytest.fixture(scope="session")
def sparse_frames(rig_and_box):
    """About 0.008 particles per pixel: many isolated images, for the OTF."""
    rig, box = rig_and_box
    return render(rig, box, 600, seed=11)


@pytest.fixture(scope="session")
def otfs(sparse_frames):
    from ptv.reconstruct import measure_otf

    _, frames = sparse_frames
    return measure_otf([f.image for f in frames], regions=(1, 2), min_per_region=20)


@pytest.fixture(scope="session")
def renderer():
    """:func:`render` (test modules cannot import conftest under importlib mode)."""
    return render


@pytest.fixture(scope="session")
def rig_factory():
    """:func:`small_rig`."""
    return small_rig
