"""Double-frame PTV on a rendered dataset: particles against the truth, statistics, bad input.

The calibration's world frame is the nominal plate frame; the rendered plate is tilted
by 0.1° (REALISTIC imperfections), so the calibration itself puts particles up to
~85 µm off in Z at the sheet's corners. Positions are therefore compared with the
truth mapped into the calibration's frame (the affine map of the true dot centres onto
their nominal positions); displacements need no such map.
"""

import json
import logging
import os
import shutil

import h5py
import numpy as np
import pytest
import tifffile
from scipy.spatial import cKDTree

from ptv.calibration.grid_errors import nominal_positions
from ptv.calibration.io import load_calibrations
from ptv.detect.frames import ImageDetector
from ptv.io.dataset import DatasetError, open_dataset
from ptv.pipeline.double_frame import measure_snapshot, measure_snapshots, run_pipeline
from ptv.pipeline.resolve import match_frame, resolve_matching
from ptv.pipeline.results import load_runs, save_results
from ptv.settings import ANALYSIS_VOLUME, PipelineSettings, StatisticsSettings
from ptv.stats.links import RunParticles, shared_snapshots
from ptv.stats.mean_displacement import shared_mean_displacement
from ptv.stats.pairs import pair_sums
from ptv.stats.run_statistics import compute_statistics
from ptv.tracking.outliers import median_test_outliers
from simulator.presets import flow_preset
from simulator.rigs import load_rig
from simulator.target import PlateDesign
from validation.dataset.calibrate import calibrate_dataset
from validation.run.render_dataset import RenderSettings, write_dataset
from validation.truth.truth_file import TruthFile

SETTINGS = RenderSettings(frames=3, planes=3, particles=800)


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    folder = tmp_path_factory.mktemp("ptv") / "ds"
    write_dataset(folder, load_rig("paper-stereo"), flow_preset("lem-10hz"), SETTINGS)
    cal = calibrate_dataset(folder, methods=("model-free",))
    path = cal.files["model-free"]
    return folder, path, load_calibrations(path)


PROGRESS: list[tuple[int, int]] = []


@pytest.fixture(scope="module")
def result(rendered):
    folder, _, calibrations = rendered
    return run_pipeline(
        ImageDetector(open_dataset(folder)), calibrations, progress=lambda *p: PROGRESS.append(p)
    )


@pytest.fixture(scope="module")
def to_calibration_frame(rendered):
    """Affine map of true world points into the calibration's (nominal plate) frame."""
    folder = rendered[0]
    target = json.loads((folder / "experiment.json").read_text())["target"]
    keys = ("pitch", "dot_diameter", "mark_diameter", "columns", "rows", "thickness")
    design = PlateDesign(**{key: target[key] for key in keys})
    with h5py.File(folder / "truth.h5") as truth:
        true_dots = truth["plate/dots_world"][:].reshape(-1, 3)
        z = truth["plate/z_nominal"][:]
        nominal = nominal_positions(design.indices, design.pitch, z).reshape(-1, 3)
    design_matrix = np.column_stack([true_dots, np.ones(len(true_dots))])
    affine, *_ = np.linalg.lstsq(design_matrix, nominal, rcond=None)
    residual = design_matrix @ affine - nominal
    assert np.sqrt(np.mean(residual**2)) < 10e-6  # dot scatter and bow: a few µm

    def apply(points):
        points = np.asarray(points)
        return np.concatenate([points, np.ones((*points.shape[:-1], 1))], axis=-1) @ affine

    return apply


def _truth(folder, k):
    run = TruthFile(folder).runs()[k]
    visible = np.all([run.visible[c] for c in ("cam1", "cam2")], axis=0)
    return run.positions, visible


