"""``synptv export``: OpenPTV reads the export without edits and its files put the dots
and particles where the simulator's truth has them; the MyPTV export holds the
dataset's images and a camera guess that projects like the rig's pinhole; bad input is
a one-line error that writes nothing."""

import csv
import dataclasses
import json
import shutil
from importlib import resources
from pathlib import Path

import cv2
import h5py
import numpy as np
import pytest
import tifffile

from validation.cli import main

#: The paper-stereo rig with a sensor of 512 × 272 pixels of 22 µm (the same field,
#: 16 times fewer pixels to render).
SMALL_SENSOR = {
    "sensor_size = [2048, 1088]": "sensor_size = [512, 272]",
    "pixel_pitch = 5.5e-6": "pixel_pitch = 22e-6",
}
#: The rig's windows, as its TOML file gives them: 15 mm of glass of n = 1.49
#: (the default window glass) between air and water.
GLASS_MM, N_AIR, N_GLASS, N_WATER = 15.0, 1.0, 1.49, 1.333


def small_rig(folder: Path) -> Path:
    text = (resources.files("simulator") / "rig_presets" / "paper-stereo.toml").read_text()
    for old, new in SMALL_SENSOR.items():
        assert old in text
        text = text.replace(old, new)
    path = folder / "rig.toml"
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    """A rendered dataset: 2 cameras, 3 plate positions, 2 frame pairs per Δt."""
    root = tmp_path_factory.mktemp("export")
    argv = ["render", "--rig", str(small_rig(root)), "--out", str(root / "dataset")]
    sizes = ["--frames", "2", "--particles", "60", "--planes", "3", "--workers", "1"]
    assert main([*argv, *sizes, "--quiet"]) == 0
    return root / "dataset"


@pytest.fixture(scope="module")
def openptv(dataset):
    out = dataset.parent / "openptv"
    assert (
        main(["export", "--dataset", str(dataset), "--format", "openptv", "--out", str(out)]) == 0
    )
    return out


@pytest.fixture(scope="module")
def myptv(dataset):
    out = dataset.parent / "myptv"
    assert main(["export", "--dataset", str(dataset), "--format", "myptv", "--out", str(out)]) == 0
    return out


def experiment(dataset: Path) -> dict:
    return json.loads((dataset / "experiment.json").read_text())


# -- OpenPTV, read by optv ------------------------------------------------------------


def test_optv_reads_the_parameter_files(openptv, dataset):
    parameters = pytest.importorskip("optv.parameters")
    spec = experiment(dataset)
    control = parameters.ControlParams(2)
    control.read_control_par(str(openptv / "parameters/ptv.par"))
    assert control.get_num_cams() == 2
    assert tuple(control.get_image_size()) == (512, 272)
    assert tuple(control.get_pixel_size()) == pytest.approx((0.022, 0.022))
    media = control.get_multimedia_params()
    assert media.get_n1() == pytest.approx(N_AIR)
    assert media.get_n2()[0] == pytest.approx(N_GLASS)
    assert media.get_n3() == pytest.approx(N_WATER)
    assert media.get_d()[0] == pytest.approx(GLASS_MM)
    for c in range(2):
        assert (openptv / control.get_img_base_name(c)).is_file()
        assert (openptv / control.get_cal_img_base_name(c)).is_file()

    for k in range(len(spec["dt"])):
        sequence = parameters.SequenceParams(num_cams=2)
        sequence.read_sequence_par(str(openptv / f"parameters/sequence_dt{k}.par"), 2)
        numbers = range(sequence.get_first(), sequence.get_last() + 1)
        assert len(numbers) == 2 * spec["frames_per_dt"]
        for c in range(2):
            base = sequence.get_img_base_name(c)
            assert all((openptv / f"{base}{n}").is_file() for n in numbers)

    volume = parameters.VolumeParams()
    volume.read_volume_par(str(openptv / "parameters/criteria.par"))
    assert volume.get_X_lay()[0] < -45 and volume.get_X_lay()[1] > 45  # the 100 mm sheet
    assert volume.get_Zmin_lay()[0] < -5 and volume.get_Zmax_lay()[0] > 5  # its 10 mm
    assert 0 < volume.get_eps0() < 0.1
    for name in ("targ_rec.par", "detect_plate.par"):
        target = parameters.TargetParams()
        target.read(str(openptv / "parameters" / name))
        assert all(0 < t < 256 for t in target.get_grey_thresholds(2))
    tracking = parameters.TrackingParams()
    tracking.read_track_par(str(openptv / "parameters/track.par"))
    assert tracking.get_dvxmin() < 0 < tracking.get_dvxmax()


