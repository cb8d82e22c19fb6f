"""The OTF model, its background level, and its measurement on rendered images."""

import numpy as np
import pytest

from ptv.reconstruct import (
    OpticalTransferFunction,
    background_level,
    measure_camera_otf,
    measure_otf,
)
from simulator.render.sensor import Sensor


def test_otf_interpolates_between_region_centres_and_holds_beyond():
    sx = np.array([[0.6, 1.0], [0.8, 1.2]])
    otf = OpticalTransferFunction(
        shape=(100, 200),
        grid_x=[50.0, 150.0],
        grid_y=[25.0, 75.0],
        sigma_x=sx,
        sigma_y=sx,
        rho=np.zeros((2, 2)),
        intensity=np.ones((2, 2)),
        counts=np.ones((2, 2)),
    )
    xy = np.array([[50, 25], [100, 25], [100, 50], [0, 0], [199, 99], [np.nan, 3]])
    got = otf.at(xy)[0]
    assert np.allclose(got[:5], [0.6, 0.8, 0.9, 0.6, 1.2])
    assert np.isnan(got[5])


def test_otf_with_depth_interpolates_in_depth():
    table = np.stack([np.full((1, 1), 0.6), np.full((1, 1), 1.0)])
    otf = OpticalTransferFunction(
        shape=(10, 10),
        grid_x=[5.0],
        grid_y=[5.0],
        grid_z=[-0.01, 0.01],
        sigma_x=table,
        sigma_y=table,
        rho=np.zeros((2, 1, 1)),
        intensity=np.ones((2, 1, 1)),
        counts=np.ones((2, 1, 1)),
    )
    pts = np.array([[0, 0, -0.02], [0, 0, 0.0], [0, 0, 0.005]])
    assert np.allclose(otf.at(np.zeros((3, 2)), pts)[0], [0.6, 0.8, 0.9])
    assert otf.has_depth


@pytest.mark.parametrize(
    ("field", "value", "match"),
    [
        ("sigma_x", np.zeros((1, 1)), "sigma_x"),
        ("rho", np.ones((1, 1)), "rho"),
        ("intensity", np.ones((2, 2)), "shape"),
    ],
)
def test_otf_refuses_bad_tables(field, value, match):
    good = dict(
        shape=(10, 10),
        grid_x=[5.0],
        grid_y=[5.0],
        sigma_x=np.ones((1, 1)),
        sigma_y=np.ones((1, 1)),
        rho=np.zeros((1, 1)),
        intensity=np.ones((1, 1)),
        counts=np.ones((1, 1)),
    )
    good[field] = value
    with pytest.raises(ValueError, match=match):
        OpticalTransferFunction(**good)


def test_background_level_of_a_noise_frame():
    sensor = Sensor()  # offset 10 DN, 8 e⁻ read noise at 0.4 DN/e⁻: σ ≈ 3.2 DN
    image = sensor.record(np.zeros((400, 400)), 3)
    level = background_level(image)
    assert abs(level.level - sensor.offset) < 0.1
    assert abs(level.noise - 0.4 * 8.0) < 0.15


def test_otf_measured_on_rendered_images_matches_their_spots(sparse_frames, otfs):
    """Measured σ and intensity per region against the simulator's truth.

    The truth: the median σ of the particle images rendered in the region (each a
    pixel-integrated Gaussian whose σ grows with defocus away from Z = 0). The fit of an
    isolated image is unbiased at this signal (σ from about 2000 e⁻ of 6000 e⁻ on the
    sensor, 3 DN of noise), but the region's median over depths is not the median of
    the fitted spots' σ exactly (the fitted population is the isolated, bright-enough
    one) and the sheet dims particles off its centre: 4 % on σ and 5 % on intensity.
    """
    _, frames = sparse_frames
    for frame, otf in zip(frames, otfs, strict=True):
        edges = np.concatenate([[-np.inf], 0.5 * (otf.grid_x[1:] + otf.grid_x[:-1]), [np.inf]])
        seen = frame.visible
        region = np.searchsorted(edges, frame.xy[seen, 0]) - 1
        for k in range(otf.grid_x.size):
            truth = np.median(frame.sigma[seen][region == k])
            assert otf.sigma_x[0, 0, k] == pytest.approx(truth, rel=0.04)
            assert otf.sigma_y[0, 0, k] == pytest.approx(truth, rel=0.04)
            electrons = np.median(frame.electrons[seen][region == k])
            assert otf.intensity[0, 0, k] == pytest.approx(0.4 * electrons, rel=0.05)
        assert np.all(otf.rho == 0)  # round spots: no significant tilt
        assert otf.background == pytest.approx(10.0, abs=0.2)


def test_otf_measurement_says_how_many_particles_it_lacks(sparse_frames):
    _, frames = sparse_frames
    with pytest.raises(ValueError, match=r"too few isolated.*needed in each of the 4 x 4"):
        measure_camera_otf(frames[0].image, regions=(4, 4), min_per_region=200)
    with pytest.raises(ValueError, match="needs at least"):
        measure_otf([np.full((64, 64), 10, dtype=np.uint16)])


def test_otf_per_depth_slab_from_reconstructed_particles(rig_and_box, sparse_frames, otfs):
    """refine_otf: σ per region and depth slab against the rendered spots' truth."""
    from ptv.reconstruct import reconstruct, refine_otf

    rig, box = rig_and_box
    truth, frames = sparse_frames
    images = [f.image for f in frames]
    first = reconstruct(images, rig.cameras, otfs, box)
    refined = refine_otf(images, first.positions, first.xy, otfs, depth_slabs=2,
                         min_per_cell=10)  # fmt: skip
    for frame, otf in zip(frames, refined, strict=True):
        assert otf.has_depth and otf.sigma_x.shape == (2, 1, 2)
        mid = 0.5 * (otf.grid_z[0] + otf.grid_z[1])
        for slab, near in enumerate((truth[:, 2] < mid, truth[:, 2] >= mid)):
            sel = frame.visible & near
            assert np.median(otf.sigma_x[slab]) == pytest.approx(
                np.median(frame.sigma[sel]), rel=0.04
            )
    with pytest.raises(ValueError, match="too few isolated reconstructed"):
        refine_otf(images, first.positions, first.xy, otfs, depth_slabs=8, min_per_cell=40)