def test_pipeline_runs_on_every_dt(result):
    st = result.statistics
    assert len(result.runs) == 5 and st.dt.size == 5
    for run in result.runs:
        assert list(run.snapshot_ids) == [0, 1, 2] and run.skipped.size == 0
        assert run.detections.shape == (3, 2, 2) and np.all(run.detections > 600)
        assert np.all(run.links > 0.9 * run.matches.min(axis=1))
        assert 100 < run.used.sum() < run.in_analysis.sum() + 1
    sf = st.structure
    assert sf.fitted.sum() >= 5 and np.all(sf.s2[sf.fitted] > 0)
    assert st.plateau is not None and 0.05 < st.plateau.epsilon < 0.4
    assert st.plateau.epsilon_paper_caption == pytest.approx(2.0**1.5 * st.plateau.epsilon)
    assert set(st.subsets) == {"3 largest dt", "smallest and largest dt"}
    assert st.u_prime is not None and 0.08 < st.u_prime.value < 0.3
    # One call per snapshot (5 Δt × 3) and one for the statistics.
    assert PROGRESS == [(i, 16) for i in range(1, 17)]


def test_matched_points_lie_on_the_true_particles(rendered, to_calibration_frame):
    folder, _, calibrations = rendered
    detector = ImageDetector(open_dataset(folder))
    cameras = [calibrations[c] for c in detector.cameras]
    settings, _ = resolve_matching(detector, cameras, PipelineSettings())
    visible_total = found = found_raw = matched = ghosts = 0
    errors = []
    for k in range(len(detector.dt)):
        truth, visible = _truth(folder, k)
        for f, frame in enumerate("ab"):
            points = match_frame(detector.detections(k, 0, frame), cameras, settings)
            true_raw = truth[0, f][visible[0, f]]
            true_cal = to_calibration_frame(true_raw)
            tree = cKDTree(points)
            found += np.sum(tree.query(true_cal)[0] < 1e-4)
            found_raw += np.sum(tree.query(true_raw)[0] < 1e-4)
            distance, nearest = cKDTree(to_calibration_frame(truth[0, f])).query(points)
            ghosts += np.sum(distance >= 1e-4)
            close = distance < 1e-4
            errors.append(points[close] - to_calibration_frame(truth[0, f])[nearest[close]])
            visible_total += len(true_raw)
            matched += len(points)
    errors = np.concatenate(errors)
    rms = np.sqrt(np.mean(errors**2, axis=0))
    assert found / visible_total >= 0.90  # measured 0.95
    assert found_raw / visible_total >= 0.75  # the calibration's 0.1° frame tilt: 0.83
    assert ghosts / matched < 0.03  # measured 0.005
    assert np.all(rms[:2] < 10e-6) and rms[2] < 20e-6  # measured 3.4, 2.7, 6.2 µm


def test_links_agree_with_the_true_displacements(rendered, result, to_calibration_frame):
    folder = rendered[0]
    start_errors, displacement_errors, wrong, used = [], [], 0, 0
    for run in result.runs:
        truth, _ = _truth(folder, run.k)
        for i, m in enumerate(run.snapshot_ids):
            rows = slice(run.offsets[i], run.offsets[i + 1])
            keep = run.used[rows]
            xa = run.positions[rows][keep]
            d = run.displacements[rows][keep]
            ta, tb = truth[m, 0], truth[m, 1]
            da, ia = cKDTree(to_calibration_frame(ta)).query(xa)
            db, ib = cKDTree(to_calibration_frame(tb)).query(xa + d)
            ok = (da < 1e-4) & (db < 1e-4) & (ia == ib)
            wrong += np.sum(~ok)
            used += len(xa)
            start_errors.append(xa[ok] - to_calibration_frame(ta[ia[ok]]))
            displacement_errors.append(d[ok] - (tb[ia[ok]] - ta[ia[ok]]))
    sigma = np.sqrt(np.mean(np.concatenate(start_errors) ** 2, axis=0))
    err = np.concatenate(displacement_errors)
    assert wrong / used < 0.01  # measured ~0.3 %
    # ΔX error of a correct link: b(t + Δt) − b(t), √2 σ per component for white noise.
    bound = 3.0 * np.sqrt(2.0) * sigma
    assert np.mean(np.all(np.abs(err) <= bound, axis=1)) >= 0.95
    assert np.all(np.sqrt(np.mean(err**2, axis=0)) <= 1.5 * np.sqrt(2.0) * sigma)