def optv_projection(openptv: Path, camera: str, points_mm: np.ndarray, glass: bool = True):
    """Pixels of world points (mm) through the exported orientation and ptv.par."""
    calibration = pytest.importorskip("optv.calibration")
    parameters = pytest.importorskip("optv.parameters")
    imgcoord = pytest.importorskip("optv.imgcoord")
    transforms = pytest.importorskip("optv.transforms")
    control = parameters.ControlParams(2)
    control.read_control_par(str(openptv / "parameters/ptv.par"))
    cal = calibration.Calibration()
    cal.from_file(
        str(openptv / f"cal/{camera}.tif.ori").encode(),
        str(openptv / f"cal/{camera}.tif.addpar").encode(),
    )
    media = control.get_multimedia_params()
    if not glass:  # no refraction: every medium air
        media.set_layers(np.array([1.0]), np.array([GLASS_MM]))
        media.set_n3(1.0)
    metric = imgcoord.image_coordinates(points_mm, cal, media)
    return transforms.convert_arr_metric_to_pixel(metric, control)


def test_exported_orientations_project_the_true_dots_onto_their_images(openptv, dataset):
    """The .ori guesses (pose, rotation, principal point and distance, glass vector in
    OpenPTV's conventions and units) put every true dot centre within 1 px of the
    renderer's image of it: only the lens distortion and the sensor tilt, which OpenPTV
    has no term for, are missing; without the window the guess is tens of px off."""
    with h5py.File(dataset / "truth.h5", "r") as truth:
        dots = truth["plate/dots_world"][:] * 1e3
        for camera in ("cam1", "cam2"):
            seen = truth[f"plate/{camera}/dots_on_sensor"][:]
            xy = truth[f"plate/{camera}/dots_xy"][:]
            for j in range(len(dots)):
                pixels = optv_projection(openptv, camera, dots[j])
                error = np.linalg.norm(pixels - xy[j], axis=1)[seen[j]]
                assert seen[j].sum() > 100
                assert np.max(error) < 1.0
                dry = optv_projection(openptv, camera, dots[j], glass=False)
                assert np.median(np.linalg.norm(dry - xy[j], axis=1)[seen[j]]) > 10


def test_target_files_hold_the_nominal_dots_of_each_plane(openptv, dataset):
    spec = experiment(dataset)
    pitch_mm = spec["target"]["pitch"] * 1e3
    with h5py.File(dataset / "truth.h5", "r") as truth:
        indices = truth["plate/dot_indices"][:]
        z_nominal = truth["plate/z_nominal"][:] * 1e3
        true = truth["plate/dots_world"][:] * 1e3
    for j, z in enumerate(z_nominal):
        rows = np.loadtxt(openptv / f"cal/target_plane_{j:02d}.txt")
        assert rows[:, 0].tolist() == list(range(1, len(indices) + 1))
        np.testing.assert_allclose(rows[:, 1:3], indices * pitch_mm, atol=1e-6)
        np.testing.assert_allclose(rows[:, 3], z, atol=1e-6)
        assert np.max(np.abs(rows[:, 1:] - true[j])) < 0.5  # the plate's small errors


def test_optv_finds_the_dots_where_the_target_files_project(openptv, dataset):
    """optv's own dot detection (detect_plate.par) on an exported plate image finds a dot
    within 1 px of nearly every target-file point projected with the exported
    orientation."""
    parameters = pytest.importorskip("optv.parameters")
    segmentation = pytest.importorskip("optv.segmentation")
    control = parameters.ControlParams(2)
    control.read_control_par(str(openptv / "parameters/ptv.par"))
    plate = parameters.TargetParams()
    plate.read(str(openptv / "parameters/detect_plate.par"))
    image = tifffile.imread(openptv / "cal/cam1/plane_01.tif")
    assert image.dtype == np.uint8
    found = np.array([t.pos() for t in segmentation.target_recognition(image, plate, 0, control)])
    targets = np.loadtxt(openptv / "cal/target_plane_01.txt")[:, 1:]
    with h5py.File(dataset / "truth.h5", "r") as truth:
        seen = truth["plate/cam1/dots_on_sensor"][1]
    projected = optv_projection(openptv, "cam1", targets[seen])
    nearest = np.min(np.linalg.norm(projected[:, None] - found[None], axis=2), axis=1)
    assert np.mean(nearest < 1.0) > 0.9


