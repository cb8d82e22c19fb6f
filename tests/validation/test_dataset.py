"""``synptv render`` datasets: layout, images, truth consistent with the cameras, atomicity."""

import json
import os
import shutil
from dataclasses import replace

import cv2
import h5py
import numpy as np
import pytest
import tifffile

from ptv.io.experiment_file import description_problems
from simulator.presets import flow_preset
from simulator.rigs import load_rig
from validation.cli import main
from validation.run.render_dataset import RenderSettings, write_dataset

SETTINGS = RenderSettings(frames=1, planes=2, particles=200, n_modes=60, seed=3)


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    out = tmp_path_factory.mktemp("render") / "ds"
    rig = load_rig("paper-stereo")
    write_dataset(out, rig, flow_preset("lem-10hz"), SETTINGS)
    return out, rig


def test_layout_and_experiment_description(dataset):
    out, rig = dataset
    exp = json.loads((out / "experiment.json").read_text())
    assert description_problems(exp, needs=("particles", "calibration")) == []
    assert exp["dt"] == pytest.approx(list(flow_preset("lem-10hz").dt))
    assert exp["traverse_z"] == pytest.approx([-0.5e-3, 0.5e-3])
    assert exp["target"]["pitch"] == 5e-3 and exp["target"]["marks"]["x_axis"] == [2, 0]
    for name in rig.camera_names:
        for j in range(2):
            image = tifffile.imread(out / "calibration" / name / f"plane_{j:02d}.tif")
            assert image.dtype == np.uint16 and image.shape == (1088, 2048)
        for k in range(5):
            for label in "ab":
                assert (out / "particles" / f"dt{k}" / name / f"000000_{label}.tif").is_file()


def test_a_shared_first_frame_is_one_exposure_for_every_dt(dataset):
    out, rig = dataset
    assert json.loads((out / "experiment.json").read_text())["shared_first_frame"] is True
    with h5py.File(out / "truth.h5") as truth:
        first = truth["particles/dt0/positions_a"]
        for k in range(1, 5):  # one dataset, linked into every Δt's group
            for key in ("positions_a", "velocity", "cam1/xy_a", "cam1/visible_a"):
                assert truth[f"particles/dt{k}/{key}"] == truth[f"particles/dt0/{key}"]
            assert not np.array_equal(truth[f"particles/dt{k}/positions_b"][:], first[:])
    for name in rig.camera_names:
        frames = [out / "particles" / f"dt{k}" / name / "000000_a.tif" for k in range(5)]
        assert len({f.read_bytes() for f in frames}) == 1
        assert len({f.read_bytes() for f in (frames[0], frames[0].with_name("000000_b.tif"))}) == 2


def test_independent_runs_per_dt_are_rendered_too(tmp_path):
    """One experiment per Δt: each run seeds its own particles (more at larger Δt)."""
    out = tmp_path / "ds"
    settings = replace(SETTINGS, planes=2, shared_first_frame=False)
    write_dataset(out, load_rig("paper-stereo"), flow_preset("lem-10hz"), settings)
    assert json.loads((out / "experiment.json").read_text())["shared_first_frame"] is False
    with h5py.File(out / "truth.h5") as truth:
        counts = [truth[f"particles/dt{k}/positions_a"].shape[1] for k in range(5)]
        assert counts[-1] > counts[0]
        for k, count in enumerate(counts):
            assert truth[f"particles/dt{k}/cam1/xy_b"].shape == (1, count, 2)
    frames = [out / "particles" / f"dt{k}" / "cam1" / "000000_a.tif" for k in range(5)]
    assert len({f.read_bytes() for f in frames}) == 5


def test_truth_is_consistent_with_the_cameras_and_the_images(dataset):
    out, rig = dataset
    with h5py.File(out / "truth.h5") as truth:
        dots = truth["plate/dots_world"][:]
        for name, camera in zip(rig.camera_names, rig.cameras, strict=True):
            dots_xy = truth[f"plate/{name}/dots_xy"][1]
            assert np.allclose(dots_xy, camera.project(dots[1]), atol=1e-9, equal_nan=True)
            on_sensor = truth[f"plate/{name}/dots_on_sensor"][1]
            assert on_sensor.sum() > 300 and not on_sensor[~np.isfinite(dots_xy[:, 0])].any()
            positions = truth["particles/dt2/positions_b"][0]  # snapshot 0, frame b
            xy = truth[f"particles/dt2/{name}/xy_b"][0]
            visible = truth[f"particles/dt2/{name}/visible_b"][0]
            # Stored as float32: within half its spacing at the sensor's far edge.
            half_spacing = np.spacing(np.float32(2048)) / 2
            exact = camera.project(positions[visible])
            assert np.allclose(xy[visible], exact, atol=half_spacing, rtol=0)
            image = tifffile.imread(out / "particles" / "dt2" / name / "000000_b.tif")
            # Lit particles are bright where the truth puts them (sheet-centre ones the most).
            lit = visible & (np.abs(positions[:, 2]) < 2e-3)
            cols, rows = np.round(xy[lit]).astype(int).T
            assert np.median(image[rows, cols]) > np.median(image) + 100