def test_mean_displacement_is_linear_in_dt_and_the_noise_term_is_small(result):
    md = result.statistics.mean_displacement
    assert md.mean.shape == (5, 3) and np.all(md.count > 100)
    # Zero-mean noise: the line αΔt + β0 passes through the origin.
    # (Three snapshots per Δt: errors scaled by the Birge ratio; Z came out at 2.6.)
    assert np.all(np.abs(md.fit.c2) < 3 * md.se_offset_scaled + 3e-6)
    sf = result.statistics.structure
    # Position noise is ~3 µm here: c2 = 4σ∥² ≈ 30 µm² is below the statistical error of
    # three snapshots (see test_statistics_remove_injected_noise for c2 > 0).
    assert np.median(sf.noise[sf.fitted]) > -3 * np.median(sf.se_noise[sf.fitted])


def _synthetic_runs(dt, *, sigma, snapshots=16, particles=500, rng=0):
    """Runs of a smooth random velocity field, positions measured with white noise."""
    rng = np.random.default_rng(rng)
    k = rng.normal(size=(12, 3)) * 150.0  # wavelengths ~ 2-6 cm
    amp = rng.normal(size=(12, 3)) * 0.06
    phase = rng.uniform(0, 2 * np.pi, 12)

    def velocity(x):
        return np.sin(x @ k.T + phase) @ amp

    lower, upper = (np.array(v) for v in ANALYSIS_VOLUME)
    runs, exact = [], []
    for kk, step in enumerate(dt):
        xs, ds = [], []
        for _ in range(snapshots):
            x = rng.uniform(lower, upper, size=(particles, 3))
            v = velocity(x)
            exact.append((x, v))
            noise_a = rng.normal(scale=sigma, size=x.shape)
            noise_b = rng.normal(scale=sigma, size=x.shape)
            xs.append(x + noise_a)
            ds.append(v * step + noise_b - noise_a)
        positions, displacements = np.concatenate(xs), np.concatenate(ds)
        inside = np.all((positions >= lower) & (positions <= upper), axis=1)
        runs.append(
            RunParticles(
                k=kk,
                dt=float(step),
                positions=positions,
                displacements=displacements,
                offsets=np.arange(snapshots + 1) * particles,
                snapshot_ids=np.arange(snapshots),
                detections=np.zeros((snapshots, 2, 2), dtype=np.int64),
                matches=np.zeros((snapshots, 2), dtype=np.int64),
                links=np.full(snapshots, particles),
                processed=np.arange(snapshots),
                in_analysis=inside,
                outlier=np.zeros(len(positions), dtype=bool),
            )
        )
    return runs, exact


def test_statistics_remove_injected_noise():
    dt = np.array([1e-4, 2e-4, 3e-4, 4e-4, 5e-4])
    sigma = 20e-6
    settings = StatisticsSettings(n_boot=60, r_min=2e-3, n_bins=10, plateau=(3e-3, 20e-3))
    runs, exact = _synthetic_runs(dt, sigma=sigma)
    st = compute_statistics(runs, settings)
    sf = st.structure
    fitted = sf.fitted
    assert fitted.sum() >= 8
    # White noise of σ per component: N = 4σ² in every bin, Δt-independent.
    assert np.all(sf.noise[fitted] > 0)
    assert np.median(sf.noise[fitted]) == pytest.approx(4 * sigma**2, rel=0.2)
    bins = settings.bins
    total = pair_sums(*exact[0], bins)
    for x, v in exact[1:]:
        total = total + pair_sums(x, v, bins)
    truth = total.mean[:, 0]
    ratio = sf.s2[fitted] / truth[fitted]
    assert np.all(np.abs(ratio - 1) < 4 * sf.se_s2[fitted] / truth[fitted] + 0.02)
    # The raw single-Δt estimate at the smallest Δt is biased up by N/Δt².
    assert np.all(sf.raw_s2[fitted, 0] > sf.s2[fitted])
    md = st.mean_displacement
    assert np.all(np.abs(md.fit.c2) < 4 * md.fit.se_c2 + 1e-6)
    assert st.u_prime is not None and np.isfinite(st.u_prime.value)
    assert np.allclose(st.position_noise, sigma, rtol=0.5)