def test_particle_images_are_the_exposures_frames_csv_names(openptv, dataset):
    """Every OpenPTV image is its dataset exposure shifted to 8 bits, one shift for all,
    under the number frames.csv gives it."""
    spec = experiment(dataset)
    with (openptv / "frames.csv").open() as stream:
        rows = list(csv.DictReader(stream))
    assert len(rows) == 2 * len(spec["dt"]) * spec["frames_per_dt"]
    shifts = set()
    for row in rows:
        for camera in ("cam1", "cam2"):
            original = tifffile.imread(
                dataset / f"particles/dt{row['dt']}/{camera}/{int(row['snapshot']):06d}_"
                f"{row['frame']}.tif"
            ).astype(np.int64)
            exported = tifffile.imread(openptv / f"img/dt{row['dt']}/{camera}.{row['number']}")
            assert exported.dtype == np.uint8
            matching = [
                s for s in range(9) if np.array_equal(exported, np.minimum(original >> s, 255))
            ]
            assert len(matching) == 1
            shifts.add(matching[0])
    assert len(shifts) == 1
    numbers = {(r["dt"], r["snapshot"], r["frame"]): int(r["number"]) for r in rows}
    assert numbers[("0", "0", "b")] == numbers[("0", "0", "a")] + 1
    assert numbers[("0", "1", "a")] == numbers[("0", "0", "b")] + 1


def test_openptv_readme_states_the_guesses(openptv):
    text = (openptv / "README.txt").read_text()
    for needle in ("glass vector", "8-bit", "Scheimpflug", "frames.csv", "n2 = 1.49"):
        assert needle in text


def test_tracking_bounds_follow_the_flow_of_the_dataset(openptv, dataset):
    """track.par's displacement bounds at every Δt are max_speed·Δt, max_speed = |U| + 5
    max σ_i of the true velocities (not a speed that suits one flow), about five times
    the flow's u′ for kinematic simulation (no mean flow; 60 particles per snapshot)."""
    with h5py.File(dataset / "truth.h5", "r") as f:
        u_rms = float(f["flow"].attrs["u_rms"])
        particles = f["particles"]
        velocity = particles["dt0"]["velocity"][()].reshape(-1, 3)
        dts = [particles[f"dt{k}"].attrs["dt"] for k in range(len(particles))]
    velocity = velocity[np.isfinite(velocity).all(axis=1)]
    speed = np.linalg.norm(velocity.mean(axis=0)) + 5 * velocity.std(axis=0).max()
    assert 0.7 * 5 * u_rms < speed < 1.4 * 5 * u_rms
    for k, dt in enumerate(dts):
        bounds = np.array(
            (openptv / f"parameters/track_dt{k}.par").read_text().split()[:6], dtype=float
        )
        np.testing.assert_allclose(np.abs(bounds), speed * dt * 1e3, rtol=1e-6)


# -- MyPTV ----------------------------------------------------------------------------


def myptv_projection(path: Path, points_mm: np.ndarray) -> np.ndarray:
    """Pixels of points under a MyPTV Tsai camera file, as MyPTV's manual writes the
    model: v = R (X − O), R = R_x(θ1) R_y(θ2) R_z(θ3), η = f v1/v3 + W/2 + xh."""
    lines = path.read_text().splitlines()
    assert lines[0] == "Tsai model camera"
    width, height = (float(v) for v in lines[2].split())
    origin = np.array(lines[3].split(), dtype=float)
    t1, t2, t3 = (float(v) for v in lines[4].split())
    f = float(lines[5])
    xh, yh = (float(v) for v in lines[6].split())
    assert all(line.endswith(" ") for line in lines[2:])  # MyPTV drops 2 characters
    rx = np.array([[1, 0, 0], [0, np.cos(t1), -np.sin(t1)], [0, np.sin(t1), np.cos(t1)]])
    ry = np.array([[np.cos(t2), 0, np.sin(t2)], [0, 1, 0], [-np.sin(t2), 0, np.cos(t2)]])
    rz = np.array([[np.cos(t3), -np.sin(t3), 0], [np.sin(t3), np.cos(t3), 0], [0, 0, 1]])
    v = (points_mm - origin) @ (rx @ ry @ rz).T
    return np.column_stack(
        [f * v[:, 0] / v[:, 2] + width / 2 + xh, f * v[:, 1] / v[:, 2] + height / 2 + yh]
    )


