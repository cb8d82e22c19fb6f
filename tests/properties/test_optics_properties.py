"""Hypothesis properties of the physical camera: exact round trip and Snell's law."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from simulator.optics.camera import Camera
from simulator.optics.interfaces import FlatInterfaces, refract
from simulator.optics.lens import Lens
from simulator.optics.placement import WindowSpec, look_at_camera


@st.composite
def cameras(draw):
    focal = draw(st.floats(0.016, 0.1))
    pitch = draw(st.floats(3.45e-6, 10e-6))
    width, height = 2048, 1088
    cx, cy = draw(st.floats(900, 1150)), draw(st.floats(450, 650))
    # distortion scaled by the farthest corner's normalized radius² r_c2 so that the whole
    # sensor stays inside the distortion's monotone region (barrel at most ~8 % there)
    r_c2 = (max(cx, width - 1 - cx) ** 2 + max(cy, height - 1 - cy) ** 2) * (pitch / focal) ** 2
    lens = Lens(
        focal,
        pitch,
        sensor_size=(width, height),
        principal_point=(cx, cy),
        k1=draw(st.floats(-0.05, 0.1)) / r_c2,
        k2=draw(st.floats(-0.02, 0.05)) / r_c2**2,
        k3=draw(st.floats(-0.01, 0.02)) / r_c2**3,
        p1=draw(st.floats(-1e-3, 1e-3)),
        p2=draw(st.floats(-1e-3, 1e-3)),
        tau_x=draw(st.floats(-0.08, 0.08)),
        tau_y=draw(st.floats(-0.08, 0.08)),
        image_distance=focal * draw(st.floats(1.0, 1.2)),
    )
    window = WindowSpec(
        water_path=draw(st.floats(0.05, 0.4)),
        glass_thickness=draw(st.floats(0.0, 0.03)),
        obliquity=np.radians(draw(st.floats(0.0, 20.0))),
        obliquity_direction=draw(st.floats(0.0, 2 * np.pi)),
        n_glass=draw(st.sampled_from([1.49, 1.52])),
    )
    use_window = draw(st.integers(0, 4)) > 0  # one camera in five looks straight into air
    return look_at_camera(
        np.array([draw(st.floats(-0.05, 0.05)), draw(st.floats(-0.05, 0.05)), 0.0]),
        lens,
        distance=draw(st.floats(0.6, 1.5)),
        azimuth=np.radians(draw(st.floats(-50.0, 50.0))),
        elevation=np.radians(draw(st.floats(-15.0, 15.0))),
        window=window if use_window else None,
    )


@settings(max_examples=150)
@given(
    camera=cameras(),
    fractions=st.lists(st.tuples(st.floats(0.0, 1.0), st.floats(0.0, 1.0)), min_size=1,
                       max_size=20),
    depth=st.floats(1e-4, 1.0),
)
def test_project_inverts_pixel_to_ray(camera, fractions, depth):
    width, height = camera.lens.sensor_size
    xy = np.array(fractions) * [width - 1, height - 1]
    rays = camera.pixel_to_ray(xy)
    assert rays.valid.all()
    back = camera.project(rays.point_at(depth))
    assert np.isfinite(back).all()
    assert np.max(np.abs(back - xy)) < 1e-6


@settings(max_examples=60)
@given(
    n_layers=st.integers(1, 3),
    data=st.data(),
    fractions=st.lists(st.tuples(st.floats(0.0, 1.0), st.floats(0.0, 1.0)), min_size=1,
                       max_size=20),
    depth=st.floats(1e-4, 1.0),
)
def test_round_trip_through_general_stacks(n_layers, data, fractions, depth):
    """Any number of parallel layers, any indices (TIR possible), any normal within 30°
    of the optical axis."""
    indices = [data.draw(st.floats(1.0, 1.8)) for _ in range(n_layers + 1)]
    gaps = [data.draw(st.floats(0.0, 0.05)) for _ in range(n_layers - 1)]
    tilt = np.radians(data.draw(st.floats(0.0, 30.0)))
    turn = data.draw(st.floats(0.0, 2 * np.pi))
    normal = np.array([np.sin(tilt) * np.cos(turn), np.sin(tilt) * np.sin(turn), np.cos(tilt)])
    first = data.draw(st.floats(0.05, 0.8))
    stack = FlatInterfaces(normal, first + np.cumsum(np.r_[0.0, gaps]), indices)
    lens = Lens(data.draw(st.floats(0.016, 0.1)), 5.5e-6, k1=data.draw(st.floats(-0.5, 0.5)),
                tau_y=data.draw(st.floats(-0.05, 0.05)))
    camera = Camera(np.zeros(3), np.eye(3), lens, stack)
    xy = np.array(fractions) * [2047, 1087]
    rays = camera.pixel_to_ray(xy)
    ok = rays.valid
    back = camera.project(rays.point_at(depth)[ok])
    assert np.isfinite(back).all()
    if ok.any():
        assert np.max(np.abs(back - xy[ok])) < 1e-6


@st.composite
def unit_vectors(draw):
    v = np.array([draw(st.floats(-1, 1)) for _ in range(3)])
    if np.linalg.norm(v) < 1e-3:
        v = np.array([0.0, 0.0, 1.0])
    return v / np.linalg.norm(v)


@given(d=unit_vectors(), normal=unit_vectors(), n1=st.floats(1.0, 1.7), n2=st.floats(1.0, 1.7))
def test_snell_law_coplanarity_and_tir(d, normal, n1, n2):
    t, tir = refract(d[None, :], normal, n1, n2)
    sin1 = np.linalg.norm(np.cross(d, normal))
    if n1 * sin1 > n2 * (1 + 1e-12):
        assert tir[0] and np.isnan(t).all()
        return
    if n1 * sin1 > n2 * (1 - 1e-12):
        return  # at the critical angle: either answer is right
    assert not tir[0]
    t = t[0]
    sin2 = np.linalg.norm(np.cross(t, normal))
    assert abs(n1 * sin1 - n2 * sin2) < 1e-12
    assert abs(np.cross(d, normal) @ t) < 1e-12  # incident, normal, refracted coplanar
    assert abs(np.linalg.norm(t) - 1) < 1e-12
    assert np.sign(t @ normal) == np.sign(d @ normal) or abs(d @ normal) < 1e-12
