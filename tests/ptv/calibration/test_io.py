"""Calibration files: exact round trips, atomic writes, and clear errors for bad files."""

import h5py
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from ptv.calibration import io
from ptv.calibration.io import CalibrationFileError, load_calibrations, save_calibrations
from ptv.calibration.model_free import ModelFreeCalibration, PlaneObservation, calibrate_model_free
from ptv.calibration.tsai import TsaiCalibration
from simulator.rigs import load_rig
from simulator.target import PlateDesign, build_plate, traverse_positions

DESIGN = PlateDesign()
Z = traverse_positions(5)


@pytest.fixture(scope="module")
def calibrations():
    rig = load_rig("paper-stereo")
    plate = build_plate(DESIGN, Z, rng=0)
    rng = np.random.default_rng(0)
    out = {}
    for name, camera in zip(rig.camera_names, rig.cameras, strict=True):
        obs = []
        for j, z in enumerate(Z):
            px = camera.project(plate.dot_centres(j))
            ok = np.isfinite(px).all(axis=1)
            noisy = px[ok] + rng.normal(0.0, 0.05, (int(ok.sum()), 2))
            obs.append(PlaneObservation(z, noisy, DESIGN.nominal_xy[ok]))
        out[f"{name}-model-free"] = calibrate_model_free(obs, camera.lens.sensor_size)
    out["tsai"] = TsaiCalibration(
        rotation=Rotation.from_rotvec([0.05, -0.6, 0.02]).as_matrix(),
        translation=np.array([0.01, -0.002, 1.0]),
        focal_length=0.0512,
        kappa1=-31.7,
        sx=1.0013,
        principal_point=(1021.3, 546.9),
        pixel_size=(5.5e-6, 5.5e-6),
        reprojection_rms=0.31,
        n_points=5733,
        free_principal_point=True,
    )
    return out


@pytest.fixture(scope="module")
def reloaded(calibrations, tmp_path_factory):
    path = tmp_path_factory.mktemp("cal") / "rig.h5"
    save_calibrations(path, calibrations, metadata={"dataset": "run-01", "planes": 5})
    return path, load_calibrations(path)


def test_round_trip_keeps_names_order_types_and_fields(calibrations, reloaded):
    path, loaded = reloaded
    assert list(loaded) == list(calibrations)
    for name, cal in calibrations.items():
        assert type(loaded[name]) is type(cal)
    tsai = loaded["tsai"]
    ref = calibrations["tsai"]
    assert tsai.parameters == ref.parameters
    assert (tsai.rotation == ref.rotation).all() and tsai.pixel_size == ref.pixel_size
    assert (tsai.reprojection_rms, tsai.n_points, tsai.free_principal_point) == (0.31, 5733, True)
    mf, ref = loaded["cam1-model-free"], calibrations["cam1-model-free"]
    assert isinstance(mf, ModelFreeCalibration)
    assert mf.image_size == ref.image_size and mf.z_ref == ref.z_ref
    assert (mf.line_parameters == ref.line_parameters).all() and (mf.line_rms == ref.line_rms).all()
    for a, b in zip(mf.planes, ref.planes, strict=True):
        assert a.z == b.z and (a.residual_px == b.residual_px).all()
        assert (a.to_world.coefficients == b.to_world.coefficients).all()
        assert (a.to_pixel.scale == b.to_pixel.scale).all()
        assert (a.hull.points == b.hull.points).all()
    with h5py.File(path) as f:
        assert f.attrs["dataset"] == "run-01" and f.attrs["format_version"] == io.FORMAT_VERSION


@given(
    xy=st.lists(st.tuples(st.floats(-100, 2150), st.floats(-100, 1190)), min_size=1, max_size=20)
)
def test_pixel_to_ray_is_reproduced_exactly(calibrations, reloaded, xy):
    pixels = np.array(xy)
    for name, cal in calibrations.items():
        a, b = cal.pixel_to_ray(pixels), reloaded[1][name].pixel_to_ray(pixels)
        assert np.array_equal(a.origins, b.origins, equal_nan=True)
        assert np.array_equal(a.directions, b.directions, equal_nan=True)


@given(
    points=st.lists(
        st.tuples(st.floats(-0.06, 0.06), st.floats(-0.06, 0.06), st.floats(-8e-3, 8e-3)),
        min_size=1,
        max_size=10,
    )
)
def test_project_is_reproduced_exactly(calibrations, reloaded, points):
    world = np.array(points)
    for name, cal in calibrations.items():
        assert np.array_equal(cal.project(world), reloaded[1][name].project(world), equal_nan=True)


def test_overwrite_is_atomic(calibrations, tmp_path, monkeypatch):
    path = tmp_path / "rig.h5"
    save_calibrations(path, {"tsai": calibrations["tsai"]})
    before = path.read_bytes()

    def broken(group, cal):
        group.create_dataset("rotation", data=np.eye(3))
        raise RuntimeError("disk full")

    codec = io._BY_TYPE[TsaiCalibration]
    monkeypatch.setitem(
        io._BY_TYPE, TsaiCalibration, io._Codec("tsai", TsaiCalibration, broken, codec.read)
    )
    with pytest.raises(RuntimeError, match="disk full"):
        save_calibrations(path, {"a": calibrations["tsai"]})
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rig.h5"]