def test_myptv_camera_files_project_like_the_rigs_pinhole(myptv, dataset):
    """The camera guesses are the rig cameras' pinholes (pupil, rotation, image distance,
    principal point), checked against OpenCV's projection of the rig's cameras."""
    from validation.truth.truth_file import TruthFile

    rig = TruthFile(dataset).rig
    points = np.random.default_rng(1).uniform([-40, -40, -5], [40, 40, 5], (50, 3))
    for name, camera in zip(rig.camera_names, rig.cameras, strict=True):
        rvec, _ = cv2.Rodrigues(camera.rotation)
        tvec = -camera.rotation @ (np.asarray(camera.center) * 1e3)
        expected, _ = cv2.projectPoints(
            points, rvec, tvec, camera.lens.camera_matrix(), np.zeros(5)
        )
        np.testing.assert_allclose(
            myptv_projection(myptv / name, points), expected[:, 0], atol=1e-6
        )


def test_myptv_export_holds_the_dataset_images_and_targets(myptv, dataset):
    yaml = pytest.importorskip("yaml")
    spec = experiment(dataset)
    with (myptv / "frames.csv").open() as stream:
        rows = list(csv.DictReader(stream))
    assert len(rows) == 2 * len(spec["dt"]) * spec["frames_per_dt"]
    for row in rows:
        name = f"{int(row['snapshot']):06d}_{row['frame']}.tif"
        for camera in ("cam1", "cam2"):
            exported = myptv / f"Images/dt{row['dt']}/{camera}" / name
            original = dataset / f"particles/dt{row['dt']}/{camera}" / name
            assert exported.read_bytes() == original.read_bytes()
        folder = sorted((myptv / f"Images/dt{row['dt']}/cam1").iterdir())
        assert folder[int(row["frame_index"])].name == name
    with h5py.File(dataset / "truth.h5", "r") as truth:
        indices = truth["plate/dot_indices"][:]
        z_nominal = truth["plate/z_nominal"][:] * 1e3
    for j, z in enumerate(z_nominal):
        rows = np.loadtxt(myptv / f"Calibration/target_file_plane_{j:02d}")
        np.testing.assert_allclose(rows[:, :2], indices * spec["target"]["pitch"] * 1e3)
        np.testing.assert_allclose(rows[:, 2], z, atol=1e-6)
        assert (myptv / f"Calibration/cam2/plane_{j:02d}.tif").is_file()
    steps = yaml.safe_load((myptv / "params_file.yml").read_text())
    sections = {key for step in steps for key in step}
    assert {"calibration", "segmentation", "matching", "tracking"} <= sections
    calibration = next(step["calibration"] for step in steps if "calibration" in step)
    assert (myptv / calibration["calibration_image"]).is_file()
    assert (myptv / calibration["target_file"]).is_file()


# -- bad input ------------------------------------------------------------------------


def export(capsys, *argv) -> tuple[int, str]:
    code = main(["export", *argv])
    return code, capsys.readouterr().err


def assert_refused(code: int, err: str, names: str, folder: Path, before: set) -> None:
    assert code == 2
    assert len(err.strip().splitlines()) == 1, err
    assert names in err
    assert set(folder.iterdir()) == before  # nothing written, no partial folder


def test_a_missing_dataset_is_refused(capsys, tmp_path):
    before = set(tmp_path.iterdir())
    code, err = export(
        capsys, "--dataset", str(tmp_path / "nope"), "--format", "openptv",
        "--out", str(tmp_path / "out"),
    )  # fmt: skip
    assert_refused(code, err, "nope", tmp_path, before)


@pytest.mark.parametrize("layout", ["openptv", "myptv"])
def test_a_dataset_without_truth_is_refused(capsys, tmp_path, dataset, layout):
    copy = tmp_path / "copy"
    shutil.copytree(dataset, copy)
    (copy / "truth.h5").unlink()
    before = set(tmp_path.iterdir())
    code, err = export(
        capsys, "--dataset", str(copy), "--format", layout, "--out", str(tmp_path / "out")
    )
    assert_refused(code, err, "truth.h5", tmp_path, before)


