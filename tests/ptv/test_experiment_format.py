"""experiment.json against its schema, grey images in TIFF and PNG, and camera masks."""

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
import tifffile
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from ptv.detect import Detections
from ptv.detect.frames import ImageDetector
from ptv.io.dataset import DatasetError, open_dataset
from ptv.io.experiment_file import DescriptionError, description_problems, read_experiment
from ptv.io.images import ImageError, read_image

PARTICLES = {
    "cameras": {"cam1": {"image_size": [64, 48]}, "cam2": {"image_size": [64, 48]}},
    "dt": [1e-4, 2e-4],
    "frames_per_dt": 1,
}


def test_a_complete_description_has_no_problem():
    spec = {
        **PARTICLES,
        "cameras": {
            c: {
                "image_size": [64, 48],
                "pixel_pitch": 5.5e-6,
                "focal_length": 0.05,
                "mask": "m.png",
            }
            for c in ("cam1", "cam2")
        },
        "target": {
            "pitch": 5e-3,
            "dot_diameter": 2e-3,
            "mark_diameter": 3.2e-3,
            "marks": {"origin": [0, 0], "x_axis": [2, 0], "y_axis": [0, 3]},
            "extent": [[-10, 10], [-10, 10]],
            "dots": "dark",
            "threshold": "local",
        },
        "traverse_z": [-1e-3, 0.0, 1e-3],
        "calibration_images": "plates/{camera}_{j:02d}.png",
        "particle_images": "run/{camera}/{k}_{m:04d}{a|b}.tif",
    }
    assert description_problems(spec, needs=("particles", "calibration")) == []


def test_a_point_target_description_needs_no_traverse_nor_data_sheet():
    spec = {
        **PARTICLES,
        "target": {
            "points": "cal/target.txt",
            "units": "mm",
            "dots": "bright",
            "min_dot_area": 6,
            "distortion": ["k1", "k2"],
            "principal_point": "centre",
        },
        "calibration_images": "cal/{camera}.tif",
        "calibration_seeds": "seeds.csv",
    }
    assert description_problems(spec, needs=("particles", "calibration")) == []
    spec["target"] |= {"pitch": 0.005, "principal_point": "middle", "distortion": ["k4"]}
    assert description_problems(spec) == [
        "target: unknown field(s) 'pitch'; known: points, units, dots, min_dot_area, "
        "distortion, principal_point",
        "target.distortion[0]: 'k4' is not one of ['k1', 'k2', 'p1', 'p2', 'k3']",
        "target.principal_point: 'middle' is not one of ['free', 'centre']",
    ]


def test_every_problem_is_named_in_one_line(tmp_path):
    spec = {
        "cameras": {"cam1": {"image_size": [64]}, "../cam2": {"image_size": [64, 48]}},
        "dt": [1e-4],
        "frame_per_dt": 2,
        "target": {"pitch": -1.0, "dot_diameter": 2e-3, "mark_diameter": 3e-3, "marks": {}},
    }
    (tmp_path / "experiment.json").write_text(json.dumps(spec))
    with pytest.raises(DescriptionError) as raised:
        read_experiment(tmp_path, needs=("particles", "calibration"))
    message = str(raised.value)
    assert "\n" not in message and message.startswith(f"{tmp_path / 'experiment.json'}: ")
    for fragment in (
        "(top level): unknown field(s) 'frame_per_dt'; known: format_version,",
        "cameras: camera name: expected",
        "cameras.cam1.image_size: [64] is too short",
        "cameras.cam1.pixel_pitch: required to calibrate",
        "dt: [0.0001]: the multi-Δt method needs at least two Δt values",
        "frames_per_dt: required to process particle images",
        "target.marks: {} should be non-empty",
        "target.pitch: -1.0 is less than or equal to the minimum of 0",
        "traverse_z: required to calibrate",
        "calibration_images: required to calibrate",
    ):
        assert fragment in message


