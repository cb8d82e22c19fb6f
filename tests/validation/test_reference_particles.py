"""Reading the particles MyPTV and OpenPTV shipped, and comparing particle sets."""

import numpy as np
import pytest

from validation.reference_particles import agreement, read_myptv_particles, read_rt_is


def test_myptv_particles_by_recorded_frame_in_m(tmp_path):
    path = tmp_path / "particles"
    path.write_text(
        "6.432\t17.481\t-3.761\t49\t36\t43\t0.020\t0.000\n"
        "31.282\t55.075\t4.796\t8\t9\t6\t0.016\t0.000\n"
        "1.0\t2.0\t3.0\t1\t2\t3\t0.01\t2.000\n"
    )
    frames = read_myptv_particles(path, first_frame=1)
    assert sorted(frames) == [1, 3]
    np.testing.assert_allclose(frames[1][0], [6.432e-3, 17.481e-3, -3.761e-3])
    assert frames[3].shape == (1, 3)


def test_openptv_rt_is_in_m_and_a_wrong_count_named(tmp_path):
    path = tmp_path / "rt_is.10001"
    path.write_text("2\n   1    22.159    41.050     9.228  128  131  203  162\n")
    with pytest.raises(ValueError, match=r"rt_is\.10001: says 2 particles, holds 1"):
        read_rt_is(path)
    path.write_text("1\n   1    22.159    41.050     9.228  128  131  -1  162\n")
    np.testing.assert_allclose(read_rt_is(path), [[22.159e-3, 41.05e-3, 9.228e-3]])


def test_agreement_counts_reference_particles_with_a_found_one_near():
    reference = {7: np.array([[0.0, 0.0, 0.0], [1e-3, 0.0, 0.0], [2e-3, 0.0, 0.0]])}
    found = {7: np.array([[0.05e-3, 0.0, 0.0], [1.0e-3, 0.2e-3, 0.0]]), 8: np.zeros((1, 3))}
    result = agreement(found, reference)
    assert list(result) == [7]
    assert result[7]["reference"] == 3 and result[7]["found"] == 2
    assert result[7]["within"] == pytest.approx(1 / 3)
    assert result[7]["median_mm"] == pytest.approx(0.2)
