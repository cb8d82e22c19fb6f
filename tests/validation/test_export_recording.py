"""``synptv export --format openptv`` of a recorded dataset: every recorded frame is an
image of one OpenPTV sequence under the number frames.csv gives it, and sequence.par and
track.par describe the recording (its frames; one frame interval's bounds from the true
velocities and accelerations); a recording's own folder, or a recording asked of MyPTV's
layout, is a one-line error that writes nothing."""

import csv

import h5py
import numpy as np
import pytest
import tifffile

from simulator.presets import flow_preset
from simulator.rigs import load_rig
from validation.cli import main
from validation.export.openptv import NOISE_GUESS_PX
from validation.run.experiment import object_pixel
from validation.run.render_dataset import RenderSettings, ks_flow
from validation.run.render_recording import RecordingPlan, build_recording_dataset, sequence_folder

FRAMES = 12
FIRST_NUMBER = 10001


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """A recorded dataset: 150 tracers, 12 frames at τ_η/10, 3 plate planes."""
    preset = flow_preset("lem-10hz")
    settings = RenderSettings(planes=3, particles=150, n_modes=40, seed=5)
    plan = RecordingPlan(
        frame_rate=1.0 / (0.1 * preset.parameters.tau_eta), frames=FRAMES, sequences=1, steps=(1, 2)
    )
    folder = tmp_path_factory.mktemp("recorded") / "dataset"
    rig = load_rig("paper-stereo")
    build_recording_dataset(folder, rig, preset, ks_flow(preset, settings), settings, plan)
    out = folder.parent / "openptv"
    argv = ["export", "--dataset", str(folder), "--format", "openptv", "--out", str(out)]
    assert main(argv) == 0
    return folder, out, plan, rig


def test_every_recorded_frame_is_an_image_of_one_sequence(recorded):
    folder, out, _, _ = recorded
    with (out / "frames.csv").open() as stream:
        rows = list(csv.DictReader(stream))
    assert [(int(r["frame"]), int(r["number"])) for r in rows] == [
        (n, FIRST_NUMBER + n) for n in range(FRAMES)
    ]
    shifts = set()
    for row in rows:
        for camera in ("cam1", "cam2"):
            original = tifffile.imread(
                sequence_folder(folder, 0) / f"images/{camera}/{int(row['frame']):06d}.tif"
            ).astype(np.int64)
            exported = tifffile.imread(out / f"img/seq0/{camera}.{row['number']}")
            assert exported.dtype == np.uint8
            shifts |= {
                s for s in range(9) if np.array_equal(exported, np.minimum(original >> s, 255))
            }
    assert len(shifts) == 1
    sequence = (out / "parameters/sequence.par").read_text().split()
    assert sequence == ["img/seq0/cam1.", "img/seq0/cam2.", "10001", str(10000 + FRAMES)]
    assert (out / "parameters/sequence_seq0.par").read_text().split() == sequence
    ptv = (out / "parameters/ptv.par").read_text().split()
    assert ptv[1] == f"img/seq0/cam1.{FIRST_NUMBER}"
    assert "Time-resolved acquisition" in (out / "README.txt").read_text()


def test_track_bounds_are_one_frame_interval_of_the_true_motion(recorded):
    """Displacement bounds max_speed·τ per component; dacc = max_acceleration·τ² plus
    five times the noise of three positions, √6 × 0.1 object-side pixel; max_speed and
    max_acceleration are |mean| + 5 max σ_i of the true values of the first five frames."""
    folder, out, plan, rig = recorded
    with h5py.File(sequence_folder(folder, 0) / "truth.h5", "r") as f:
        group = f["recording"]
        frame = group["frame"][()]
        velocity, acceleration = group["velocity"][()], group["acceleration"][()]
    first = frame < 5

    def bound(v):
        return np.linalg.norm(v.mean(axis=0)) + 5 * v.std(axis=0).max()

    tau = 1.0 / plan.frame_rate
    values = np.array((out / "parameters/track.par").read_text().split(), dtype=float)
    np.testing.assert_allclose(np.abs(values[:6]), bound(velocity[first]) * tau * 1e3, rtol=1e-6)
    noise = 5 * np.sqrt(6) * NOISE_GUESS_PX * object_pixel(rig)
    expected = (bound(acceleration[first]) * tau**2 + noise) * 1e3
    np.testing.assert_allclose(values[7], expected, rtol=1e-6)
    assert values[6] == 120 and values[8] == 0


def test_optv_reads_the_sequence_and_the_track_bounds(recorded):
    parameters = pytest.importorskip("optv.parameters")
    _, out, _, _ = recorded
    sequence = parameters.SequenceParams(num_cams=2)
    sequence.read_sequence_par(str(out / "parameters/sequence.par"), 2)
    assert (sequence.get_first(), sequence.get_last()) == (FIRST_NUMBER, 10000 + FRAMES)
    bounds = parameters.TrackingParams()
    bounds.read_track_par(str(out / "parameters/track.par"))
    values = np.array((out / "parameters/track.par").read_text().split(), dtype=float)
    assert bounds.get_dvxmax() == pytest.approx(values[1])
    assert bounds.get_dacc() == pytest.approx(values[7])


@pytest.mark.parametrize(
    ("which", "layout", "names"),
    [("sequence", "openptv", "sequence0"), ("dataset", "myptv", "--format openptv")],
)
def test_a_recording_exported_wrongly_is_one_line_and_writes_nothing(
    recorded, capsys, tmp_path, which, layout, names
):
    folder = recorded[0]
    given = sequence_folder(folder, 0) if which == "sequence" else folder
    before = set(tmp_path.iterdir())
    argv = ["export", "--dataset", str(given), "--format", layout, "--out", str(tmp_path / "o")]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and names in err
    assert set(tmp_path.iterdir()) == before
