"""Reading a positions file: track ids are integers ≥ 0, in CSV and in HDF5 (the scorer
keeps −1 for "no track")."""

import h5py
import numpy as np
import pytest

from validation.score.positions import read_positions


def test_a_negative_track_id_in_a_csv_is_refused_by_file_and_line(tmp_path):
    path = tmp_path / "positions.csv"
    path.write_text("dt,snapshot,frame,x,y,z,track\n0,0,a,0,0,0,3\n0,0,b,0,0,0,-2\n")
    with pytest.raises(ValueError, match=r"line 3, column track: track id -2 is negative"):
        read_positions(path, tracks=True)


def test_a_negative_track_id_in_hdf5_is_refused_by_row(tmp_path):
    path = tmp_path / "positions.h5"
    with h5py.File(path, "w") as f:
        f["dt"] = np.zeros(2, dtype=np.int64)
        f["snapshot"] = np.zeros(2, dtype=np.int64)
        f["frame"] = np.array([b"a", b"b"])
        for axis in "xyz":
            f[axis] = np.zeros(2)
        f["track"] = np.array([4, -1], dtype=np.int64)
    with pytest.raises(ValueError, match=r"row 1, column track: track id -1 is negative"):
        read_positions(path, tracks=True)