def test_a_missing_plate_image_is_named(capsys, tmp_path, dataset):
    copy = tmp_path / "copy"
    shutil.copytree(dataset, copy)
    (copy / "calibration/cam2/plane_01.tif").unlink()
    before = set(tmp_path.iterdir())
    code, err = export(
        capsys, "--dataset", str(copy), "--format", "openptv", "--out", str(tmp_path / "out")
    )
    assert_refused(code, err, "plane_01.tif", tmp_path, before)


def test_a_bad_experiment_field_is_named(capsys, tmp_path, dataset):
    copy = tmp_path / "copy"
    shutil.copytree(dataset, copy)
    spec = experiment(copy)
    spec["dt"] = "soon"
    (copy / "experiment.json").write_text(json.dumps(spec))
    before = set(tmp_path.iterdir())
    code, err = export(
        capsys, "--dataset", str(copy), "--format", "myptv", "--out", str(tmp_path / "out")
    )
    assert_refused(code, err, "experiment.json", tmp_path, before)
    assert "dt" in err


def test_a_run_without_its_particle_images_says_keep_images(capsys, tmp_path, dataset):
    """synptv run's dataset holds no particle images unless --keep-images."""
    copy = tmp_path / "copy"
    shutil.copytree(dataset, copy)
    spec = experiment(copy)
    spec["particle_images"] = None
    (copy / "experiment.json").write_text(json.dumps(spec))
    before = set(tmp_path.iterdir())
    code, err = export(
        capsys, "--dataset", str(copy), "--format", "openptv", "--out", str(tmp_path / "out")
    )
    assert_refused(code, err, "experiment.json", tmp_path, before)
    assert "--keep-images" in err


def test_dot_lists_instead_of_plate_images_are_refused(capsys, tmp_path, dataset):
    copy = tmp_path / "copy"
    shutil.copytree(dataset, copy)
    spec = experiment(copy)
    for name in spec["cameras"]:
        for j in range(len(spec["traverse_z"])):
            rows = [
                f"{i},{k},{100 + 20 * i + 5 * j},{100 + 20 * k}" for i in range(5) for k in range(5)
            ]
            (copy / f"{name}_{j}.csv").write_text("i,j,x,y\n" + "\n".join(rows))
    del spec["calibration_images"]
    spec["calibration_dots"] = {"format": "csv", "files": "{camera}_{j}.csv"}
    (copy / "experiment.json").write_text(json.dumps(spec))
    before = set(tmp_path.iterdir())
    code, err = export(
        capsys, "--dataset", str(copy), "--format", "openptv", "--out", str(tmp_path / "out")
    )
    assert_refused(code, err, "experiment.json", tmp_path, before)
    assert "dot lists (calibration_dots)" in err


def test_an_existing_output_folder_and_an_unknown_format_are_refused(capsys, tmp_path, dataset):
    (tmp_path / "taken").mkdir()
    before = set(tmp_path.iterdir())
    code, err = export(
        capsys, "--dataset", str(dataset), "--format", "openptv", "--out", str(tmp_path / "taken")
    )
    assert_refused(code, err, "taken", tmp_path, before)
    assert not any((tmp_path / "taken").iterdir())
    code, err = export(
        capsys, "--dataset", str(dataset), "--format", "lpt", "--out", str(tmp_path / "new")
    )
    assert_refused(code, err, "--format", tmp_path, before)


def test_windows_openptv_cannot_describe_are_refused(tmp_path, dataset):
    """ptv.par holds one glass thickness: a rig whose windows differ is refused before
    anything is written."""
    from simulator.rigs import load_rig
    from validation.export.openptv import write_openptv
    from validation.export.source import read_source

    text = small_rig(tmp_path).read_text()
    head, tail = text.rsplit("glass_thickness = 0.015", 1)
    (tmp_path / "uneven.toml").write_text(head + "glass_thickness = 0.012" + tail)
    source = read_source(dataset)
    uneven = dataclasses.replace(source, rig=load_rig(str(tmp_path / "uneven.toml")))
    with pytest.raises(ValueError, match=r"truth\.h5.*windows differ"):
        write_openptv(uneven, tmp_path / "out")
    assert not (tmp_path / "out").exists()