def test_existing_folder_is_refused_and_interrupted_runs_leave_nothing(tmp_path):
    rig = load_rig("paper-stereo")
    (tmp_path / "taken").mkdir()
    with pytest.raises(ValueError, match="already exists"):
        write_dataset(tmp_path / "taken", rig, flow_preset("lem-10hz"), SETTINGS)

    def interrupt(done, total):
        if done > 3:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        write_dataset(tmp_path / "new", rig, flow_preset("lem-10hz"), SETTINGS, progress=interrupt)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["taken"]


def test_render_cli_reports_bad_input_in_one_line(capsys, tmp_path):
    assert main(["render", "--rig", "nope", "--out", str(tmp_path / "x"), "--quiet"]) == 2
    assert "unknown rig 'nope'" in capsys.readouterr().err
    argv = ["render", "--scenario", "default", "--frames", "3", "--out", str(tmp_path / "x")]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "--scenario sets the rig, the flow and the sizes: drop --frames" in err
    assert not (tmp_path / "x").exists()


def test_render_cli_renders_what_a_scenario_describes(capsys, tmp_path):
    scenario = tmp_path / "small.toml"
    scenario.write_text(
        'name = "small"\nseed = 4\n[flow]\npreset = "lem-8hz"\nmodes = 40\n'
        "[calibration]\nplanes = 3\nbrightness = 3000.0\n"
        "[particles]\ncount = 150\nframes = 2\n[sensor]\nbit_depth = 12\n"
    )
    out = tmp_path / "ds"
    argv = ["render", "--scenario", str(scenario), "--out", str(out), "--seed", "7"]
    assert main([*argv, "--workers", "1", "--quiet"]) == 0, capsys.readouterr().err
    spec = json.loads((out / "experiment.json").read_text())
    assert spec["frames_per_dt"] == 2 and len(spec["traverse_z"]) == 3
    assert spec["dt"] == pytest.approx(list(flow_preset("lem-8hz").dt))
    assert spec["bit_depth"] == 12
    with h5py.File(out / "truth.h5") as truth:
        assert truth["flow"].attrs["preset"] == "lem-8hz"
        assert truth["flow"].attrs["n_modes"] == 40


