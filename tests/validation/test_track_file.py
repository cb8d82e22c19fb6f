"""Reading a tracks CSV: the columns, the optional fit, and one line per bad input."""

import numpy as np
import pytest

from validation.score.track_file import read_tracks


def _write(tmp_path, text: str):
    path = tmp_path / "tracks.csv"
    path.write_text(text)
    return path


def test_tracks_and_their_fit_are_read(tmp_path):
    path = _write(
        tmp_path,
        "frame,track,x,y,z,vx,vy,vz,note\n"
        "0,7,0.001,0.002,0.0,0.1,0.2,0.3,a\n"
        "1,7,0.0011,0.002,0.0,0.1,0.2,0.3,b\n"
        "0,3,-0.01,0.0,0.0005,0,0,0,c\n",
    )
    tracks = read_tracks(path)
    np.testing.assert_array_equal(tracks.track, [7, 7, 3])
    np.testing.assert_array_equal(tracks.frame, [0, 1, 0])
    np.testing.assert_allclose(tracks.position[1], [0.0011, 0.002, 0.0])
    np.testing.assert_allclose(tracks.velocity[0], [0.1, 0.2, 0.3])
    assert tracks.acceleration is None


@pytest.mark.parametrize(
    ("rows", "message"),
    [
        ("1,0,0,0,0\n1,0,0,0,0\n", r"line 3: track 1 frame 0 given twice"),
        ("1,5,0,0,0\n2,0,0,0,0\n1,4,0,0,0\n", r"line 4: track 1 frame 4 after frame 5"),
        ("1,0,0,nan,0\n", r"line 2, column y: nan \(every coordinate must be a finite"),
        ("1,0,0,inf,0\n", r"line 2, column y"),
        ("1,0.5,0,0,0\n", r"line 2, column frame: '0.5' is not an integer"),
        ("-1,0,0,0,0\n", r"line 2, column track: track id -1 is negative"),
        ("2.5,0,0,0,0\n", r"line 2, column track: '2.5' is not an integer"),
        ("1,0,0,0\n", r"line 2: 4 values for the 5 columns"),
        ("", r"no tracks"),
    ],
)
def test_bad_rows_are_named_by_file_and_line(tmp_path, rows, message):
    path = _write(tmp_path, "track,frame,x,y,z\n" + rows)
    with pytest.raises(ValueError, match=message) as err:
        read_tracks(path)
    assert str(path) in str(err.value) and "\n" not in str(err.value)


def test_a_missing_column_and_a_missing_file(tmp_path):
    with pytest.raises(ValueError, match=r"line 1: no column 'frame'"):
        read_tracks(_write(tmp_path, "track,x,y,z\n1,0,0,0\n"))
    with pytest.raises(ValueError, match="no such file"):
        read_tracks(tmp_path / "absent.csv")


def test_track_ids_beyond_double_precision_stay_apart(tmp_path):
    """Ids of 2⁶⁰ and 2⁶⁰ + 1 are two tracks: read through float64 they would merge."""
    big = 2**60
    path = _write(
        tmp_path, f"track,frame,x,y,z\n{big},0,0,0,0\n{big + 1},0,0.001,0,0\n{big},1,0,0,0\n"
    )
    tracks = read_tracks(path)
    np.testing.assert_array_equal(tracks.track, [big, big + 1, big])
    np.testing.assert_allclose(tracks.position[1], [0.001, 0, 0])
