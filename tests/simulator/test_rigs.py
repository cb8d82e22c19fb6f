"""Rigs: presets load, see the sheet at ~0.1 mm/px, focus claims; tanks, aim, roll and
named distortion; rig-file errors, also through the command line."""

import tomllib
from importlib import resources

import numpy as np
import pytest

from simulator import rigs
from simulator.optics import Camera, defocus_blur, focus_on_plane
from simulator.render.camera_frames import local_magnification
from simulator.render.spot import SHEET_PROFILES
from simulator.rigs import RigFileError, check_sees_sheet, load_rig, rig_from_dict, rig_presets
from validation.cli import main


def sheet_grid(n=21, half=0.05):
    u = np.linspace(-half, half, n)
    x, y = np.meshgrid(u, u)
    return np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])


def volume_grid(size, n=9):
    """An n × n × n grid over a sheet of ``size`` (X, Y, Z), centred on the origin, m."""
    axes = [np.linspace(-0.5 * s, 0.5 * s, n) for s in size]
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)


def preset_spec(name):
    return tomllib.loads(
        (resources.files("simulator") / "rig_presets" / f"{name}.toml").read_text()
    )


def test_presets_are_listed():
    assert set(rig_presets()) == {
        "paper-stereo",
        "conventional",
        "box-3cam",
        "box-4cam",
        "box-4cam-unequal",
        "lpt-challenge",
        "lpt-challenge-small",
    }


@pytest.mark.parametrize("name", sorted(rig_presets()))
def test_every_preset_loads_and_sees_all_of_its_sheet(name):
    rig = load_rig(name)
    for camera in rig.cameras:
        assert np.isfinite(camera.project(volume_grid(rig.sheet.size, 5))).all()


@pytest.mark.parametrize("name", ["paper-stereo", "conventional"])
def test_cameras_see_the_whole_sheet_at_a_tenth_of_a_millimetre_per_pixel(name):
    rig = load_rig(name)
    assert len(rig.cameras) == 2
    for camera in rig.cameras:
        xy = camera.project(sheet_grid())
        assert np.isfinite(xy).all()
        centre = camera.project(np.array([[0, 0, 0.0], [0, 1e-3, 0.0]]))
        # Sensor y ~ world Y: 1 mm along Y moves ~10 px (0.1 mm per object-side pixel).
        assert np.linalg.norm(centre[1] - centre[0]) == pytest.approx(10.0, rel=0.05)


def test_paper_stereo_is_in_focus_with_the_tilt_and_blurred_without():
    rig = load_rig("paper-stereo")
    points = sheet_grid()
    for camera in rig.cameras:
        assert abs(camera.lens.tau_y) > np.deg2rad(1.0)  # a real Scheimpflug tilt
        assert defocus_blur(camera, points).max() <= 1.0
        untilted = focus_on_plane(camera, tilt=False)
        assert defocus_blur(untilted, points).max() > 2.0


def test_conventional_has_untilted_sensors_and_perpendicular_windows():
    rig = load_rig("conventional")
    for camera in rig.cameras:
        assert camera.lens.tau_x == 0 and camera.lens.tau_y == 0
        assert np.isclose(abs(camera.interfaces.normal @ camera.axis), 1.0, atol=1e-3)


def spec_with(path, value):
    """The paper-stereo description with the field at ``path`` (keys, indices) set."""
    spec = preset_spec("paper-stereo")
    table = spec
    for key in path[:-1]:
        table = table[key]
    table[path[-1]] = value
    return spec


def test_missing_field_is_named():
    spec = preset_spec("paper-stereo")
    del spec["cameras"][1]["window"]["water_path"]
    with pytest.raises(RigFileError, match=r"cameras\[1\]\.window: missing field 'water_path'"):
        rig_from_dict(spec, source="mine.toml")


def test_unknown_field_is_named():
    spec = preset_spec("paper-stereo")
    spec["cameras"][0]["focal_lenght"] = 0.05
    with pytest.raises(RigFileError, match="unknown field 'focal_lenght'"):
        rig_from_dict(spec)


