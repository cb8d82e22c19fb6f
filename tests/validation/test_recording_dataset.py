"""Rendered recordings (``validation.run.render_recording``): a lab's dataset and its truth.

A small recording (150 tracers in the paper-stereo sheet, 12 frames at τ_η/10, 3 plate
planes) is rendered once. It must be what ``synptv ptv`` reads as a time-resolved
dataset, its truth must be the particles the images show (every visible particle's
image position is the camera's projection of its true position, exactly), the frames
must not depend on how the work is cut into chunks, and a folder left half-written must
be completed to the same bits.
"""

import json
from dataclasses import replace

import h5py
import numpy as np
import pytest
import tifffile

from ptv.io.dataset import open_dataset
from simulator.presets import flow_preset
from simulator.rigs import load_rig
from validation.run import render_recording as recording_module
from validation.run.render_dataset import RenderSettings, ks_flow
from validation.run.render_recording import (
    RecordingPlan,
    build_recording_dataset,
    sequence_folder,
)
from validation.truth.recording_truth import read_recording_truth

FRAMES = 12


@pytest.fixture(scope="module")
def setup():
    preset = flow_preset("lem-10hz")
    settings = RenderSettings(planes=3, particles=150, n_modes=40, seed=3)
    plan = RecordingPlan(
        frame_rate=1.0 / (0.1 * preset.parameters.tau_eta),
        frames=FRAMES,
        sequences=2,
        steps=(1, 2),
    )
    return load_rig("paper-stereo"), preset, ks_flow(preset, settings), settings, plan


@pytest.fixture(scope="module")
def rendered(setup, tmp_path_factory):
    rig, preset, flow, settings, plan = setup
    folder = tmp_path_factory.mktemp("recorded") / "dataset"
    return build_recording_dataset(folder, rig, preset, flow, settings, plan)


def test_each_sequence_is_a_time_resolved_dataset(rendered, setup):
    rig, _, _, _, plan = setup
    for s in range(plan.sequences):
        dataset = open_dataset(sequence_folder(rendered, s))
        assert dataset.sequence is not None
        assert dataset.sequence.frame_rate == plan.frame_rate
        assert list(dataset.sequence.frame_numbers()) == list(range(FRAMES))
        assert dataset.cameras == tuple(rig.camera_names)
    top = json.loads((rendered / "experiment.json").read_text())
    assert top["calibration_images"] == "calibration/{camera}/plane_{j:02d}.tif"
    assert "time_resolved" not in top


def test_the_truth_is_what_the_images_show(rendered, setup):
    rig, _, _, _, _ = setup
    truth = read_recording_truth(sequence_folder(rendered, 0))
    assert np.all(np.diff(truth.frame) >= 0)
    # Every particle-frame is inside the sheet, and the sheet holds its mean count.
    assert np.all(rig.sheet.contains(truth.position))
    per_frame = np.bincount(truth.frame, minlength=FRAMES)
    assert abs(per_frame.mean() - 150) < 5 * np.sqrt(150)
    for name, camera in zip(rig.camera_names, rig.cameras, strict=True):
        seen = truth.visible[name]
        assert seen.mean() > 0.9
        projected = camera.project(truth.position[seen])
        np.testing.assert_allclose(truth.xy[name][seen], projected, atol=2e-4)
        assert np.isnan(truth.xy[name][~seen]).all()
        image = tifffile.imread(sequence_folder(rendered, 0) / f"images/{name}/000003.tif")
        assert image.shape == tuple(camera.lens.sensor_size[::-1]) and image.dtype == np.uint16
    # Particles enter and leave the sheet during the recording.
    first = {p for p, f in zip(truth.particle, truth.frame, strict=True) if f == 0}
    last = {p for p, f in zip(truth.particle, truth.frame, strict=True) if f == FRAMES - 1}
    assert first - last and last - first


def test_sequences_are_independent_realizations(rendered):
    a = read_recording_truth(sequence_folder(rendered, 0))
    b = read_recording_truth(sequence_folder(rendered, 1))
    assert not np.allclose(a.position[:10], b.position[:10])


def test_frames_do_not_depend_on_the_chunks_and_a_half_written_folder_resumes(
    rendered, setup, tmp_path, monkeypatch
):
    rig, preset, flow, settings, plan = setup
    single = replace(plan, sequences=1)
    folder = tmp_path / "dataset"
    monkeypatch.setattr(recording_module, "FRAMES_PER_CHUNK", 5)
    calls = []
    original = recording_module.render_frames

    def interrupted(item, *, job):
        if len(calls) == 1:
            raise KeyboardInterrupt
        calls.append(item[0])
        return original(item, job=job)

    monkeypatch.setattr(recording_module, "render_frames", interrupted)
    with pytest.raises(KeyboardInterrupt):
        build_recording_dataset(folder, rig, preset, flow, settings, single)
    with h5py.File(sequence_folder(folder, 0) / "truth.h5", "r") as f:
        assert f["progress/chunks"][:].tolist() == [True, False, False]
    monkeypatch.setattr(recording_module, "render_frames", original)
    build_recording_dataset(folder, rig, preset, flow, settings, single)
    for name in rig.camera_names:
        for n in (0, 7, FRAMES - 1):
            path = f"images/{name}/{n:06d}.tif"
            np.testing.assert_array_equal(
                tifffile.imread(sequence_folder(folder, 0) / path),
                tifffile.imread(sequence_folder(rendered, 0) / path),
            )
    ours = read_recording_truth(sequence_folder(folder, 0))
    theirs = read_recording_truth(sequence_folder(rendered, 0))
    for name in rig.camera_names:
        np.testing.assert_array_equal(ours.xy[name], theirs.xy[name])
