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


def test_otf_pools_the_isolated_images_of_several_exposures(rig_and_box, renderer):
    """A stack of exposures: the fitted images of each are pooled (the counts add up on
    one region), and the pooled σ still matches the rendered spots' truth (4 %, as
    above); one exposure short of the count asked for raises TooFewIsolatedImages."""
    from ptv.reconstruct import TooFewIsolatedImages

    rig, box = rig_and_box
    frames = [renderer(rig, box, 600, seed=seed)[1][0] for seed in (21, 22)]
    alone = [measure_camera_otf(f.image, regions=(1, 1), min_per_region=1) for f in frames]
    pooled = measure_camera_otf(
        np.stack([f.image for f in frames]), regions=(1, 1), min_per_region=1
    )
    assert pooled.counts.sum() == sum(o.counts.sum() for o in alone)
    truth = np.median(np.concatenate([f.sigma[f.visible] for f in frames]))
    assert pooled.sigma_x[0, 0, 0] == pytest.approx(truth, rel=0.04)
    with pytest.raises(TooFewIsolatedImages, match="in 1 exposures"):
        measure_camera_otf(
            frames[0].image, regions=(1, 1), min_per_region=alone[0].counts.sum() + 1
        )


def test_run_otf_reads_further_exposures_only_while_a_slab_lacks_images(rig_and_box, renderer):
    """measure_run_otf pools the next exposure only when a depth slab holds too few
    isolated images, and says how many it pooled when even all of them are too few."""
    from ptv.pipeline.reconstructed import measure_run_otf
    from ptv.reconstruct import (
        IPRSettings,
        TooFewIsolatedImages,
        measure_otf,
        reconstruct,
        refine_otf,
    )

    rig, box = rig_and_box
    exposures = [[f.image for f in renderer(rig, box, 600, seed=s)[1]] for s in (31, 32, 33)]
    flat = measure_otf(exposures[0], regions=(1, 1))
    first = reconstruct(
        exposures[0], rig.cameras, flat, box, settings=IPRSettings(outer_iterations=10)
    )
    one = refine_otf(exposures[0], first.positions, first.xy, flat, depth_slabs=2, min_per_cell=1)
    needed = min(int(o.counts.min()) for o in one) + 1
    read = []

    def recording():
        for images in exposures:
            read.append(1)
            yield images

    otfs = measure_run_otf(recording(), rig.cameras, box, IPRSettings(), depth_slabs=2,
                           min_per_cell=needed)  # fmt: skip
    assert len(read) == 2 and min(int(o.counts.min()) for o in otfs) >= needed
    with pytest.raises(TooFewIsolatedImages, match=r"pooled over 3 exposures"):
        measure_run_otf(iter(exposures), rig.cameras, box, IPRSettings(), depth_slabs=2,
                        min_per_cell=10**6)  # fmt: skip


def test_the_defocus_law_fills_a_middle_slab_without_images():
    """Fitted images at the outer depths only, σ from a known defocus law (a 0.63 px
    spot, a blur of 0.03 px per mm added in quadrature, focused 1 mm off the centre) with
    2 % noise and a few hidden-neighbour outliers: the middle slab's σ comes back within
    1 % of the law at its centre; its ρ and intensity are the medians over all depths."""
    from ptv.reconstruct.otf_measure import _defocus_fill

    rng = np.random.default_rng(3)
    z = np.concatenate([rng.uniform(-0.015, -0.005, 300), rng.uniform(0.005, 0.015, 300)])

    def law(depth):
        return np.sqrt(0.63**2 + (30.0 * (depth - 0.001)) ** 2)

    fitted = np.zeros((len(z), 7))
    fitted[:, 0] = rng.normal(1000.0, 50.0, len(z))
    fitted[:, 3] = law(z) * rng.normal(1.0, 0.02, len(z))
    fitted[:, 4] = fitted[:, 3]
    fitted[:20, 3:5] *= 1.5  # hidden neighbours
    edges = np.linspace(-0.015, 0.015, 4)
    tables = {k: np.full((3, 1, 1), np.nan) for k in ("sigma_x", "sigma_y", "rho", "intensity")}
    short = np.array([False, True, False])[:, None, None]
    zeros = np.zeros(len(z), dtype=int)
    _defocus_fill(tables, short, fitted, z, zeros, zeros, edges)
    assert tables["sigma_x"][1, 0, 0] == pytest.approx(law(0.0), rel=0.01)
    assert tables["sigma_y"][1, 0, 0] == tables["sigma_x"][1, 0, 0]
    assert tables["intensity"][1, 0, 0] == pytest.approx(1000.0, rel=0.01)
    assert tables["rho"][1, 0, 0] == 0.0
    assert np.isnan(tables["sigma_x"][[0, 2]]).all()  # the others are left alone


def test_the_defocus_law_recovers_an_exact_law_and_gives_no_width_where_it_has_none():
    """σ² = 1 − z² sampled exactly at |z| ≤ 0.9: the law gives it back at the centre, and
    NaN at |z| = 2, where σ² would be negative."""
    from ptv.reconstruct import defocus_law

    z = np.linspace(-0.9, 0.9, 19)
    sigma = defocus_law(z, np.sqrt(1.0 - z**2), np.array([0.0, 0.5, 2.0, -2.0]))
    assert sigma[:2] == pytest.approx([1.0, np.sqrt(0.75)], rel=1e-9)
    assert np.isnan(sigma[2:]).all()