def test_bad_value_is_named():
    spec = preset_spec("paper-stereo")
    spec["cameras"][0]["sensor_size"] = [2048]
    with pytest.raises(RigFileError, match="sensor_size"):
        rig_from_dict(spec)


def test_camera_that_sees_none_of_the_sheet_is_an_error():
    rig = load_rig("conventional")
    camera = rig.cameras[0]
    turned = Camera(  # the same camera turned 180° about its image y axis: looks away
        camera.center, np.diag([-1.0, 1.0, -1.0]) @ camera.rotation, camera.lens, camera.interfaces
    )
    assert not np.isfinite(turned.project(sheet_grid())).any()
    with pytest.raises(RigFileError, match="camera 'cam1' sees none of the laser sheet"):
        check_sees_sheet("cam1", turned, rig.sheet, "mine.toml: cameras[0]")


def test_unknown_preset_and_bad_files(tmp_path):
    with pytest.raises(RigFileError, match="unknown rig 'stereo'"):
        load_rig("stereo")
    with pytest.raises(RigFileError, match="does not exist"):
        load_rig(tmp_path / "none.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("name = [")
    with pytest.raises(RigFileError, match="not valid TOML"):
        load_rig(bad)


@pytest.mark.parametrize("name", ["../../x", "/tmp/x", ".hidden", "", "cam 1", "a/b", 7])
def test_camera_names_that_would_leave_the_output_folder_are_refused(name):
    spec = preset_spec("paper-stereo")
    spec["cameras"][0]["name"] = name
    with pytest.raises(RigFileError, match=r"cameras\[0\]\.name: expected 1 to 64 letters"):
        rig_from_dict(spec, source="mine.toml")


def test_binary_rig_file_is_named(tmp_path):
    binary = tmp_path / "binary.toml"
    binary.write_bytes(b"\xff\xfe\x00name")
    with pytest.raises(RigFileError, match=r"binary\.toml: not readable as a UTF-8 text file"):
        load_rig(binary)


@pytest.mark.parametrize(
    ("path", "value", "message"),
    [
        (("cameras", 0, "window", "n_water"), 100.0, r"window\.n_water: must be from 1 to 2"),
        (("cameras", 0, "distortion"), {"k2": 1e6}, r"distortion\.k2: must lie within ±10"),
        (("cameras", 0, "distortion"), {"p1": "a"}, r"distortion\.p1: expected a finite number"),
        (("cameras", 0, "distortion"), {"k4": 0.1}, r"distortion: unknown field 'k4'"),
        (
            ("cameras", 0, "distortion"),
            [-0.08, 0, 0, 0, 0],
            r"distortion: give the coefficients by name.*OpenCV's is k1, k2, p1, p2, k3",
        ),
        (("cameras", 0, "aim"), [0.0, 0.0], r"aim: expected 3 numbers"),
        (("cameras", 0, "aim"), [0.0, 0.0, 0.2], r"aim: the aim point .* is not inside the tank"),
        (("cameras", 0, "roll_deg"), 400.0, r"roll_deg: must be from -360 to 360°"),
        (("tank", "kind"), "cylinder", r"tank\.kind: expected one of icosahedron, box, free"),
        (("cameras", 1, "focal_length"), float("inf"), r"focal_length: expected a finite"),
        (("cameras", 1, "pixel_pitch"), 1e-3, r"pixel_pitch: must be from 5e-07 to 0.0001 m"),
        (("cameras", 0, "sensor_size"), [10**6, 1088], r"sensor_size: .* from 16 to 16384 px"),
        (("cameras", 0, "sensor_size"), [True, 1088], r"sensor_size"),
        (("sheet", "width"), 1e9, r"sheet\.width: must be from 0.001 to 2 m"),
    ],
)
def test_implausible_values_are_refused_with_the_limit(path, value, message):
    with pytest.raises(RigFileError, match=message):
        rig_from_dict(spec_with(path, value), source="mine.toml")


def test_distortion_that_folds_the_field_of_view_over_is_refused():
    # r (1 + k1 r²) turns back at r = 1/√(−3 k1): 0.187 for k1 = −9.5, inside 1.5 × the
    # sensor's half-diagonal, 0.191 in normalised coordinates (f = 50 mm, 2048 × 1088 px
    # of 5.5 µm); for k1 = −8 it turns back at 0.204, beyond.
    with pytest.raises(RigFileError, match="folds the image over"):
        rig_from_dict(spec_with(("cameras", 0, "distortion"), {"k1": -9.5}), source="m")
    rig_from_dict(spec_with(("cameras", 0, "distortion"), {"k1": -8.0}))


@pytest.mark.parametrize(
    ("path", "value", "message"),
    [
        (("tank", "inradius"), 0.05, r"the sheet reaches 20.9 mm beyond the tank's inradius 0.05"),
        (("cameras", 0, "window", "water_path"), 0.03, r"window: a corner of the sheet lies"),
        (("cameras", 0, "window", "obliquity_deg"), 70.0, r"window: a corner of the sheet lies"),
        (("cameras", 0, "distance"), 0.1, r"cameras\[0\]: the window .* does not fit"),
    ],
)
def test_geometry_with_the_sheet_out_of_the_water_is_refused(path, value, message):
    with pytest.raises(RigFileError, match=message):
        rig_from_dict(spec_with(path, value), source="mine.toml")


def test_named_distortion_coefficients_reach_the_lens_in_their_own_places():
    spec = spec_with(("cameras", 0, "distortion"), {"k1": -0.05, "k3": 0.2, "p1": 1e-3})
    lens = rig_from_dict(spec).cameras[0].lens
    assert (lens.k1, lens.k2, lens.k3, lens.p1, lens.p2) == (-0.05, 0.0, 0.2, 1e-3, 0.0)


def _offsets(camera, points):
    """Image positions relative to the principal point, px."""
    return camera.project(points) - camera.lens.camera_matrix()[:2, 2]


@pytest.mark.parametrize("roll_deg", [90.0, -30.0])
def test_roll_turns_the_image_about_the_principal_point(roll_deg):
    # Untilted sensors, radial distortion only: the image of the rolled camera is the
    # unrolled one turned by the roll, x' = cos ρ x + sin ρ y, y' = −sin ρ x + cos ρ y.
    plain = rig_from_dict(preset_spec("conventional")).cameras[0]
    rolled = rig_from_dict(spec_of("conventional", ("cameras", 0, "roll_deg"), roll_deg)).cameras[0]
    points = 0.6 * sheet_grid(7)
    u, v = _offsets(plain, points).T
    rho = np.deg2rad(roll_deg)
    expected = np.column_stack(
        [np.cos(rho) * u + np.sin(rho) * v, -np.sin(rho) * u + np.cos(rho) * v]
    )
    np.testing.assert_allclose(_offsets(rolled, points), expected, atol=1e-6)


def spec_of(name, path, value):
    spec = preset_spec(name)
    table = spec
    for key in path[:-1]:
        table = table[key]
    table[path[-1]] = value
    return spec


@pytest.mark.parametrize("name", ["paper-stereo", "box-3cam"])
def test_the_aim_point_images_at_the_principal_point(name):
    aim = [0.01, -0.02, 0.002]
    camera = rig_from_dict(spec_of(name, ("cameras", 0, "aim"), aim)).cameras[0]
    np.testing.assert_allclose(_offsets(camera, np.array([aim])), 0.0, atol=1e-6)


@pytest.mark.parametrize(
    ("name", "count", "blur_px"),
    # The 60 mm lenses of the unequal rig, at 1.05–1.1 m, blur a little more at f/8.
    [("box-3cam", 3, 1.1), ("box-4cam", 4, 1.1), ("box-4cam-unequal", 4, 1.3)],
)
def test_box_presets_see_the_whole_sheet_through_the_front_wall(name, count, blur_px):
    rig = load_rig(name)
    assert len(rig.cameras) == count and rig.tank.kind == "box"
    corners = np.array(
        [[x, y, z] for x in (-0.05, 0.05) for y in (-0.05, 0.05) for z in (-5e-3, 5e-3)]
    )
    for camera in rig.cameras:
        # The wet face of the front wall is Z = +150 mm, its dry face 12 mm further out.
        np.testing.assert_allclose(camera.interfaces.normal, [0.0, 0.0, -1.0], atol=1e-15)
        np.testing.assert_allclose(camera.interfaces.offsets, [-0.162, -0.15], rtol=1e-14)
        assert np.isfinite(camera.project(corners)).all()
        # About a pixel at f/8, below the diffraction spot (2.44 λN ≈ 10 µm ≈ 1.9 px).
        assert defocus_blur(camera, sheet_grid()).max() <= blur_px


@pytest.mark.parametrize(
    ("path", "value", "message"),
    [
        (("cameras", 0, "azimuth_deg"), -48.0, r"sees the sheet through 2 walls"),
        (("tank", "size"), [0.3, 0.09, 0.3], r"the sheet reaches 5 mm beyond the box's walls"),
        (("tank", "glass_thickness"), 1.0, r"glass_thickness: must be from 0 to 0.5 m"),
        (("cameras", 0, "distance"), 0.19, r"inside the glass of the tank's wall"),
        (("cameras", 0, "window"), {"water_path": 0.15}, r"window: a camera of a box tank"),
    ],
)
def test_box_tank_errors_are_named(path, value, message):
    with pytest.raises(RigFileError, match=message):
        rig_from_dict(spec_of("box-3cam", path, value), source="mine.toml")


def test_a_yawed_box_puts_its_walls_at_the_yaw():
    # Yaw 40°: the front wall faces azimuth 40°, so a camera there looks along its normal.
    spec = spec_of("box-3cam", ("tank", "yaw_deg"), 40.0)
    spec["cameras"] = [spec["cameras"][0] | {"azimuth_deg": 40.0}]
    camera = rig_from_dict(spec).cameras[0]
    normal = -np.array([np.sin(np.deg2rad(40.0)), 0.0, np.cos(np.deg2rad(40.0))])
    np.testing.assert_allclose(camera.interfaces.normal, normal, atol=1e-12)


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        ('kind = "box"', 'kind = "cylinder"', "tank.kind"),
        ("distortion = { k1 = -0.08 }", "distortion = [-0.08, 0, 0, 0, 0]", "by name"),
        ('name = "cam1"', 'name = "cam1"\naim = [0.0, 0.0, 0.3]', "aim: the aim point"),
    ],
)
@pytest.mark.parametrize("command", ["render", "run"])
def test_a_bad_rig_file_exits_2_in_one_line_and_writes_nothing(
    tmp_path, capsys, command, old, new, message
):
    text = (resources.files("simulator") / "rig_presets" / "box-3cam.toml").read_text()
    (tmp_path / "rig.toml").write_text(text.replace(old, new, 1))
    scenario = tmp_path / "s.toml"
    scenario.write_text('name = "s"\n[rig]\nname = "rig.toml"\n')
    out = tmp_path / "out"
    assert main([command, "--scenario", str(scenario), "--out", str(out), "--quiet"]) == 2
    printed = capsys.readouterr()
    assert printed.err.count("\n") == 1 and message in printed.err and "rig.toml" in printed.err
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["rig.toml", "s.toml"]