def test_median_test_flags_a_planted_mislink():
    rng = np.random.default_rng(1)
    x = rng.uniform(-0.03, 0.03, size=(400, 3)) * [1, 1, 0.1]
    d = np.column_stack([np.sin(x[:, 0] * 100), np.cos(x[:, 1] * 80), 0 * x[:, 2]]) * 1e-4
    d += rng.normal(scale=3e-6, size=d.shape)
    assert not median_test_outliers(x, d, threshold=4.0, noise=30e-6).any()
    d[17] += [4e-4, -3e-4, 2e-4]
    flagged = median_test_outliers(x, d, threshold=4.0, noise=30e-6)
    assert np.flatnonzero(flagged).tolist() == [17]
    assert not median_test_outliers(x[:3], d[:3], threshold=4.0, noise=30e-6).any()


def _link_dataset(src, dst):
    """A copy of a dataset folder made of symbolic links (cheap), experiment.json copied."""
    dst.mkdir()
    (dst / "experiment.json").write_text((src / "experiment.json").read_text())
    for path in (src / "particles").rglob("*.tif"):
        target = dst / path.relative_to(src)
        target.parent.mkdir(parents=True, exist_ok=True)
        os.symlink(path, target)


def test_an_empty_frame_skips_its_snapshot(rendered, tmp_path, caplog):
    folder, _, calibrations = rendered
    copy = tmp_path / "ds"
    _link_dataset(folder, copy)
    for k in range(5):  # the shared first frame of snapshot 0, at every Δt
        frame = copy / "particles" / f"dt{k}" / "cam1" / "000000_a.tif"
        shape = tifffile.imread(frame).shape
        frame.unlink()
        tifffile.imwrite(frame, np.zeros(shape, dtype=np.uint16))
    with caplog.at_level(logging.WARNING, logger="ptv.pipeline.double_frame"):
        res = run_pipeline(
            ImageDetector(open_dataset(copy)), calibrations, PipelineSettings(snapshots=2)
        )
    assert "snapshot 0 skipped: no matched particle in frame a" in caplog.text
    assert res.runs[0].skipped.tolist() == [0] and res.runs[0].snapshot_ids.tolist() == [1]
    assert res.runs[0].detections[0, 0, 0] == 0
    assert res.statistics.errors == "pairs"  # one snapshot left at Δt_0: no bootstrap
    assert res.statistics.structure.fitted.any()


def _tiny_dataset(folder, *, dt=(1e-4, 2e-4), frames=1, size=(64, 64), image=(64, 64)):
    folder.mkdir()
    spec = {
        "cameras": {c: {"image_size": list(size)} for c in ("cam1", "cam2")},
        "dt": list(dt),
        "frames_per_dt": frames,
        "bit_depth": 12,
        "particle_images": "particles/dt{k}/{camera}/{m:06d}_{a|b}.tif",
    }
    (folder / "experiment.json").write_text(json.dumps(spec))
    for k in range(len(dt)):
        for c in ("cam1", "cam2"):
            for m in range(frames):
                for f in "ab":
                    path = folder / "particles" / f"dt{k}" / c / f"{m:06d}_{f}.tif"
                    path.parent.mkdir(parents=True, exist_ok=True)
                    tifffile.imwrite(path, np.full(image[::-1], 100, dtype=np.uint16))
    return folder


def test_all_frames_empty_is_a_clear_error(rendered, tmp_path, caplog):
    calibrations = rendered[2]
    dataset = open_dataset(_tiny_dataset(tmp_path / "empty"))
    with pytest.raises(ValueError, match=r"no particle matched .* detections per camera \[0, 0\]"):
        run_pipeline(ImageDetector(dataset), calibrations)  # the tolerance cannot be measured
    with pytest.raises(ValueError, match=r"no snapshot at Δt_0 .* has matched particles"):
        run_pipeline(ImageDetector(dataset), calibrations, PipelineSettings(tolerance=1.5e-4))
    given = PipelineSettings(max_speed=1.5, tolerance=1.5e-4)
    with pytest.raises(ValueError, match="multi-Δt method needs at least two"):
        run_pipeline(ImageDetector(dataset), calibrations, given)
    assert caplog.text.count("no matched particle") == 2