@settings(max_examples=20, deadline=None)
@given(
    image=arrays(
        st.sampled_from([np.uint8, np.uint16]),
        st.tuples(st.integers(1, 40), st.integers(1, 40)),
    ),
    suffix=st.sampled_from([".png", ".tif"]),
)
def test_grey_images_read_back_as_written(tmp_path_factory, image, suffix):
    path = tmp_path_factory.mktemp("img") / f"frame{suffix}"
    if suffix == ".png":
        cv2.imwrite(str(path), image)
    else:
        tifffile.imwrite(path, image)
    back = read_image(path)
    assert back.dtype == image.dtype
    np.testing.assert_array_equal(back, image)


def test_colour_unknown_and_corrupt_images_are_refused(tmp_path):
    colour = tmp_path / "colour.png"
    cv2.imwrite(str(colour), np.zeros((8, 8, 3), np.uint8))
    with pytest.raises(ImageError, match=r"colour\.png: expected a 2-D grey image"):
        read_image(colour)
    with pytest.raises(ImageError, match=r"frame\.jpg: images must be TIFF or PNG"):
        (tmp_path / "frame.jpg").write_bytes(b"")
        read_image(tmp_path / "frame.jpg")
    (tmp_path / "bad.png").write_text("not an image")
    with pytest.raises(ImageError, match=r"bad\.png: not readable as a PNG image"):
        read_image(tmp_path / "bad.png")


def _png_dataset(folder, mask=None):
    """Two cameras, one frame pair per Δt, PNG frames with one bright spot at (20, 10)."""
    spec = json.loads(json.dumps(PARTICLES))
    spec["particle_images"] = "img/{camera}_{k}_{m}{a|b}.png"
    spec["bit_depth"] = 16
    folder.mkdir()
    frame = np.full((48, 64), 100, np.uint16)
    y, x = np.mgrid[:48, :64]
    for cx, cy in ((20.3, 10.6), (50.2, 30.4)):
        frame += (3000 * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / (2 * 0.8**2))).astype(np.uint16)
    (folder / "img").mkdir()
    for c in ("cam1", "cam2"):
        for k in range(2):
            for f in "ab":
                cv2.imwrite(str(folder / "img" / f"{c}_{k}_0{f}.png"), frame)
    if mask is not None:
        spec["cameras"]["cam1"]["mask"] = "mask_cam1.png"
        cv2.imwrite(str(folder / "mask_cam1.png"), mask)
    (folder / "experiment.json").write_text(json.dumps(spec))
    return folder


def test_particles_on_a_mask_s_zero_pixels_are_not_detected(tmp_path):
    mask = np.full((48, 64), 255, np.uint8)
    mask[:, 40:] = 0  # hides the spot at x = 50
    dataset = open_dataset(_png_dataset(tmp_path / "ds", mask))
    cam1, cam2 = ImageDetector(dataset).detections(0, 0, "a")
    np.testing.assert_allclose(cam1, [[20.3, 10.6]], atol=0.05)
    assert len(cam2) == 2


def test_a_mask_of_the_wrong_size_is_refused(tmp_path):
    folder = _png_dataset(tmp_path / "ds", np.full((40, 64), 255, np.uint8))
    with pytest.raises(DatasetError, match=r"mask_cam1\.png: mask of 64 × 40 px, but the camera"):
        open_dataset(folder)


def test_detections_within_a_mask_keep_those_on_true_pixels():
    found = Detections(
        xy=[[1.2, 0.8], [3.6, 2.4], [-0.4, 1.0]],
        intensity=[1, 2, 3],
        peak=[1, 2, 3],
        size=[1, 1, 1],
        flags=[0, 0, 0],
        shape=(4, 5),
    )
    mask = np.zeros((4, 5), bool)
    mask[1, 1] = mask[1, 0] = True
    np.testing.assert_array_equal(found.within(mask).intensity, [1.0, 3.0])


def test_the_documented_example_meets_the_schema():
    page = (Path(__file__).parents[2] / "docs" / "experiment.md").read_text()
    example = json.loads(page.split("```json\n", 1)[1].split("```", 1)[0])
    assert description_problems(example, needs=("particles", "calibration")) == []