@pytest.mark.parametrize(
    ("name", "sensor"), [("lpt-challenge", (1920, 1200)), ("lpt-challenge-small", (512, 512))]
)
def test_lpt_challenge_sees_its_whole_volume_in_focus_at_a_60_micrometre_voxel(name, sensor):
    """Four cameras in the XZ plane at −30°, −10°, +10°, +30°, f = 100 mm, 10 µm pixels,
    a 60 µm voxel, and at f/16 the defocus blur over the 30 mm depth no larger than the
    diffraction spot (≈ 2.4 px): the whole volume in focus within a particle image."""
    rig = load_rig(name)
    assert rig.sheet_profile == "top-hat" and rig.tank.kind == "box"
    assert rig.sheet.size[2] == 0.030
    points = volume_grid(rig.sheet.size)
    azimuths = []
    for camera in rig.cameras:
        lens = camera.lens
        assert (lens.focal_length, lens.pixel_pitch, lens.sensor_size) == (0.1, 10e-6, sensor)
        assert camera.center[1] == pytest.approx(0.0, abs=1e-12)  # all in one plane
        azimuths.append(np.rad2deg(np.arctan2(camera.center[0], camera.center[2])))
        voxel = lens.pixel_pitch / local_magnification(camera, np.zeros((1, 3)))[0]
        assert voxel == pytest.approx(60e-6, rel=0.01)
        xy = camera.project(points)
        assert np.isfinite(xy).all()
        assert (xy.min(axis=0) > 10).all() and (xy.max(axis=0) < np.array(sensor) - 10).all()
        diffraction = 2.44 * lens.f_number * (lens.pixel_pitch / voxel + 1) * 532e-9
        blur = defocus_blur(camera, points)
        assert blur.max() <= diffraction / lens.pixel_pitch
        # The Scheimpflug tilt matters: untilted, focused on the centre, it blurs more.
        if name == "lpt-challenge":
            assert defocus_blur(focus_on_plane(camera, tilt=False), points).max() > 1.2 * blur.max()
    np.testing.assert_allclose(azimuths, [-30, -10, 10, 30], atol=1e-9)