def test_bad_datasets_are_refused(tmp_path):
    with pytest.raises(DatasetError, match="the multi-Δt method needs at least two Δt values"):
        open_dataset(_tiny_dataset(tmp_path / "single", dt=(1e-4,)))
    with pytest.raises(FileNotFoundError, match="does not exist"):
        open_dataset(tmp_path / "nowhere")
    folder = _tiny_dataset(tmp_path / "missing", frames=1)
    spec = json.loads((folder / "experiment.json").read_text())
    spec["frames_per_dt"] = 2
    (folder / "experiment.json").write_text(json.dumps(spec))
    with pytest.raises(FileNotFoundError, match=r"000001_a\.tif is missing"):
        open_dataset(folder)
    small = open_dataset(_tiny_dataset(tmp_path / "small", image=(32, 48)))
    with pytest.raises(DatasetError, match=r"wrong size: 32 × 48 px.*64 × 64 px"):
        small.read_frame(0, "cam1", 0, "a")
    escaping = _tiny_dataset(tmp_path / "escaping")
    spec = json.loads((escaping / "experiment.json").read_text())
    spec["cameras"]["../../cam1"] = spec["cameras"].pop("cam1")
    (escaping / "experiment.json").write_text(json.dumps(spec))
    with pytest.raises(DatasetError, match=r"camera name: expected 1 to 64 .*'\.\./\.\./cam1'"):
        open_dataset(escaping)
    nan = open_dataset(_tiny_dataset(tmp_path / "nan"))
    path = nan.frame_path(0, "cam2", 0, "b")
    frame = np.full((64, 64), 100.0, dtype=np.float32)
    frame[3, :5] = np.nan
    tifffile.imwrite(path, frame)
    with pytest.raises(DatasetError, match=rf"{path}: 5 pixels are NaN or infinite"):
        nan.read_frame(0, "cam2", 0, "b")


def test_cameras_must_match_the_calibration(rendered):
    folder, _, calibrations = rendered
    dataset = ImageDetector(open_dataset(folder))
    renamed = {"cam1": calibrations["cam1"], "camX": calibrations["cam2"]}
    with pytest.raises(DatasetError, match=r"cameras don't match the calibration.*cam2.*camX"):
        run_pipeline(dataset, renamed)
    extra = {**calibrations, "cam3": calibrations["cam1"]}
    with pytest.raises(DatasetError, match=r"cameras don't match the calibration.*cam3"):
        run_pipeline(dataset, extra)


def test_settings_are_checked():
    with pytest.raises(ValueError, match="max_speed"):
        PipelineSettings(max_speed=0.0)
    with pytest.raises(ValueError, match="analysis_volume"):
        StatisticsSettings(analysis_volume=((0, 0, 0), (0, 1, 1)))
    with pytest.raises(ValueError, match="snapshots"):
        PipelineSettings(snapshots=0)


def test_results_are_written_with_units(result, tmp_path):
    h5_path, json_path = save_results(result, tmp_path / "out", calibration="cal.h5")
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["results.h5", "summary.json"]
    with h5py.File(h5_path) as f:
        assert f.attrs["format"] == "synptv-ptv-results"
        run = f["particles/dt3"]
        assert run["positions"].attrs["units"] == "m"
        n = run["positions"].shape[0]
        assert run["offsets"][-1] == n == run["displacements"].shape[0]
        assert run["in_analysis"].shape == run["outlier"].shape == (n,)
        s = f["statistics"]
        assert s["s2"].attrs["units"] == "m^2/s^2" and s["noise"].attrs["units"] == "m^2"
        assert s["raw_s2"].shape == (24, 5) and s["r_edges"].shape == (25,)
        assert s["plateau"].attrs["epsilon"] == pytest.approx(result.statistics.plateau.epsilon)
        assert "subsets/3 largest dt/epsilon" in s
    summary = json.loads(json_path.read_text())
    assert summary["calibration"] == "cal.h5"
    assert summary["epsilon"]["plateau"]["epsilon"] == pytest.approx(
        result.statistics.plateau.epsilon
    )
    assert len(summary["counts"]) == 5 and summary["counts"][0]["links"] > 1000
    assert set(summary["subsets"]) == {"3 largest dt", "smallest and largest dt"}
    # Δt written and read back bit for bit (docs/claims.md #48 covers the dataset's files).
    assert summary["dt"] == [float(v) for v in result.source.dt]
    assert [r.dt for r in load_runs(h5_path)] == [float(v) for v in result.source.dt]


