"""Chunks of a rendered run: independent of how the run is cut, and the detections made
in memory are those of the TIFF files the same chunk writes."""

import itertools
from dataclasses import replace

import numpy as np
import pytest

from ptv.detect.frames import ImageDetector
from ptv.detect.store import DetectionStore, write_index
from ptv.io.dataset import open_dataset
from ptv.settings import DetectorSettings
from simulator.presets import flow_preset
from simulator.rigs import load_rig
from validation.run.particle_chunks import render_chunk, snapshot_chunks
from validation.run.render_dataset import (
    DetectionOutput,
    RenderSettings,
    build_dataset,
    particle_job,
)
from validation.truth.truth_file import TruthFile

SETTINGS = RenderSettings(frames=4, planes=2, particles=300, n_modes=60, seed=11)
DETECTOR = DetectorSettings(saturation=4095.0)


@pytest.mark.parametrize("frames", [1, 7, 8, 40, 1500])
def test_chunks_cover_every_snapshot_once(frames):
    chunks = snapshot_chunks(frames)
    assert chunks[0][0] == 0 and chunks[-1][1] == frames
    assert all(a[1] == b[0] for a, b in itertools.pairwise(chunks))
    assert max(m1 - m0 for m0, m1 in chunks) <= 10
    assert len(chunks) >= min(frames, 8)


@pytest.mark.parametrize("shared", [True, False])
def test_a_chunk_is_the_same_however_the_run_is_cut(shared):
    rig = load_rig("paper-stereo")
    settings = replace(SETTINGS, shared_first_frame=shared)
    job = particle_job(rig, flow_preset("lem-10hz"), settings, detector=DETECTOR)
    whole = render_chunk((0, 4), job=job)
    part = render_chunk((1, 3), job=job)
    for k, (a, b) in enumerate(zip(whole.truth, part.truth, strict=True)):
        assert b.first == 1 and a.first == 0
        assert np.array_equal(a.positions[1:3], b.positions)
        assert np.array_equal(a.velocity[1:3], b.velocity)
        for camera in rig.camera_names:
            assert np.array_equal(a.xy[camera][1:3], b.xy[camera], equal_nan=True)
            assert np.array_equal(a.visible[camera][1:3], b.visible[camera])
        for key, found in part.detections.items():
            assert key[1] in (1, 2) and (key[0] < 0) == (shared and key[2] == "a")
            for d_part, d_whole in zip(found, whole.detections[key], strict=True):
                assert np.array_equal(d_part.xy, d_whole.xy), (k, key)


def test_detections_in_memory_are_those_of_the_written_images(tmp_path):
    rig = load_rig("paper-stereo")
    preset = flow_preset("lem-10hz")
    folder, store = tmp_path / "ds", tmp_path / "detections"
    build_dataset(folder, rig, preset, SETTINGS, detections=DetectionOutput(store, DETECTOR))
    chunks = snapshot_chunks(SETTINGS.frames)
    frames = (SETTINGS.frames,) * len(preset.dt)
    write_index(
        store,
        cameras=rig.camera_names,
        dt=np.asarray(preset.dt),
        frames=frames,
        shared_first_frame=True,
        detector=DETECTOR.as_dict(),
        chunks=chunks,
        source=str(folder),
    )
    stored = DetectionStore(store)
    from_images = ImageDetector(open_dataset(folder), DetectorSettings())
    assert from_images.detector == stored.detector
    for k in range(len(preset.dt)):
        for m in range(SETTINGS.frames):
            for frame in "ab":
                read = from_images.detections(k, m, frame)
                kept = stored.detections(k, m, frame)
                assert all(np.array_equal(a, b) for a, b in zip(read, kept, strict=True))
    assert TruthFile(folder).frames == SETTINGS.frames


def test_a_chunk_of_a_rig_lit_through_its_depth_has_its_lit_particles_all_equally_bright():
    """A rig whose [sheet] asks for the top-hat profile lights the particles of its volume
    (its sheet in X and Y too) with it, and a rig that does not keeps the settings' own
    lighting."""
    job = particle_job(load_rig("lpt-challenge-small"), flow_preset("lem-10hz"), SETTINGS)
    assert job.lighting.sheet.profile == "top-hat" and job.lighting.sheet.half_width == 0.015
    chunk = render_chunk((0, 1), job=job)
    positions = chunk.truth[0].positions[0, 0]
    plain = particle_job(load_rig("paper-stereo"), flow_preset("lem-10hz"), SETTINGS)
    assert plain.lighting is SETTINGS.lighting
    inside = (np.abs(positions) <= [0.010, 0.0125, 0.015]).all(axis=1)  # the lit volume
    assert not inside.all()  # some in the padding, dark
    visible = chunk.truth[0].visible["cam1"][0, 0]
    np.testing.assert_array_equal(visible, inside)