def test_the_small_lpt_rig_is_a_crop_of_the_full_one():
    full, small = load_rig("lpt-challenge"), load_rig("lpt-challenge-small")
    for a, b in zip(full.cameras, small.cameras, strict=True):
        np.testing.assert_allclose(a.center, b.center, atol=1e-12)
        np.testing.assert_allclose(a.rotation, b.rotation, atol=1e-12)
        assert a.lens.image_distance == pytest.approx(b.lens.image_distance, rel=1e-3)


def test_the_sheet_profile_is_gaussian_unless_asked_and_checked():
    assert rigs._SHEET_PROFILES == SHEET_PROFILES  # the loader's list is the renderer's
    assert load_rig("paper-stereo").sheet_profile == "gaussian"
    spec = spec_of("paper-stereo", ("sheet", "profile"), "top-hat")
    assert rig_from_dict(spec).sheet_profile == "top-hat"
    with pytest.raises(
        RigFileError,
        match=r"mine.toml: sheet.profile: expected one of gaussian, top-hat, got 'flat'",
    ):
        rig_from_dict(spec_of("paper-stereo", ("sheet", "profile"), "flat"), source="mine.toml")


def test_a_plate_table_sets_the_plate_and_the_traverse_step():
    rig = load_rig("lpt-challenge-small")
    assert (rig.plate.pitch, rig.plate.dot_diameter, rig.plate.mark_diameter) == (
        0.0025,
        0.001,
        0.0016,
    )
    assert (rig.plate.columns, rig.plate.rows, rig.plane_spacing) == (13, 13, 0.005)
    default = load_rig("paper-stereo")
    assert (default.plate.pitch, default.plate.columns, default.plane_spacing) == (5e-3, 21, 1e-3)


@pytest.mark.parametrize(
    ("plate", "message"),
    [
        ({"pitch": 0.0}, r"plate\.pitch: must be from"),
        ({"columns": 4}, r"plate\.columns: expected an integer from 5"),
        ({"columns": 2.5}, r"plate\.columns: expected an integer"),
        ({"dot_diameter": 0.004}, r"plate: need dot_diameter < mark_diameter < pitch"),
        ({"plane_spacing": -1e-3}, r"plate\.plane_spacing: must be from"),
        ({"spacing": 1e-3}, r"plate: unknown field 'spacing'"),
    ],
)
def test_a_bad_plate_table_is_named(plate, message):
    spec = preset_spec("paper-stereo")
    spec["plate"] = plate
    with pytest.raises(RigFileError, match=message):
        rig_from_dict(spec, source="mine.toml")