def test_a_time_resolved_recording_is_cut_into_shared_first_frame_pairs(tmp_path):
    spec = {
        "cameras": {"c1": {"image_size": [64, 48]}, "c2": {"image_size": [64, 48]}},
        "time_resolved": {
            "frame_rate": 1000.0,
            "images": "seq/{camera}/{n:04d}.png",
            "steps": [1, 3],
            "first": 2,
            "last": 14,
        },
    }
    (tmp_path / "experiment.json").write_text(json.dumps(spec))
    for c in ("c1", "c2"):
        (tmp_path / "seq" / c).mkdir(parents=True)
        for n in range(2, 15):
            cv2.imwrite(str(tmp_path / "seq" / c / f"{n:04d}.png"), np.full((48, 64), n, np.uint8))
    dataset = open_dataset(tmp_path)
    np.testing.assert_allclose(dataset.dt, [1e-3, 3e-3])
    # stride = the largest step, 3: frames a 2, 5, 8, 11 (11 + 3 = 14 is the last).
    assert dataset.frames == (4, 4) and dataset.shared_first_frame
    assert dataset.read_frame(1, "c2", 3, "a")[0, 0] == 11
    assert dataset.read_frame(1, "c2", 3, "b")[0, 0] == 14
    assert dataset.read_frame(0, "c1", 2, "b")[0, 0] == 9
    # Tracking reads every frame: 2 … 14, or those the first two snapshots span, 2 … 8.
    assert dataset.sequence.frame_numbers() == range(2, 15)
    assert dataset.sequence.frame_numbers(2) == range(2, 9)
    assert dataset.sequence.frame_numbers(100) == range(2, 15)
    assert dataset.read_recorded("c1", 7)[0, 0] == 7
    (tmp_path / "seq" / "c2" / "0013.png").unlink()
    assert dataset.missing_recorded(range(12, 15)) == [tmp_path / "seq" / "c2" / "0013.png"]


def test_a_time_resolved_recording_replaces_the_frame_pair_fields(tmp_path):
    spec = {
        **PARTICLES,
        "time_resolved": {
            "frame_rate": -5.0,
            "images": "{camera}/{n}.tif",
            "steps": [2],
            "last": 9,
        },
    }
    problems = description_problems(spec, needs=("particles",))
    assert problems == [
        "(top level): time_resolved gives the Δt values and the frame pairs: leave out dt, "
        "frames_per_dt",
        "time_resolved.frame_rate: -5.0 is less than or equal to the minimum of 0",
        "time_resolved.steps: [2] is too short",
    ]


WINDOW = {"normal": [0, 0, 1], "distance": 0.03, "thickness": 0.01, "glass_index": 1.49,
          "medium_index": 1.33}  # fmt: skip


def test_a_window_belongs_to_a_point_target_and_has_every_field():
    spec = {
        **PARTICLES,
        "target": {"points": "cal/target.txt", "units": "mm"},
        "calibration_images": "cal/{camera}.tif",
        "calibration_seeds": "seeds.csv",
    }
    spec["cameras"] = {"cam1": {"image_size": [64, 48], "window": WINDOW},
                       "cam2": {"image_size": [64, 48], "window": {"normal": [0, 1]}}}  # fmt: skip
    problems = description_problems(spec, needs=("calibration",))
    assert any(p.startswith("cameras.cam2.window.normal: [0, 1] is too short") for p in problems)
    assert "cameras.cam2.window: 'distance' is a required property" in problems
    plate = {**PARTICLES, "cameras": {c: {"image_size": [64, 48], "window": WINDOW}
                                      for c in ("cam1", "cam2")}}  # fmt: skip
    assert description_problems(plate) == [
        f"cameras.{c}.window: only a point target's pinhole uses a window (a plate's "
        "model-free rays need none)"
        for c in ("cam1", "cam2")
    ]
