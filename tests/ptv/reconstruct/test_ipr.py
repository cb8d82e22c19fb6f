"""Iterative particle reconstruction on rendered images of a small four-camera rig."""

import dataclasses

import numpy as np
import pytest
from scipy.spatial import cKDTree

from ptv.reconstruct import IPRSettings, OpticalTransferFunction, reconstruct


def _score(truth, found, voxel):
    """Found fraction (one to one within one voxel on each axis), ghost fraction and
    the matched particles' errors (m)."""
    d, i = cKDTree(found).query(truth, p=np.inf)
    hit = d <= voxel
    # one to one: a reconstructed particle matched by two true ones counts once
    used = np.unique(i[hit])
    return used.size / len(truth), 1 - used.size / len(found), found[i[hit]] - truth[hit]


def test_ipr_finds_every_particle_without_ghosts(rig_and_box, otfs, renderer):
    """About 0.015 particles per pixel on 320 × 256 px images, the true cameras."""
    rig, box = rig_and_box
    truth, frames = renderer(rig, box, 700, seed=5)
    result = reconstruct([f.image for f in frames], rig.cameras, otfs, box)
    voxel = result.diagnostics.voxel
    found, ghosts, err = _score(truth, result.positions, voxel)
    # a particle needs an image on at least 3 sensors to be seen
    visible = np.sum([f.visible for f in frames], axis=0) >= 3
    assert visible.mean() > 0.98
    assert found >= 0.99 * visible.mean()
    assert ghosts <= 0.01
    d, i = cKDTree(result.positions).query(truth, p=np.inf)
    hit = d <= voxel
    projected = np.concatenate(
        [
            np.linalg.norm(cam.project(result.positions[i[hit]]) - cam.project(truth[hit]), axis=1)
            for cam in rig.cameras
        ]
    )
    assert np.sqrt(np.nanmean(projected**2)) < 0.1
    assert np.sqrt(np.mean(np.sum(err**2, axis=1))) < 0.15 * voxel
    assert result.diagnostics.iterations >= 2
    assert np.median(result.intensities) == pytest.approx(1.0, abs=0.15)


def test_shaking_pulls_a_misplaced_particle_back(rig_and_box, otfs, renderer):
    """Given the true particles, one moved by 1.5 voxels on each lateral axis: the
    shaking brings it back, and without shaking it stays where it was put."""
    rig, box = rig_and_box
    truth, frames = renderer(rig, box, 150, seed=8)
    inside = np.all(np.abs(truth) < 0.3 * np.asarray(box[1]) / 0.5, axis=1)
    k = int(np.flatnonzero(inside)[0])
    voxel = 61e-6
    start = truth.copy()
    start[k] += [1.5 * voxel, -1.5 * voxel, 0.0]
    images = [f.image for f in frames]
    base = IPRSettings(outer_iterations=0, final_shakes=8, shake_step=1.0, shake_step_min=0.05)
    shaken = reconstruct(
        images, rig.cameras, otfs, box, settings=base, initial=(start, np.ones(len(start)))
    )
    still = reconstruct(
        images,
        rig.cameras,
        otfs,
        box,
        settings=dataclasses.replace(base, final_shakes=0),
        initial=(start, np.ones(len(start))),
    )
    moved = np.linalg.norm(shaken.positions - truth[k], axis=1).min()
    stayed = np.linalg.norm(still.positions - truth[k], axis=1).min()
    assert stayed > 1.4 * voxel
    assert moved < 0.2 * voxel
    assert shaken.diagnostics.residual_energy.size == 0
    # the residual energy drops when the particle is back in place
    energy = [np.sum(np.square(r)) for r in (shaken.residuals, still.residuals)]
    assert energy[0] < 0.5 * energy[1]


def test_ipr_refuses_bad_input(rig_and_box, otfs, sparse_frames):
    rig, box = rig_and_box
    _, frames = sparse_frames
    images = [f.image for f in frames]
    with pytest.raises(ValueError, match="at least 3 cameras, got 2"):
        reconstruct(images[:2], rig.cameras[:2], otfs[:2], box)
    with pytest.raises(ValueError, match="one image and one OTF per camera"):
        reconstruct(images[:3], rig.cameras, otfs, box)
    cropped = [images[0][:-1], *images[1:]]
    with pytest.raises(ValueError, match=r"camera 0 has shape \(255, 320\).*\(256, 320\)"):
        reconstruct(cropped, rig.cameras, otfs, box)
    nan = [images[0].astype(float), *images[1:]]
    nan[0][3, 3] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        reconstruct(nan, rig.cameras, otfs, box)
    with pytest.raises(ValueError, match="box"):
        reconstruct(images, rig.cameras, otfs, ((0, 0, 0), (0, 0, 0)))
    with pytest.raises(ValueError, match="OpticalTransferFunction"):
        reconstruct(images, rig.cameras, [None] * 4, box)


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("tolerance", 0.0),
        ("shake_step_min", 2.0),
        ("intensity_threshold", 1.5),
        ("outer_iterations", -1),
        ("epipolar_samples", 1),
        ("peak_uses", 0),
        ("radius_sigmas", 1.0),
        ("min_cameras", 1),
        ("camera_ratio", True),
    ],
)
def test_settings_are_validated(field, value):
    with pytest.raises(ValueError, match=field):
        IPRSettings(**{field: value})


def test_three_cameras_work_and_a_given_otf_is_accepted(rig_factory, renderer):
    rig, box = rig_factory(3)
    truth, frames = renderer(rig, box, 150, seed=21)
    otfs = [OpticalTransferFunction.uniform((256, 320), 0.68, intensity=2300.0) for _ in range(3)]
    result = reconstruct([f.image for f in frames], rig.cameras, otfs, box)
    found, ghosts, _ = _score(truth, result.positions, result.diagnostics.voxel)
    assert found > 0.95
    assert ghosts < 0.03


def test_grid_mappings_built_once_reconstruct_as_built_each_time(rig_and_box, otfs, renderer):
    from ptv.reconstruct import grid_mappings

    rig, box = rig_and_box
    _truth, frames = renderer(rig, box, 300, seed=5)
    images = [f.image for f in frames]
    settings = IPRSettings(mapping_grid=16, outer_iterations=3)
    each = reconstruct(images, rig.cameras, otfs, box, settings=settings)
    grids = grid_mappings(rig.cameras, box, settings)
    once = reconstruct(images, grids, otfs, box, settings=settings)
    assert len(once.positions) > 250
    assert np.array_equal(each.positions, once.positions)
    assert np.array_equal(each.intensities, once.intensities)


def test_a_loop_stopped_by_its_cap_says_it_did_not_converge(rig_and_box, otfs, renderer):
    """One outer iteration adds the particles and cannot converge (convergence needs two
    iterations with one camera fewer); the default loop converges before its cap."""
    rig, box = rig_and_box
    _, frames = renderer(rig, box, 700, seed=5)
    images = [f.image for f in frames]
    capped = reconstruct(images, rig.cameras, otfs, box, settings=IPRSettings(outer_iterations=1))
    assert not capped.diagnostics.converged
    full = reconstruct(images, rig.cameras, otfs, box)
    assert full.diagnostics.converged
    assert full.diagnostics.iterations < IPRSettings().outer_iterations