def _run_from_snapshots(k, dt, rows, processed):
    """A RunParticles from {snapshot: (positions, displacements, used)}, rows as given."""
    ids = sorted(rows)
    sizes = [len(rows[m][0]) for m in ids]
    used = np.concatenate([rows[m][2] for m in ids])
    return RunParticles(
        k=k,
        dt=dt,
        positions=np.concatenate([rows[m][0] for m in ids]),
        displacements=np.concatenate([rows[m][1] for m in ids]),
        offsets=np.concatenate([[0], np.cumsum(sizes)]),
        snapshot_ids=np.array(ids),
        detections=np.zeros((len(processed), 2, 2), dtype=np.int64),
        matches=np.zeros((len(processed), 2), dtype=np.int64),
        links=np.array([len(rows[m][0]) if m in rows else 0 for m in processed]),
        processed=np.array(processed),
        in_analysis=used,
        outlier=np.zeros(len(used), dtype=bool),
    )


def test_shared_snapshots_join_the_particles_used_at_every_dt():
    rng = np.random.default_rng(31)
    dt, snapshots, particles = np.array([1e-4, 2e-4, 3e-4]), 4, 8
    x = rng.uniform(-0.03, 0.03, size=(snapshots, particles, 3))
    v = rng.normal(size=(snapshots, particles, 3)) * 0.2
    # Per run: particles missing (no link), particles not used, a missing snapshot, and a
    # frame-a position one ulp off (no longer the same measured X(t)).
    missing = {(1, 0): [2], (1, 2): [5], (0, 3): [6]}
    unused = {(0, 0): [7], (2, 2): [3]}
    moved = {(1, 3): [0]}
    skipped = {(2, 1)}
    runs = []
    for k, step in enumerate(dt):
        rows = {}
        for m in range(snapshots):
            if (k, m) in skipped:
                continue
            keep = rng.permutation(np.setdiff1d(np.arange(particles), missing.get((k, m), [])))
            positions = x[m, keep].copy()
            for p in moved.get((k, m), []):
                row = np.flatnonzero(keep == p)[0]
                positions[row, 0] = np.nextafter(positions[row, 0], np.inf)
            used = ~np.isin(keep, unused.get((k, m), []))
            rows[m] = (positions, v[m, keep] * step, used)
        runs.append(_run_from_snapshots(k, float(step), rows, list(range(snapshots))))

    snapshot_ids, joined = shared_snapshots(runs)

    expected = {0: {0, 1, 3, 4, 5, 6}, 2: {0, 1, 2, 4, 6, 7}, 3: {1, 2, 3, 4, 5, 7}}
    assert snapshot_ids.tolist() == list(expected)
    for (positions, displacements), (m, ids) in zip(joined, expected.items(), strict=True):
        assert positions.shape == (len(ids), 3)
        assert displacements.shape == (len(ids), len(dt), 3)
        particle_ids = [int(np.flatnonzero(np.all(x[m] == row, axis=1))[0]) for row in positions]
        assert set(particle_ids) == ids and len(particle_ids) == len(ids)
        for k, step in enumerate(dt):
            assert np.array_equal(displacements[:, k], v[m, particle_ids] * step)


def test_shared_snapshots_of_runs_with_no_common_particle_are_empty():
    dt = [1e-4, 2e-4, 3e-4, 4e-4]
    runs = [
        _run_from_snapshots(
            k,
            step,
            {0: (np.full((1, 3), float(k)), np.full((1, 3), step), np.ones(1, dtype=bool))},
            [0],
        )
        for k, step in enumerate(dt)
    ]
    snapshot_ids, ((positions, displacements),) = shared_snapshots(runs)
    assert snapshot_ids.tolist() == [0]
    assert positions.shape == (0, 3) and displacements.shape == (0, len(dt), 3)


