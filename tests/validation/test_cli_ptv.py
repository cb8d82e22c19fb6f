"""``synptv ptv``: results, summary and figures from a dataset folder; tracks through a
time-resolved recording; bad input."""

import dataclasses
import json
import os
import shutil

import h5py
import matplotlib.image
import numpy as np
import pytest
from scipy.spatial import cKDTree

from ptv.calibration.io import load_calibrations, read_calibrated_volume, save_calibrations
from ptv.pipeline.time_resolved import MISS_NOISE_FACTOR
from ptv.settings import PipelineSettings, PtvSettings
from simulator.particles import Box
from simulator.presets import flow_preset
from simulator.rigs import load_rig
from validation.cli import main
from validation.commands.ptv import with_derived_volumes
from validation.dataset.calibrate import calibrate_dataset
from validation.report.ptv_figures import FIGURE_FILES
from validation.run.particle_chunks import particle_path, render_chunk
from validation.run.render_dataset import RenderSettings, particle_job, write_dataset
from validation.score.track_file import read_tracks

SETTINGS = RenderSettings(frames=2, planes=3, particles=600, n_modes=80, seed=5)
#: The recording: 8 frames at 2 kHz, cut into frame pairs 1 and 3 frames apart.
FRAME_RATE, FRAMES, STEPS = 2000.0, 8, (1, 3)


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    folder = tmp_path_factory.mktemp("cli-ptv") / "ds"
    write_dataset(folder, load_rig("paper-stereo"), flow_preset("lem-10hz"), SETTINGS)
    cal = calibrate_dataset(folder, methods=("model-free",))
    return folder, cal.files["model-free"]


def test_ptv_command_writes_results_summary_and_figures(dataset, tmp_path, capsys):
    folder, calibration = dataset
    out = tmp_path / "out"
    argv = ["ptv", "--dataset", str(folder), "--calibration", str(calibration)]
    code = main([*argv, "--out", str(out), "--max-speed", "1.2", "--quiet"])
    printed = capsys.readouterr()
    assert code == 0, printed.err
    assert "epsilon plateau" in printed.out and "u' (Eulerian variance fit)" in printed.out
    # --quiet: no progress bar; the one warning says the statistics ranges are the paper's
    assert printed.err.splitlines() == [
        line for line in printed.err.splitlines() if line.startswith("synptv ptv: warning: ")
    ]
    assert "r range or plateau is the default, chosen for the paper's" in printed.err
    assert "max_speed 1.2 m/s (given)" in printed.out
    names = {p.name for p in out.iterdir()}
    assert names == {"results.h5", "summary.json", *FIGURE_FILES.values()}
    for name in FIGURE_FILES.values():
        image = matplotlib.image.imread(out / name)
        assert image.ndim == 3 and image.shape[0] > 300 and image.shape[1] > 400
    summary = json.loads((out / "summary.json").read_text())
    assert summary["settings"]["max_speed"] == 1.2
    assert summary["dataset"] == str(folder) and summary["calibration"] == str(calibration)
    assert [c["snapshots_kept"] for c in summary["counts"]] == [2] * 5
    assert summary["epsilon"]["plateau"]["epsilon"] > 0
    # The smallest Δt is linked around X(t) within max_speed·Δt + 5σ_b; the others share
    # its frame a and are linked around their predictions, within the measured misses.
    assert summary["counts"][0]["link_radius"] == pytest.approx(1.2 * 0.97e-4 + 1.5e-4, rel=2e-3)
    radii = summary["settings"]["predicted_radii"]
    assert radii[0] is None and all(0 < r < 1.2 * 0.97e-4 + 1.5e-4 for r in radii[1:])
    assert [c["link_radius"] for c in summary["counts"][1:]] == radii[1:]
    with h5py.File(out / "results.h5") as f:
        assert f["statistics/s2"].shape == (24,)
        assert f["particles/dt0/offsets"].shape == (3,)