def test_unsupported_type_and_bad_names(calibrations, tmp_path):
    with pytest.raises(TypeError, match="cannot save a dict"):
        save_calibrations(tmp_path / "x.h5", {"cam": {}})
    with pytest.raises(ValueError, match="camera name: expected 1 to 64 letters"):
        save_calibrations(tmp_path / "x.h5", {"a/b": calibrations["tsai"]})
    with pytest.raises(ValueError, match="no calibrations"):
        save_calibrations(tmp_path / "x.h5", {})
    with pytest.raises(ValueError, match="reserved"):
        save_calibrations(tmp_path / "x.h5", {"a": calibrations["tsai"]}, metadata={"format": "x"})
    assert not (tmp_path / "x.h5").exists()


# -- bad files --------------------------------------------------------------------------------
def test_missing_file(tmp_path):
    with pytest.raises(FileNotFoundError, match=r"nothere\.h5"):
        load_calibrations(tmp_path / "nothere.h5")


def test_a_folder_is_no_file(tmp_path):
    with pytest.raises(CalibrationFileError, match="is a folder, not a calibration file"):
        load_calibrations(tmp_path)


def test_not_hdf5(tmp_path):
    path = tmp_path / "notes.h5"
    path.write_text("camera 1: f = 50 mm\n")
    with pytest.raises(CalibrationFileError, match=r"notes\.h5 is not a synptv calibration"):
        load_calibrations(path)


def test_truncated_file(calibrations, reloaded, tmp_path):
    data = reloaded[0].read_bytes()
    path = tmp_path / "cut.h5"
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(CalibrationFileError, match=r"cut\.h5"):
        load_calibrations(path)


def test_foreign_hdf5(tmp_path):
    path = tmp_path / "other.h5"
    with h5py.File(path, "w") as f:
        f.create_dataset("images", data=np.zeros((2, 2)))
    with pytest.raises(CalibrationFileError, match=r"other\.h5.*another program"):
        load_calibrations(path)


def _copy_and_edit(src, dst, edit):
    dst.write_bytes(src.read_bytes())
    with h5py.File(dst, "r+") as f:
        edit(f)
    return dst


def test_newer_version(reloaded, tmp_path):
    def bump(f):
        f.attrs["format_version"] = io.FORMAT_VERSION + 1

    path = _copy_and_edit(reloaded[0], tmp_path / "new.h5", bump)
    with pytest.raises(CalibrationFileError, match=r"new\.h5.*newer.*upgrade"):
        load_calibrations(path)


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda f: f["cameras/cam1-model-free"].__delitem__("grid_x"), "corrupt or incomplete"),
        (lambda f: f["cameras/tsai"].attrs.__delitem__("kappa1"), "corrupt or incomplete"),
        (lambda f: f["cameras/tsai/rotation"].__setitem__((), 2 * np.eye(3)), "corrupt"),
        (lambda f: f["cameras/tsai"].attrs.__setitem__("model", "magic"), "unknown calibration"),
        (lambda f: f.__delitem__("cameras"), "no cameras"),
        (lambda f: f.attrs.__setitem__("format_version", "one"), "format_version"),
    ],
)
def test_damaged_entries(reloaded, tmp_path, edit, message):
    path = _copy_and_edit(reloaded[0], tmp_path / "bad.h5", edit)
    with pytest.raises(CalibrationFileError, match=rf"bad\.h5.*{message}"):
        load_calibrations(path)


@pytest.mark.parametrize("method", ["pinhole", "soloff"])
def test_baselines_round_trip_exactly(tmp_path, method):
    from ptv.calibration.methods import CameraSheet, calibrate
    from simulator.rigs import load_rig
    from simulator.target import Imperfections, PlateDesign, build_plate, traverse_positions
    from validation.truth.calibration_errors import synthetic_plane_dots

    rig = load_rig("paper-stereo")
    plate = build_plate(PlateDesign(), traverse_positions(7), imperfections=Imperfections(), rng=0)
    dots = synthetic_plane_dots(rig.cameras[:1], plate, noise_px=0.05, rng=1)[0]
    lens = rig.cameras[0].lens
    sheet = CameraSheet(lens.sensor_size, lens.pixel_pitch, lens.focal_length)
    cal = calibrate(method, [d.observation() for d in dots], sheet)
    back = load_calibrations(save_calibrations(tmp_path / "c.h5", {"cam1": cal}))["cam1"]
    rng = np.random.default_rng(2)
    xy = rng.uniform([600, 100], [1400, 1000], (100, 2))
    points = np.column_stack([rng.uniform(-0.04, 0.04, (100, 2)), rng.uniform(-5e-3, 5e-3, 100)])
    assert np.array_equal(cal.pixel_to_ray(xy).directions, back.pixel_to_ray(xy).directions)
    assert np.array_equal(cal.project(points), back.project(points), equal_nan=True)