def test_a_shared_first_frame_is_measured_once_with_the_same_result(rendered):
    folder, _, calibrations = rendered
    detector = ImageDetector(open_dataset(folder))
    assert detector.shared_first_frame
    cameras = [calibrations[name] for name in detector.cameras]
    settings, _ = resolve_matching(detector, cameras, PipelineSettings(max_speed=1.5))
    shared = measure_snapshots(detector, range(3), cameras, settings)
    for m in range(3):
        fresh = measure_snapshot(ImageDetector(open_dataset(folder)), 2, m, cameras, settings)
        cached = shared[2][m]
        for name in ("positions", "displacements", "detections", "matches", "outlier"):
            assert np.array_equal(getattr(cached, name), getattr(fresh, name)), name


def test_a_wrongly_declared_shared_first_frame_is_an_error_naming_the_file(rendered, tmp_path):
    folder, _, calibrations = rendered
    copy = tmp_path / "ds"
    shutil.copytree(folder, copy)
    frame = copy / "particles" / "dt3" / "cam1" / "000001_a.tif"
    other = tifffile.imread(copy / "particles" / "dt3" / "cam1" / "000001_b.tif")
    frame.unlink()  # a hard link: replace the file, not the shared content
    tifffile.imwrite(frame, other)
    with pytest.raises(DatasetError, match=r"000001_a\.tif.*shared first frame"):
        run_pipeline(ImageDetector(open_dataset(copy)), calibrations)


def _joined_experiment(rng, dt, *, offset=0.0, snapshots=30, particles=200, sigma=5e-6):
    """Particles followed over every Δt from a shared frame a: each snapshot has its own
    mean velocity and acceleration, each frame its own white noise (frame a's is shared
    by every Δt), and frame b may be offset by a constant, m."""
    joined = []
    for _ in range(snapshots):
        x = rng.uniform(-0.03, 0.03, (particles, 3))
        v = rng.normal(size=3) * 0.05 + rng.normal(size=(particles, 3)) * 0.2
        a = rng.normal(size=3) * 2.0 + rng.normal(size=(particles, 3)) * 20.0
        b_a = rng.normal(size=(particles, 1, 3)) * sigma
        b_b = rng.normal(size=(particles, len(dt), 3)) * sigma + offset
        t = dt[None, :, None]
        joined.append((x, v[:, None] * t + 0.5 * a[:, None] * t**2 + b_b - b_a))
    return joined


def test_the_mean_displacement_offset_of_shared_frames_has_calibrated_errors():
    """The K means share frame a, so their errors are correlated: β0 must scatter over
    independent experiments as its error says (pulls of unit spread; Student's factor
    √((M − 1)/(M − 3)) ≈ 1.04 at M = 30), the joint test must raise 1 % false alarms
    (at most 9 of 300 is a 4σ binomial bound), and a 1 µm offset of frame b, ten times
    its error, must stand out."""
    rng = np.random.default_rng(5)
    dt = np.array([1e-4, 2e-4, 3e-4, 4e-4, 5e-4])
    pulls, alarms = [], 0
    for _ in range(300):
        md = shared_mean_displacement(_joined_experiment(rng, dt, particles=100), dt)
        pulls.append(md.fit.c2 / md.fit.se_c2)
        statistic, limit = md.offset_test()
        alarms += statistic > limit
    assert 0.9 < np.std(pulls) < 1.2
    assert alarms <= 9
    md = shared_mean_displacement(_joined_experiment(rng, dt, offset=1e-6), dt)
    statistic, limit = md.offset_test()
    assert statistic > 10 * limit
    assert np.allclose(md.fit.c2, 1e-6, rtol=0.3)


@pytest.mark.parametrize(
    ("k", "snapshots", "defined"), [(2, 3, False), (2, 4, True), (5, 5, False)]
)
def test_shared_mean_displacement_needs_more_snapshots_than_its_test_has_parameters(
    k, snapshots, defined
):
    """Hotelling's T² of β0 needs M > 3 (its F has M − 3 degrees of freedom) and Σ needs
    M > K: below either, the line falls back to the per-Δt means (None here)."""
    dt = np.arange(1, k + 1) * 1e-4
    joined = _joined_experiment(np.random.default_rng(1), dt, snapshots=snapshots)
    md = shared_mean_displacement(joined, dt)
    assert (md is not None) == defined
    if defined:
        assert np.isfinite(md.offset_test()).all()
