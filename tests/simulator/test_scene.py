"""The pyrender overview picture of a rig: size, content, the sheet's colour, the camera
colours and labels, the PNG."""

import dataclasses

import cv2
import numpy as np
import pytest

from simulator.rigs import load_rig
from simulator.scene import (
    CAMERA_COLOURS,
    SceneOptions,
    _scene_items,
    axes_length,
    caption,
    render_scene,
)
from simulator.target import PlateDesign, build_plate
from validation.report.png import save_picture

RIG = load_rig("paper-stereo")
SMALL = SceneOptions(size=(400, 250), show_axes=False)


def sheet_pixels(rgb):
    """Pixels where green clearly dominates (the translucent green sheet)."""
    r, g, b = (rgb[:, :, k].astype(int) for k in range(3))
    return (g - np.maximum(r, b)) > 30


def test_picture_has_the_size_and_shows_rig_and_sheet():
    rgb = render_scene(RIG, options=SMALL)
    assert rgb.shape == (250, 400, 3) and rgb.dtype == np.uint8
    background = (rgb == 255).all(axis=2)
    assert 0.05 < 1.0 - background.mean() < 0.9  # something drawn, not everything
    assert background[0].all() or background[-1].all()  # framed with a margin
    green = sheet_pixels(rgb)
    assert green.sum() > 20
    no_sheet = render_scene(
        RIG, options=SceneOptions(size=(400, 250), show_axes=False, show_sheet=False)
    )
    assert sheet_pixels(no_sheet).sum() < 0.1 * green.sum()


def test_plate_and_particles_are_drawn_and_the_png_is_written(tmp_path):
    plate = build_plate(PlateDesign(), [0.0, 1e-3])
    particles = RIG.sheet.sample(200, np.random.default_rng(0))
    rgb = render_scene(RIG, plate=plate, plate_plane=1, particles=particles, options=SMALL)
    path = save_picture(rgb, tmp_path / "scene.png")
    assert path.exists() and [p.name for p in tmp_path.iterdir()] == ["scene.png"]
    bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
    assert bgr.shape == (250, 400, 3)
    assert np.array_equal(bgr[:, :, ::-1], rgb)
    assert path.stat().st_mode & 0o777 == 0o644  # as every figure synptv writes
    plain = render_scene(RIG, options=SMALL)
    # The dark plate changes the picture where the sheet is.
    changed = np.abs(rgb.astype(int) - plain.astype(int)).sum(axis=2) > 60
    assert changed.sum() > 50


def test_bad_arguments_are_rejected(tmp_path):
    with pytest.raises(ValueError, match="png"):
        save_picture(render_scene(RIG, options=SMALL), tmp_path / "scene.jpg")
    with pytest.raises(ValueError, match="size"):
        SceneOptions(size=(0, 100))
    with pytest.raises(ValueError, match="particles"):
        render_scene(RIG, particles=np.zeros((3, 2)), options=SMALL)
    with pytest.raises(ValueError, match="plate_plane"):
        render_scene(RIG, plate=build_plate(PlateDesign(), [0.0, 1e-3]), plate_plane=5)


def _of_colour(rgb, colour):
    """Saturated pixels whose hue is that of ``colour`` (RGB in [0, 1]) within 10°: the
    hue survives shading and transparency over white, the brightness does not."""
    hsv = cv2.cvtColor(rgb, cv2.COLOR_RGB2HSV).astype(int)  # hue in 2° steps, 0-179
    target = cv2.cvtColor(np.uint8([[np.round(255 * np.asarray(colour))]]), cv2.COLOR_RGB2HSV)
    step = np.abs(hsv[:, :, 0] - int(target[0, 0, 0]))
    return (np.minimum(step, 180 - step) <= 5) & (hsv[:, :, 1] > 60)


@pytest.mark.parametrize("name", ["box-3cam", "box-4cam", "lpt-challenge"])
def test_every_camera_of_a_box_rig_is_drawn_and_labelled(name):
    rig = load_rig(name)
    options = SceneOptions(size=(800, 500))
    rgb = render_scene(rig, options=options)
    for colour in CAMERA_COLOURS[: len(rig.cameras)]:
        assert _of_colour(rgb, colour).sum() > 200  # body, frustum, window
    # Without names, the pixels of the labels change back to what lies behind them.
    nameless = dataclasses.replace(rig, camera_names=("",) * len(rig.cameras))
    changed = np.abs(render_scene(nameless, options=options).astype(int) - rgb).sum(axis=2) > 60
    assert changed.sum() > 40 * len(rig.cameras)


@pytest.mark.parametrize("name", ["paper-stereo", "box-3cam"])
def test_the_axes_start_at_the_world_origin_inside_the_tank(name):
    rig = load_rig(name)
    with_axes = SceneOptions(size=(400, 250), show_axes=True)
    items, labels = _scene_items(rig, None, 0, None, with_axes)
    plain, _ = _scene_items(rig, None, 0, None, dataclasses.replace(with_axes, show_axes=False))
    axes = items[len(plain) :]
    assert len(axes) == 3
    length = axes_length(rig)
    # Each arrow from the origin (the sheet's centre) along its axis…
    assert np.allclose(rig.sheet.centre, 0.0)
    for k, item in enumerate(axes):
        along = item.mesh.vertices[:, k]
        across = np.delete(item.mesh.vertices, k, axis=1)
        assert along.min() == pytest.approx(0.0, abs=1e-9)
        assert along.max() == pytest.approx(length)
        assert np.abs(across).max() <= 0.1 * length
    points = np.vstack([item.mesh.vertices for item in axes])
    # …to beyond the sheet, so that the arrowheads show…
    assert length > 0.5 * max(rig.sheet.size[:2])
    # …and inside the tank: within its inscribed sphere, or its box.
    if rig.tank.kind == "icosahedron":
        assert np.linalg.norm(points, axis=1).max() < rig.tank.inradius
    else:
        assert np.all(np.abs(points) < 0.5 * np.asarray(rig.tank.size))
    assert [label.text for label in labels[-3:]] == ["X", "Y", "Z"]
    assert "origin" in caption(rig) and rig.name in caption(rig)