def test_calibrate_command_finds_every_dot_and_scores_against_nominal_and_truth(
    dataset, capsys, tmp_path
):
    import json as json_module

    out, _ = dataset
    args = [
        "calibrate",
        "--dataset",
        str(out),
        "--methods",
        "model-free,tsai",
        "--out",
        str(tmp_path),
        "--json",
        "--quiet",
    ]
    assert main(args) == 0
    report = json_module.loads(capsys.readouterr().out)
    nominal = report["table1"]["model-free"]["nominal"]
    # Machined plate (5 µm scatter) and detection noise (~0.01 px): a few µm, far below
    # one object-side pixel (100 µm); the true-centre reference adds the plate's tilt.
    assert nominal["coverage"] == 1.0 and nominal["d_um"] < 20
    assert report["table1"]["model-free"]["true"]["d_um"] > nominal["d_um"]
    assert report["table1"]["tsai"]["nominal"]["d_um"] > 3 * nominal["d_um"]
    assert all(v < 2.0 for v in report["max_plane_residual_px"].values())  # paper: < 2 px
    # Per image: every dot, reprojected within the plate's scatter (5 µm ≈ 0.05 px) and
    # the detection noise; the pinhole Tsai misses the refraction by pixels.
    for rows in report["per_image"].values():
        assert [row["dots"] for row in rows] == [441, 441]
        assert all(row["rms_px"]["model-free"] < 0.1 for row in rows)
        assert all(row["rms_px"]["tsai"] > 3 * row["rms_px"]["model-free"] for row in rows)
    assert report["leave_one_plane_out"] == {}  # two plate positions
    assert "only 2 plate positions" in report["warnings"][0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["model-free.h5", "tsai.h5"]


def test_png_plates_under_their_own_pattern_calibrate_as_the_tiff_ones(dataset, tmp_path):
    from ptv.calibration.plate_images import find_traverse_dots, plate_setup

    out, _ = dataset
    copy = tmp_path / "png"
    spec = json.loads((out / "experiment.json").read_text())
    spec["calibration_images"] = "plates/{j}-{camera}.png"
    for name in spec["cameras"]:
        for j in range(len(spec["traverse_z"])):
            image = tifffile.imread(out / "calibration" / name / f"plane_{j:02d}.tif")
            path = copy / "plates" / f"{j}-{name}.png"
            path.parent.mkdir(parents=True, exist_ok=True)
            assert cv2.imwrite(str(path), image)
    (copy / "experiment.json").write_text(json.dumps(spec))
    png, tiff = (find_traverse_dots(plate_setup(folder)) for folder in (copy, out))
    for name in spec["cameras"]:
        for a, b in zip(png[name], tiff[name], strict=True):
            np.testing.assert_array_equal(a.indices, b.indices)
            np.testing.assert_array_equal(a.pixels, b.pixels)


def test_plate_images_numbered_in_any_way_are_listed_one_per_plane(dataset, tmp_path):
    # Planes numbered 01 and 11, as a lab's traverse names them: no {j} pattern holds them.
    from ptv.calibration.plate_images import plate_setup

    out, _ = dataset
    listed = tmp_path / "listed"
    spec = json.loads((out / "experiment.json").read_text())
    spec["calibration_images"] = ["plates/{camera}_z01.tif", "plates/{camera}_z11.tif"]
    for name in spec["cameras"]:
        for j, number in enumerate(("01", "11")):
            path = listed / "plates" / f"{name}_z{number}.tif"
            path.parent.mkdir(parents=True, exist_ok=True)
            path.symlink_to(out / "calibration" / name / f"plane_{j:02d}.tif")
    (listed / "experiment.json").write_text(json.dumps(spec))
    shutil.copy(out / "truth.h5", listed / "truth.h5")
    original, renamed = plate_setup(out), plate_setup(listed)
    for name in spec["cameras"]:
        assert [p.resolve() for p in renamed.images[name]] == original.images[name]


def test_a_local_threshold_finds_the_same_dots_as_the_global_one(dataset, tmp_path):
    from ptv.calibration.plate_images import find_traverse_dots, plate_setup

    out, _ = dataset
    local = tmp_path / "local"
    shutil.copytree(out, local, copy_function=os.symlink)
    spec = json.loads((out / "experiment.json").read_text())
    spec["target"]["threshold"] = "local"
    (local / "experiment.json").unlink()
    (local / "experiment.json").write_text(json.dumps(spec))
    found = {folder: find_traverse_dots(plate_setup(folder)) for folder in (out, local)}
    for name in spec["cameras"]:
        for a, b in zip(found[out][name], found[local][name], strict=True):
            np.testing.assert_array_equal(a.indices, b.indices)
            # The centroid window grows from a slightly different mask: ~0.001 px apart.
            np.testing.assert_allclose(a.pixels, b.pixels, atol=0.01)


def test_calibrate_command_on_a_folder_that_is_no_dataset(capsys, tmp_path):
    assert main(["calibrate", "--dataset", str(tmp_path), "--quiet"]) == 2
    assert "is not a dataset" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("methods", "message"), [(",", "got none"), ("model-free,foo", "got 'model-free', 'foo'")]
)
def test_calibrate_command_refuses_bad_methods_before_reading(capsys, tmp_path, methods, message):
    # tmp_path is no dataset: the methods are checked first.
    assert main(["calibrate", "--dataset", str(tmp_path), "--methods", methods, "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "calibration methods must be some of model-free" in err and message in err
    assert err.count("\n") == 1


def test_methods_the_traverse_cannot_fit_are_refused_before_any_dot_search(
    dataset, capsys, tmp_path, monkeypatch
):
    """Two plate positions and the default methods: Soloff (quadratic in Z) needs three.
    Refused by name, with the methods that can run, before a plate image is searched."""
    import validation.dataset.calibrate as module

    def no_search(*args, **kwargs):
        raise AssertionError("the dots were searched before the methods were checked")

    monkeypatch.setattr(module, "find_traverse_dots", no_search)
    out, _ = dataset
    args = ["calibrate", "--dataset", str(out), "--out", str(tmp_path / "cal"), "--quiet"]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "2 plate position(s) with distinct Z: soloff needs 3" in err
    assert "methods that can run on 2: model-free, tsai, pinhole" in err
    assert err.count("\n") == 1
    assert not (tmp_path / "cal").exists()


def test_a_method_that_fails_leaves_no_calibration_file(dataset, capsys, tmp_path, monkeypatch):
    import ptv.calibration.plate_images as module

    def fails_for_tsai(method, planes, sheet):
        if method == "tsai":
            raise ValueError("tsai: refused")
        return calibrate(method, planes, sheet)

    calibrate = module.calibrate
    monkeypatch.setattr(module, "calibrate", fails_for_tsai)
    out, _ = dataset
    args = ["calibrate", "--dataset", str(out), "--methods", "model-free,tsai"]
    assert main([*args, "--out", str(tmp_path / "cal"), "--quiet"]) == 2
    assert "tsai: refused" in capsys.readouterr().err
    assert not (tmp_path / "cal").exists()


def _spoil_experiment(spec: dict, case: str) -> None:
    if case == "no traverse_z":
        del spec["traverse_z"]
    elif case == "string image size":
        next(iter(spec["cameras"].values()))["image_size"] = "2048x1088"
    elif case == "target without pitch":
        del spec["target"]["pitch"]
    elif case == "unknown threshold":
        spec["target"]["threshold"] = "median"
    elif case == "short image list":
        spec["calibration_images"] = ["calibration/{camera}/plane_00.tif"]
    elif case == "image listed twice":
        spec["calibration_images"] = ["calibration/{camera}/plane_00.tif"] * 2
    elif case == "listed image without camera":
        spec["calibration_images"] = ["calibration/cam1/plane_00.tif", "b/{camera}.tif"]


@pytest.mark.parametrize(
    ("case", "file", "message"),
    [
        ("invalid JSON", "experiment.json", "not readable as JSON"),
        ("no traverse_z", "experiment.json", "traverse_z: required to calibrate"),
        ("string image size", "experiment.json", "image_size: '2048x1088' is not of type"),
        ("target without pitch", "experiment.json", "target: 'pitch' is a required property"),
        ("unknown threshold", "experiment.json", "target.threshold: 'median' is not one of"),
        ("short image list", "experiment.json", "1 entries, but traverse_z gives 2 plate"),
        ("image listed twice", "experiment.json", "plane_00.tif' given twice"),
        ("listed image without camera", "experiment.json", "does not match '\\\\{camera"),
        ("missing plane", "plane_01.tif", "plate image missing"),
        ("text as a plane", "plane_00.tif", "not readable as a TIFF image"),
        ("truncated truth", "truth.h5", "cannot read plate/dots_world"),
        ("stuck traverse", "plane_01.tif", "the same image as plane_00.tif"),
        ("noisy stuck traverse", "plane_01.tif", "dots sit where they were in plane_00.tif"),
        ("small plane", "plane_01.tif", "image of 20 × 10 px, but experiment.json gives"),
    ],
)
def test_calibrate_command_names_the_file_and_field_of_a_bad_dataset(
    dataset, capsys, tmp_path, case, file, message
):
    # A copy of the dataset whose files are links to the original, one of them spoilt.
    out, _ = dataset
    broken = tmp_path / "ds"
    shutil.copytree(out, broken, copy_function=os.symlink)
    camera = sorted(p.name for p in (broken / "calibration").iterdir())[0]
    plane = broken / "calibration" / camera / file
    experiment = broken / "experiment.json"
    if case == "invalid JSON":
        experiment.unlink()
        experiment.write_text('{"cameras": ')
    elif file == "experiment.json":
        spec = json.loads(experiment.read_text())
        _spoil_experiment(spec, case)
        experiment.unlink()
        experiment.write_text(json.dumps(spec))
    elif case == "missing plane":
        plane.unlink()
    elif case == "text as a plane":
        plane.unlink()
        plane.write_text("not an image\n")
    elif case == "stuck traverse":
        plane.unlink()
        plane.symlink_to(plane.with_name("plane_00.tif").resolve())
    elif case == "noisy stuck traverse":  # the first plane again, on fresh sensor noise
        first = tifffile.imread(plane.with_name("plane_00.tif"))
        noise = np.random.default_rng(0).normal(0.0, 0.01 * first.max(), first.shape)
        plane.unlink()
        tifffile.imwrite(plane, np.clip(first + noise, 0, 65535).astype(np.uint16))
    elif case == "small plane":
        plane.unlink()
        tifffile.imwrite(plane, np.zeros((10, 20), np.uint16))
    else:
        truth = broken / "truth.h5"
        data = truth.read_bytes()
        truth.unlink()
        truth.write_bytes(data[: len(data) // 3])
    calibrations = tmp_path / "cal"
    args = ["calibrate", "--dataset", str(broken), "--methods", "model-free"]
    assert main([*args, "--out", str(calibrations), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert message in err and file in err
    assert err.count("\n") == 1
    assert not calibrations.exists()
