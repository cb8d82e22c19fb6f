"""The HDF5 field series: save∘load is the identity, and every malformed file is refused
with one line naming the file and the dataset."""

from pathlib import Path

import h5py
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from simulator.dns.diagnostics import MeasuredParameters
from simulator.dns.fieldfile import (
    FieldFileWriter,
    PeriodicFieldSeries,
    read_field_file,
    write_field_file,
)

PARAMETERS = MeasuredParameters(
    n=4,
    box_side=0.01,
    nu=1e-6,
    epsilon_injection=0.1,
    epsilon=0.099,
    kinetic_energy=0.004,
    u_rms=0.05,
    eta=5.6e-5,
    tau_eta=3.2e-3,
    taylor_microscale=1e-3,
    r_lambda=40.0,
    integral_scale=1e-3,
    eddy_time=0.02,
    kmax_eta=1.5,
)


def series(n: int = 4, t: int = 2, *, dtype=np.float64, parameters=None) -> PeriodicFieldSeries:
    rng = np.random.default_rng(n * 10 + t)
    return PeriodicFieldSeries(
        box_side=0.01,
        nu=1e-6,
        epsilon=0.1,
        times=np.cumsum(rng.uniform(0.01, 0.02, t)),
        velocity=rng.standard_normal((t, 3, n, n, n)).astype(dtype),
        parameters=parameters,
    )


@given(
    n=st.sampled_from([2, 4, 6]),
    t=st.integers(1, 3),
    dtype=st.sampled_from([np.float64, np.float32]),
    box=st.floats(1e-4, 10.0),
    with_parameters=st.booleans(),
    seed=st.integers(0, 2**32 - 1),
)
def test_save_then_load_is_the_identity(tmp_path_factory, n, t, dtype, box, with_parameters, seed):
    rng = np.random.default_rng(seed)
    original = PeriodicFieldSeries(
        box_side=box,
        nu=rng.uniform(1e-7, 1e-5),
        epsilon=rng.uniform(1e-3, 1.0),
        times=np.cumsum(rng.uniform(1e-3, 1.0, t)) - 0.5,
        velocity=rng.standard_normal((t, 3, n, n, n)).astype(dtype),
        parameters=PARAMETERS if with_parameters else None,
    )
    path = tmp_path_factory.mktemp("field") / "f.h5"
    write_field_file(path, original)
    back = read_field_file(path)
    assert back.velocity.dtype == dtype
    assert np.array_equal(back.velocity, original.velocity)
    assert np.array_equal(back.times, original.times)
    assert (back.box_side, back.nu, back.epsilon) == (box, original.nu, original.epsilon)
    assert back.parameters == original.parameters and back.n == n
    assert list(path.parent.iterdir()) == [path]  # no temporary file left


def test_writer_appends_and_publishes_only_when_complete(tmp_path):
    path = tmp_path / "series.h5"
    s = series(dtype=np.float32)
    with FieldFileWriter(path, n=4, box_side=0.01, nu=1e-6, epsilon=0.1, dtype=np.float32) as w:
        for time, v in zip(s.times, s.velocity, strict=True):
            w.append(time, v)
            assert not path.exists()
        w.close(PARAMETERS)
    back = read_field_file(path)
    assert np.array_equal(back.velocity, s.velocity) and back.parameters == PARAMETERS
    with h5py.File(path) as f:
        assert f["u"].chunks == (1, 4, 4, 4)
        assert np.allclose(f["x"][()], np.arange(4) * 0.01 / 4)


def test_an_interrupted_writer_leaves_nothing(tmp_path):
    path = tmp_path / "series.h5"
    s = series()
    with (
        pytest.raises(RuntimeError),
        FieldFileWriter(path, n=4, box_side=0.01, nu=1e-6, epsilon=0.1) as w,
    ):
        w.append(s.times[0], s.velocity[0])
        raise RuntimeError("killed")
    assert list(tmp_path.iterdir()) == []