def test_ptv_command_processes_the_first_snapshots_only(dataset, tmp_path, capsys):
    folder, calibration = dataset
    out = tmp_path / "one"
    argv = ["ptv", "--dataset", str(folder), "--calibration", str(calibration)]
    assert main([*argv, "--out", str(out), "--snapshots", "1", "--quiet"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert [c["snapshots_processed"] for c in summary["counts"]] == [1] * 5
    assert summary["errors"] == "pairs"  # one snapshot per Δt: no bootstrap
    capsys.readouterr()


def test_a_settings_file_sets_every_stage_and_the_command_line_overrides_it(
    dataset, tmp_path, capsys
):
    folder, calibration = dataset
    settings = tmp_path / "settings.toml"
    settings.write_text(
        "[detection]\nthreshold_sigmas = 7.0\n[matching]\ntolerance = 2.0e-4\n"
        "[linking]\nmax_speed = 1.2\n[statistics]\nn_bins = 12\n[run]\nsnapshots = 1\n"
    )
    argv = ["ptv", "--dataset", str(folder), "--calibration", str(calibration), "--quiet"]
    out = tmp_path / "set"
    assert main([*argv, "--settings", str(settings), "--max-speed", "1.3", "--out", str(out)]) == 0
    used = json.loads((out / "summary.json").read_text())["settings"]
    assert used["threshold_sigmas"] == 7.0 and used["tolerance"] == 2.0e-4
    assert used["n_bins"] == 12 and used["snapshots"] == 1
    assert used["max_speed"] == 1.3  # the command line over the file
    capsys.readouterr()
    assert main(["ptv", "--settings", str(settings), "--print-settings"]) == 0
    printed = capsys.readouterr().out
    assert "threshold_sigmas = 7.0" in printed and "n_bins = 12" in printed


def test_the_volumes_left_out_are_the_calibrated_volume_and_its_core(dataset, tmp_path, capsys):
    # The plate's 21 × 21 dots, 5 mm apart, over the traverse experiment.json gives.
    folder, calibration = dataset
    z = json.loads((folder / "experiment.json").read_text())["traverse_z"]
    plate = ((-0.05, -0.05, min(z)), (0.05, 0.05, max(z)))
    np.testing.assert_allclose(read_calibrated_volume(calibration), plate, atol=1e-12)
    out = tmp_path / "derived"
    argv = ["ptv", "--dataset", str(folder), "--calibration", str(calibration), "--quiet"]
    assert main([*argv, "--out", str(out), "--snapshots", "1", "--positions-only"]) == 0
    printed = capsys.readouterr()
    assert "matching volume 100 × 100 × " in printed.out and "the calibrated volume" in printed.out
    # The traverse spans 2 mm of the 10 mm sheet: most particles lie outside the volume
    # calibrated, and one line says so (nothing about S2: positions only).
    (line,) = printed.err.splitlines()
    assert "that the matching volume holds the particles" in line
    used = json.loads((out / "summary.json").read_text())["settings"]
    np.testing.assert_allclose(used["volume"], plate, atol=1e-12)
    derived, line = with_derived_volumes(PtvSettings(), set(), calibration, statistics=True)
    depth = max(z) - min(z)
    core = ((-0.035, -0.035, -0.4 * depth), (0.035, 0.035, 0.4 * depth))
    np.testing.assert_allclose(derived.pipeline.statistics.analysis_volume, core, atol=1e-12)
    assert "analysis volume 70 × 70 × " in line
    # --print-settings leaves them out, saying what takes their place
    assert main(["ptv", "--print-settings"]) == 0
    printed = capsys.readouterr().out
    assert "# volume = ...  # matching volume" in printed and "the calibrated volume" in printed
    assert "# analysis_volume = ...  # statistics box" in printed


def test_overlays_draw_the_detections_of_the_snapshots_asked_for(dataset, tmp_path, capsys):
    folder, calibration = dataset
    out = tmp_path / "overlay"
    argv = ["ptv", "--dataset", str(folder), "--calibration", str(calibration), "--quiet"]
    argv += ["--snapshots", "1", "--positions-only", "--out", str(out)]
    assert main([*argv, "--overlay", "1"]) == 0
    assert "detections drawn over 4 images" in capsys.readouterr().out
    width, height = json.loads((folder / "experiment.json").read_text())["cameras"]["cam1"][
        "image_size"
    ]
    for camera in ("cam1", "cam2"):
        for frame in "ab":
            picture = matplotlib.image.imread(out / f"overlay_{camera}_000001_{frame}.png")
            assert picture.shape == (height, width, 3)
    # Up front: a snapshot the dataset does not have, or no number, and nothing written.
    refused = tmp_path / "refused"
    assert main([*argv[:-1], str(refused), "--overlay", "2"]) == 2
    assert "--overlay 2: the dataset has 2 snapshots" in capsys.readouterr().err
    assert main([*argv[:-1], str(refused), "--overlay", "first"]) == 2
    assert "expected snapshot numbers >= 0" in capsys.readouterr().err
    assert not refused.exists()


def test_a_calibration_without_its_volume_is_refused_before_any_work(dataset, tmp_path, capsys):
    folder, calibration = dataset
    older = save_calibrations(tmp_path / "older.h5", load_calibrations(calibration))
    out = tmp_path / "older"
    argv = ["ptv", "--dataset", str(folder), "--calibration", str(older), "--out", str(out)]
    assert main([*argv, "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "older.h5: the file records no calibrated volume" in err
    assert "set [matching] volume and [statistics] analysis_volume" in err
    assert len(err.strip().splitlines()) == 1 and not out.exists()


def test_an_analysis_volume_off_the_particles_names_the_setting(dataset, tmp_path, capsys):
    folder, calibration = dataset
    settings = tmp_path / "off.toml"
    settings.write_text("[statistics]\nanalysis_volume = [[1.0, 1.0, 1.0], [1.1, 1.1, 1.1]]\n")
    argv = ["ptv", "--dataset", str(folder), "--calibration", str(calibration), "--quiet"]
    argv += ["--settings", str(settings), "--snapshots", "1", "--max-speed", "1.2"]
    assert main([*argv, "--out", str(tmp_path / "off")]) == 2
    err = capsys.readouterr().err
    assert "only 0 Δt value(s) with particle links in the analysis volume" in err
    assert "[statistics] analysis_volume" in err and "--positions-only" in err


def test_ptv_command_reports_bad_input_in_one_line(dataset, tmp_path, capsys):
    folder, calibration = dataset
    out = str(tmp_path / "bad")
    code = main(
        ["ptv", "--dataset", str(tmp_path / "nowhere"), "--calibration", "x.h5", "--out", out]
    )
    err = capsys.readouterr().err
    assert (
        code == 2
        and err.startswith("synptv ptv: error: dataset folder")
        and "does not exist" in err
    )
    calibrations = load_calibrations(calibration)
    other = save_calibrations(
        tmp_path / "other.h5", {"cam1": calibrations["cam1"], "left": calibrations["cam2"]}
    )
    argv = ["ptv", "--dataset", str(folder), "--calibration", str(other), "--out", out, "--quiet"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "cameras don't match the calibration" in err and len(err.strip().splitlines()) == 1
    argv = ["ptv", "--dataset", str(folder), "--calibration", str(calibration), "--out", out]
    assert main([*argv, "--max-speed", "-1", "--quiet"]) == 2
    assert "max_speed must be a finite number > 0" in capsys.readouterr().err
    assert main([*argv, "--min-cameras", "3", "--quiet"]) == 2
    assert "min_cameras is 3 but the dataset has 2 cameras" in capsys.readouterr().err
    assert main([*argv, "--min-cameras", "1", "--quiet"]) == 2
    assert "min_cameras must be an integer >= 2" in capsys.readouterr().err
    assert not (tmp_path / "bad").exists()


@pytest.mark.parametrize("value", ["-15.0", "'large'", "15.0\nbackground = 'tophat'"])
def test_a_bad_particle_diameter_is_refused_in_one_line_before_anything_is_written(
    tmp_path, capsys, value
):
    settings = tmp_path / "settings.toml"
    settings.write_text(f"[detection]\ndiameter = {value}\n")
    before = sorted(tmp_path.rglob("*"))
    argv = ["ptv", "--dataset", str(tmp_path / "ds"), "--calibration", str(tmp_path / "c.h5")]
    code = main([*argv, "--settings", str(settings), "--out", str(tmp_path / "out")])
    lines = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(lines) == 1
    assert f"{settings}: [detection] diameter" in lines[0]
    assert sorted(tmp_path.rglob("*")) == before


def test_a_failure_after_the_pipeline_leaves_the_earlier_output_untouched(
    dataset, tmp_path, capsys, monkeypatch
):
    import validation.report.ptv_figures

    folder, calibration = dataset
    out = tmp_path / "out"
    argv = ["ptv", "--dataset", str(folder), "--calibration", str(calibration)]
    argv += ["--out", str(out), "--snapshots", "1", "--quiet"]
    assert main(argv) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}

    def fails(result, folder, **options):
        raise ValueError("a figure cannot be drawn")

    monkeypatch.setattr(validation.report.ptv_figures, "save_ptv_figures", fails)
    assert main([*argv, "--max-speed", "1.2"]) == 2  # results that differ, if written
    assert "a figure cannot be drawn" in capsys.readouterr().err
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before  # no lock, no staging


def test_a_folder_held_by_another_command_is_refused_before_the_pipeline(dataset, tmp_path, capsys):
    from validation.workflow.files import hold_output_folder

    folder, calibration = dataset
    out = tmp_path / "out"
    argv = ["ptv", "--dataset", str(folder), "--calibration", str(calibration)]
    with hold_output_folder(out, "synptv ptv"):
        assert main([*argv, "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "is in use by synptv ptv" in err and err.count("\n") == 1


def test_positions_only_writes_the_points_and_links_without_statistics(dataset, tmp_path, capsys):
    folder, calibration = dataset
    out = tmp_path / "positions"
    argv = ["ptv", "--dataset", str(folder), "--calibration", str(calibration), "--quiet"]
    assert main([*argv, "--positions-only", "--out", str(out)]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["results.h5", "summary.json"]
    with h5py.File(out / "results.h5") as f:
        assert "statistics" not in f
        assert len(f["positions/x"]) > 0 and len(f["particles/dt0/positions"]) > 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["statistics_dt"] is None and "epsilon" not in summary
    assert "positions and links written to" in capsys.readouterr().out


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """A time-resolved recording of the rig of ``dataset`` (whose calibration it uses),
    and the true particle positions of its frames, (F, P, 3) m.

    Rendered as one shared-first-frame snapshot at Δt = τ … 7τ, whose frames a and b
    are the frames 0 … 7 of the recording; the seeding covers a 60 × 60 mm sheet, so that
    every particle images well inside the sensors.
    """
    root = tmp_path_factory.mktemp("cli-ptv-recording")
    rig = dataclasses.replace(load_rig("paper-stereo"), sheet=Box((0.06, 0.06, 0.008)))
    preset = flow_preset("lem-10hz")
    job = dataclasses.replace(
        particle_job(rig, preset, dataclasses.replace(SETTINGS, frames=1), images=root),
        dt=np.arange(1, FRAMES) / FRAME_RATE,
    )
    truth = render_chunk((0, 1), job=job).truth
    folder = root / "recording"
    for camera in rig.camera_names:
        (folder / "seq" / camera).mkdir(parents=True)
        frames = [particle_path(root, 0, camera, 0, "a")]
        frames += [particle_path(root, k, camera, 0, "b") for k in range(FRAMES - 1)]
        for n, path in enumerate(frames):
            os.link(path, folder / "seq" / camera / f"{n:06d}.tif")
    spec = {
        "cameras": {
            name: {"image_size": list(camera.lens.sensor_size)}
            for name, camera in zip(rig.camera_names, rig.cameras, strict=True)
        },
        "time_resolved": {
            "frame_rate": FRAME_RATE,
            "images": "seq/{camera}/{n:06d}.tif",
            "steps": list(STEPS),
            "last": FRAMES - 1,
        },
        "bit_depth": SETTINGS.sensor.bit_depth,
    }
    (folder / "experiment.json").write_text(json.dumps(spec))
    positions = [truth[0].positions[0, 0]] + [run.positions[0, 1] for run in truth]
    return folder, np.stack(positions)


def read_tracks_csv(path):
    """The header and the rows (K, 6) of a tracks.csv."""
    with open(path) as f:
        header = f.readline().strip()
    return header, np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)


def by_rows(points):
    """Points (N, 3) sorted by x, then y, then z."""
    return points[np.lexsort(points.T[::-1])]


def test_tracks_link_every_frame_of_a_recording(dataset, recording, tmp_path, capsys):
    _, calibration = dataset
    folder, truth = recording
    settings = tmp_path / "settings.toml"
    # The calibration's traverse spans 2 mm of the sheet: the matching volume is given
    # (the paper's sheet and 1 mm).
    settings.write_text(
        "[linking]\nmax_acceleration = 400.0\n"
        "[matching]\nvolume = [[-0.051, -0.051, -0.006], [0.051, 0.051, 0.006]]\n"
    )
    out = tmp_path / "tracks"
    argv = ["ptv", "--dataset", str(folder), "--calibration", str(calibration), "--quiet"]
    argv += ["--settings", str(settings), "--out", str(out)]
    assert main([*argv, "--positions-only", "--tracks"]) == 0
    printed = capsys.readouterr().out
    assert "tracks written to" in printed and "mean length" in printed
    names = sorted(p.name for p in out.iterdir())
    assert names == [
        "results.h5",
        "summary.json",
        "tracks.csv",
        "tracks.png",
        "tracks_fit.json",
        "tracks_fitted.csv",
    ]
    # The fit, as synptv score reads a code's tracks: the points of the tracks of five
    # points or more (less the outliers), with a velocity and an acceleration each.
    fitted = read_tracks(out / "tracks_fitted.csv")
    fit = json.loads((out / "tracks_fit.json").read_text())
    assert len(fitted.frame) == fit["points"] > 0 and fitted.acceleration is not None
    assert np.isfinite(fitted.velocity).all() and "tracks fitted" in printed
    # With the noise removed over several steps: the noise a fraction of the raw value.
    lagrangian = fit["lagrangian"]["acceleration_variance"]
    assert 0 < lagrangian["total"] < lagrangian["raw"] and "Lagrangian" in printed
    assert matplotlib.image.imread(out / "tracks.png").ndim == 3
    header, rows = read_tracks_csv(out / "tracks.csv")
    assert header == "track,frame,time_s,x,y,z"
    track, frame = rows[:, 0].astype(int), rows[:, 1].astype(int)
    with h5py.File(out / "results.h5") as f:
        g = f["tracks"]
        points = np.column_stack([g[axis][:] for axis in "xyz"])
        np.testing.assert_array_equal(g["track"][:], track)
        np.testing.assert_array_equal(g["frame"][:], frame)
        np.testing.assert_allclose(rows[:, 3:], points, rtol=1e-8)
        assert g["frames/number"][:].tolist() == list(range(FRAMES))
        assert g["frames/matches"][:].tolist() == np.bincount(frame).tolist()
        pairs = {key: f["positions"][key][:] for key in ("dt", "snapshot", "frame", *"xyz")}
    # Every frame of the recording, not only the frames of the pairs (0, 1, 3, 4, 6).
    assert set(frame.tolist()) == set(range(FRAMES))
    np.testing.assert_allclose(rows[:, 2], frame / FRAME_RATE, rtol=1e-8)
    same = track[1:] == track[:-1]
    # Frames increase along a track, by at most the default missed frames plus one, and
    # one more where a join left out a track's last point (ptv.tracking.stitching).
    steps = range(1, PipelineSettings().track_gap + 3)
    assert np.all(np.diff(track) >= 0) and np.all(np.isin(np.diff(frame)[same], steps))
    # The points of each frame of a pair are those --positions-only writes for it.
    pair_points = np.column_stack([pairs[axis] for axis in "xyz"])
    is_b = pairs["frame"] == b"b"
    number = pairs["snapshot"] * max(STEPS) + np.where(is_b, np.take(STEPS, pairs["dt"]), 0)
    keys = np.column_stack([pairs["dt"], pairs["snapshot"], is_b])
    for key in np.unique(keys, axis=0):
        sel = np.all(keys == key, axis=1)
        mine = points[frame == number[sel][0]]
        np.testing.assert_array_equal(by_rows(mine), by_rows(pair_points[sel]))
    summary = json.loads((out / "summary.json").read_text())
    t = summary["tracks"]
    assert t["tracks"] == len(np.unique(track)) == sum(t["length_histogram"]["count"])
    assert t["points"] == len(rows) and t["frames"] == [0, FRAMES - 1]
    assert summary["settings"]["max_acceleration"] == 400.0
    # The prediction's radius follows the noise the first pass's tracks show, where that
    # is below the settings' 30 µm (ptv.pipeline.time_resolved.track_points).
    noise = min(30e-6, MISS_NOISE_FACTOR * t["miss_noise"])
    assert t["predicted_radius"] == pytest.approx(400.0 / FRAME_RATE**2 + 5 * 6**0.5 * noise)
    # Against the truth: each point's nearest true particle (after the small offset of
    # the calibration's frame); links between two real particles. The particles move
    # u'τ ≈ 0.1 mm per component a frame and are 3.6 mm apart: a wrong link is rare.
    offset = np.median(points - truth[frame, cKDTree(truth[0]).query(points)[1]], axis=0)
    particle = np.full(len(points), -1)
    for n in range(FRAMES):
        sel = frame == n
        distance, nearest = cKDTree(truth[n]).query(points[sel] - offset)
        particle[sel] = np.where(distance < 0.2e-3, nearest, -1)
    real = same & (particle[1:] >= 0) & (particle[:-1] >= 0)
    assert real.sum() > 0.8 * same.sum()
    assert np.mean(particle[1:][real] == particle[:-1][real]) >= 0.99


def test_tracks_of_the_first_snapshots_stop_at_their_last_frame(
    dataset, recording, tmp_path, capsys
):
    _, calibration = dataset
    out = tmp_path / "first"
    argv = ["ptv", "--dataset", str(recording[0]), "--calibration", str(calibration)]
    assert main([*argv, "--out", str(out), "--tracks", "--snapshots", "1", "--quiet"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    # Snapshot 0 pairs frame 0 with frames 1 and 3: frames 0 … 3 are tracked.
    assert summary["tracks"]["frames"] == [0, 3]
    assert set(read_tracks_csv(out / "tracks.csv")[1][:, 1].astype(int)) == {0, 1, 2, 3}
    capsys.readouterr()


def test_tracks_need_a_whole_time_resolved_recording(dataset, recording, tmp_path, capsys):
    folder, calibration = dataset
    out = tmp_path / "out"
    argv = ["ptv", "--calibration", str(calibration), "--out", str(out), "--tracks", "--quiet"]
    assert main([*argv, "--dataset", str(folder)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("synptv ptv: error: --tracks needs a time-resolved recording")
    assert err.count("\n") == 1 and not out.exists()
    # Frame 5 is in no frame pair, but tracking needs it.
    gap = tmp_path / "gap"
    shutil.copytree(recording[0], gap, copy_function=os.link)
    (gap / "seq" / "cam1" / "000005.tif").unlink()
    assert main([*argv, "--dataset", str(gap)]) == 2
    err = capsys.readouterr().err
    assert "particle image" in err and "000005.tif is missing" in err and err.count("\n") == 1
    assert not out.exists()
