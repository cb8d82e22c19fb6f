"""Calibration plate and traverse: nominal geometry, marks, drawn imperfections."""

import numpy as np
import pytest

from simulator.target import (
    REALISTIC,
    Imperfections,
    PlateDesign,
    build_plate,
    traverse_positions,
)


def test_default_plate_is_441_dots_at_5_mm_with_three_larger_marks():
    d = PlateDesign()
    assert d.nominal_xy.shape == (441, 2)
    assert np.allclose(np.unique(np.round(d.nominal_xy[:, 0], 9)), np.arange(-10, 11) * 5e-3)
    big = d.diameters > d.dot_diameter
    assert big.sum() == 3
    marked = {tuple(ij) for ij in d.indices[big]}
    assert marked == {(0, 0), (2, 0), (0, 3)}


def test_traverse_default_is_13_planes_1_mm_apart_centred():
    z = traverse_positions()
    assert len(z) == 13 and np.allclose(np.diff(z), 1e-3) and z.mean() == pytest.approx(0)


def test_perfect_plate_puts_dots_at_nominal_positions():
    d = PlateDesign()
    z = traverse_positions(3, 2e-3)
    plate = build_plate(d, z, rng=1)
    for j, zj in enumerate(z):
        centres = plate.dot_centres(j)
        assert np.allclose(centres[:, :2], d.nominal_xy, atol=1e-15)
        assert np.allclose(centres[:, 2], zj, atol=1e-15)


def test_imperfections_have_the_drawn_statistics():
    d = PlateDesign(columns=41, rows=41)
    imp = Imperfections(dot_position_std=10e-6, traverse_std=10e-6)
    plate = build_plate(d, traverse_positions(400, 1e-4), imperfections=imp, rng=2)
    dev = plate.dot_xy - d.nominal_xy
    assert dev.std() == pytest.approx(10e-6, rel=0.05)  # 3362 samples: SE 1.2 %
    z_err = np.array([p.z_actual - p.z_nominal for p in plate.poses])
    assert z_err.std() == pytest.approx(10e-6, rel=0.15)  # 400 samples: SE 3.5 %


def test_tilt_and_bow_move_dots_out_of_the_nominal_plane():
    d = PlateDesign()
    plate = build_plate(d, [0.0, 1e-3], imperfections=REALISTIC, rng=3)
    centres = plate.dot_centres(0)
    # A tilt θx about X shifts Z by −Y sin θx… (and +X sin θy): plane slope matches tilt.
    a = np.column_stack([centres[:, 0], centres[:, 1], np.ones(len(centres))])
    slope = np.linalg.lstsq(a, centres[:, 2], rcond=None)[0]
    assert slope[0] == pytest.approx(-np.sin(REALISTIC.tilt[1]), rel=0.05)
    assert slope[1] == pytest.approx(np.sin(REALISTIC.tilt[0]), rel=0.05)
    origin = np.all(d.indices == 0, axis=1)
    assert plate.surface_height(plate.dot_xy[origin])[0] == pytest.approx(REALISTIC.bow, rel=1e-3)


@pytest.mark.parametrize("z", [[0.0], [0.0, 0.0], [0.0, np.nan]])
def test_fewer_than_two_planes_is_an_error(z):
    with pytest.raises(ValueError, match="two"):
        build_plate(PlateDesign(), z)


def test_bad_designs_name_the_field():
    with pytest.raises(ValueError, match="pitch"):
        PlateDesign(pitch=-1)
    with pytest.raises(ValueError, match="mark_diameter"):
        PlateDesign(mark_diameter=1e-3)
    with pytest.raises(ValueError, match="traverse_std"):
        Imperfections(traverse_std=-1)
