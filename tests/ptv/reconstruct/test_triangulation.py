"""Candidates from peaks: exact projections of known points are all found again."""

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from ptv.reconstruct._grid import point_grid
from ptv.reconstruct.mapping import Mappings, voxel_size
from ptv.reconstruct.peaks import find_peaks
from ptv.reconstruct.triangulation import (
    epipolar_lengths,
    ray_box_range,
    select_candidates,
    triangulate_candidates,
)


@given(
    origin=st.tuples(*[st.floats(-3, 3)] * 3),
    direction=st.tuples(*[st.floats(-1, 1)] * 3).filter(lambda v: np.linalg.norm(v) > 0.1),
)
def test_a_line_enters_and_leaves_the_box_on_its_faces(origin, direction):
    box = ((-1.0, -0.5, -0.2), (1.0, 0.5, 0.2))
    o = np.array([origin])
    v = np.array([direction]) / np.linalg.norm(direction)
    t0, t1 = ray_box_range(o, v, box)
    lower, upper = (np.asarray(b) for b in box)
    if np.isnan(t0[0]):  # it misses: no point of the line within reach is inside
        t = np.linspace(-10, 10, 40001)
        pts = o + t[:, None] * v
        assert not np.any(np.all((pts > lower + 1e-9) & (pts < upper - 1e-9), axis=1))
        return
    for t in (t0[0], t1[0]):
        p = o[0] + t * v[0]
        assert np.all(p >= lower - 1e-9) and np.all(p <= upper + 1e-9)
    mid = o[0] + 0.5 * (t0[0] + t1[0]) * v[0]
    assert np.all(mid >= lower - 1e-9) and np.all(mid <= upper + 1e-9)


def test_exact_peaks_give_back_every_point(rig_and_box):
    rig, box = rig_and_box
    maps = Mappings(rig.cameras)
    rng = np.random.default_rng(4)
    lower, upper = (np.asarray(v) for v in box)
    truth = rng.uniform(lower, upper, (300, 3))
    peaks = []
    for c in range(4):
        xy = maps.project(c, truth)
        peaks.append(xy[np.isfinite(xy).all(axis=1)])
    grids = [point_grid(p, (256, 320)) for p in peaks]
    rays = [maps.rays(c, p) for c, p in enumerate(peaks)]
    lengths = epipolar_lengths(maps, box)
    cands = triangulate_candidates(
        maps, peaks, grids, rays, box, subset=[0, 1, 2, 3], tolerance=0.5, lengths=lengths
    )
    seen = np.all([np.isfinite(maps.project(c, truth)).all(axis=1) for c in range(4)], axis=0)
    d = np.linalg.norm(cands.points[:, None] - truth[None, seen], axis=2).min(axis=0)
    assert np.all(d < 1e-9)  # every point seen by all four cameras, to rounding
    keep = select_candidates(cands, [len(p) for p in peaks], max_uses=1)
    chosen = cands.points[keep]
    d = np.linalg.norm(chosen[:, None] - truth[None, seen], axis=2).min(axis=0)
    assert np.mean(d < 1e-9) > 0.99  # the exact ones win their peaks
    assert maps.points_projected > 0 and maps.seconds_project > 0


def test_voxel_size_of_the_rig(rig_and_box):
    rig, _box = rig_and_box
    voxel, motion = voxel_size(Mappings(rig.cameras), np.zeros(3), step=1e-5)
    # 10 µm pixels at magnification 1/6: about 61 µm
    assert 55e-6 < voxel < 65e-6
    assert motion[2] < 0.5 * motion[0]  # depth moves the images least


def test_peaks_of_separated_spots_are_found_to_a_tenth_of_a_pixel():
    from ptv.reconstruct._spots import add_spots

    rng = np.random.default_rng(2)
    xy = np.column_stack(
        [
            np.arange(10, 190, 12) + rng.uniform(-0.5, 0.5, 15),
            np.full(15, 20.0) + rng.uniform(-0.5, 0.5, 15),
        ]
    )
    image = np.zeros((40, 200))
    n = len(xy)
    add_spots(
        image,
        40,
        200,
        xy[:, 0].copy(),
        xy[:, 1].copy(),
        np.full(n, 1000.0),
        np.full(n, 0.8),
        np.full(n, 0.8),
        np.zeros(n),
        4.0,
    )
    found, value = find_peaks(image, threshold=10.0)
    assert len(found) == n
    order = np.argsort(found[:, 0])
    assert np.max(np.abs(found[order] - xy)) < 0.1
    assert np.all(value > 100)


def test_grid_mapping_interpolates_project(rig_and_box):
    from ptv.reconstruct.mapping import GridMapping

    rig, box = rig_and_box
    cam = rig.cameras[0]
    grid = GridMapping(cam, box, spacing=1e-3)
    rng = np.random.default_rng(1)
    lower, upper = (np.asarray(v) for v in box)
    inside = rng.uniform(lower, upper, (2000, 3))
    outside = inside * [1, 1, 0] + [0, 0, 0.009]  # beyond the grid: the camera answers
    for pts in (inside, outside):
        a, b = grid.project(pts), cam.project(pts)
        assert np.array_equal(np.isnan(a), np.isnan(b))
        assert np.nanmax(np.abs(a - b)) < 1e-3
    assert grid.fallback >= 2000
    rays = grid.pixel_to_ray(np.array([[100.0, 100.0]]))
    assert np.allclose(rays.directions, cam.pixel_to_ray(np.array([[100.0, 100.0]])).directions)


class _HalfView:
    """A camera that images only X < 0 (a view whose edge crosses the grid)."""

    def __init__(self, camera):
        self.camera = camera

    def project(self, points):
        xy = self.camera.project(points)
        xy[np.asarray(points)[:, 0] >= 0] = np.nan
        return xy

    def pixel_to_ray(self, xy):
        return self.camera.pixel_to_ray(xy)


def test_grid_mapping_extends_its_view_edge_instead_of_asking_the_camera(rig_and_box):
    from ptv.reconstruct.mapping import GridMapping

    rig, box = rig_and_box
    cam = _HalfView(rig.cameras[1])
    spacing = 1e-3
    grid = GridMapping(cam, box, spacing=spacing)
    rng = np.random.default_rng(2)
    lower, upper = (np.asarray(v) for v in box)
    pts = rng.uniform(lower, upper, (4000, 3))
    a, b = grid.project(pts), cam.project(pts)
    assert np.array_equal(np.isnan(a), np.isnan(b))
    # interpolated to O(h³) next to the edge too (cubic convolution of a mapping that
    # is quadratic over a 1 mm cell to well below 10⁻³ px)
    assert np.nanmax(np.abs(a - b)) < 1e-3
    # the camera is asked only beyond the edge and in the cells the edge cuts (one
    # cell's width in X), not wherever a stencil reaches past the edge (two cells)
    asked = pts[:, 0] > -grid.step[0]
    assert np.isnan(b[:, 0]).sum() < grid.fallback <= asked.sum()