def test_writer_refuses_bad_snapshots(tmp_path):
    s = series()
    with FieldFileWriter(tmp_path / "f.h5", n=4, box_side=0.01, nu=1e-6, epsilon=0.1) as w:
        w.append(1.0, s.velocity[0])
        with pytest.raises(ValueError, match="does not follow"):
            w.append(1.0, s.velocity[1])
        with pytest.raises(ValueError, match="shape"):
            w.append(2.0, s.velocity[1, :, :2])
        bad = s.velocity[1].copy()
        bad[0, 0, 0, 0] = np.inf
        with pytest.raises(ValueError, match="NaN or infinite"):
            w.append(2.0, bad)
    with pytest.raises(ValueError, match=r"^dtype"):
        FieldFileWriter(tmp_path / "g.h5", n=4, box_side=0.01, nu=1e-6, epsilon=0.1, dtype=int)
    with pytest.raises(ValueError, match=r"^n must"):
        FieldFileWriter(tmp_path / "i.h5", n=0, box_side=0.01, nu=1e-6, epsilon=0.1)
    with pytest.raises(ValueError, match=r"^box_side"):
        FieldFileWriter(tmp_path / "h.h5", n=4, box_side=-1.0, nu=1e-6, epsilon=0.1)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f.h5"]


def _corrupt(path: Path, edit) -> None:
    with h5py.File(path, "a") as f:
        edit(f)


def _replace(name, value):
    def edit(f):
        del f[name]
        f[name] = value

    return edit


def _nan_in_v(f):
    f["v"][1, 0, 2, 3] = np.nan


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda f: f.__delitem__("w"), "missing dataset 'w'"),
        (lambda f: f.__delitem__("times"), "missing dataset 'times'"),
        (lambda f: f.attrs.__delitem__("box_side"), "missing attribute 'box_side'"),
        (lambda f: f.attrs.__setitem__("nu", -1.0), "attribute 'nu'"),
        (lambda f: f.attrs.__setitem__("epsilon", "a lot"), "attribute 'epsilon'"),
        (_nan_in_v, "dataset 'v' holds NaN"),
        (_replace("times", np.array([0.1, np.inf])), "dataset 'times' holds NaN"),
        (_replace("u", np.zeros((2, 4, 4, 3))), "dataset 'u' must have shape"),
        (_replace("u", np.zeros((2, 6, 6, 6))), "dataset 'u' has shape"),
        (_replace("w", np.zeros((3, 4, 4, 4))), "dataset 'w' has shape"),
        (_replace("u", np.zeros((2, 4, 4, 4), np.int32)), "dataset 'u' must be float64"),
        (lambda f: f.attrs.__setitem__("n", 6), "dataset 'x' is not"),
        (lambda f: f.attrs.__setitem__("box_side", 0.02), "dataset 'x' is not"),
        (_replace("times", np.array([0.2, 0.2])), "dataset 'times' is not strictly increasing"),
        (_replace("times", np.array([0.3, 0.2])), "dataset 'times' is not strictly increasing"),
        (lambda f: f["measured"].attrs.__delitem__("eta"), "group 'measured' lacks"),
    ],
)
def test_malformed_files_are_refused_naming_file_and_dataset(tmp_path, edit, message):
    path = tmp_path / "bad.h5"
    write_field_file(path, series(parameters=PARAMETERS))
    _corrupt(path, edit)
    with pytest.raises(ValueError) as info:
        read_field_file(path)
    text = str(info.value)
    assert text.startswith(f"{path}: ") and message in text and "\n" not in text


def test_a_file_that_is_not_hdf5_is_refused(tmp_path):
    path = tmp_path / "notes.h5"
    path.write_text("not HDF5")
    with pytest.raises(ValueError, match="not a readable HDF5 file"):
        read_field_file(path)


def test_write_refuses_inconsistent_series(tmp_path):
    s = series()
    bad = PeriodicFieldSeries(0.01, 1e-6, 0.1, s.times[:1], s.velocity)
    with pytest.raises(ValueError, match="1 times for 2 snapshots"):
        write_field_file(tmp_path / "f.h5", bad)
    flat = PeriodicFieldSeries(0.01, 1e-6, 0.1, s.times, s.velocity[:, :, :, :, :2])
    with pytest.raises(ValueError, match=r"shape \(T, 3, N, N, N\)"):
        write_field_file(tmp_path / "f.h5", flat)
