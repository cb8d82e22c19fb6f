"""``synptv export --format openlpt``: OpenLPT 2.2.4's camera files, image lists,
configurations and tracer settings, field by field as OpenLPT reads them; the camera
files projected by an independent re-implementation of OpenLPT's models against the
truth's image positions; bad input refused in one line. Where OpenLPT's own environment
is at hand (``$OPENLPT_VENV`` or ``../peers/openlpt-venv``), OpenLPT reads the export,
projects as the re-implementation does and reconstructs an exported frame."""

import csv
import json
import math
import os
import re
import shutil
import subprocess
from pathlib import Path
from types import SimpleNamespace

import cv2
import h5py
import numpy as np
import pytest
import tifffile

from validation.cli import main

#: OpenLPT's environment, when this machine has one (never a synptv dependency).
OPENLPT_PYTHON = next(
    (
        p
        for p in (
            Path(os.environ.get("OPENLPT_VENV", "/nonexistent")) / "bin/python",
            Path(__file__).resolve().parents[3] / "peers/openlpt-venv/bin/python",
        )
        if p.is_file()
    ),
    None,
)
needs_openlpt = pytest.mark.skipif(OPENLPT_PYTHON is None, reason="no OpenLPT environment")
RIG = Path(__file__).resolve().parents[2] / "simulator/rig_presets/lpt-challenge-small.toml"


def render(folder: Path, rig: str, particles: int = 200) -> Path:
    argv = ["render", "--rig", rig, "--out", str(folder), "--frames", "2", "--planes", "3"]
    assert main([*argv, "--particles", str(particles), "--workers", "1", "--quiet"]) == 0
    return folder


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    """lpt-challenge-small (four Scheimpflug cameras behind a glass wall), 2 frame pairs
    per Δt, 3 plate positions, 200 particles."""
    return render(tmp_path_factory.mktemp("openlpt") / "dataset", "lpt-challenge-small")


@pytest.fixture(scope="module")
def export(dataset):
    out = dataset.parent / "openlpt"
    argv = ["export", "--dataset", str(dataset), "--format", "openlpt", "--out", str(out)]
    assert main(argv) == 0
    return out


def values(text: str) -> list[str]:
    """The values of an OpenLPT text file, one a line, as its readers see them: blank and
    '#' lines skipped, text after '#' dropped, spaces trimmed."""
    lines = (line.split("#")[0].strip() for line in text.splitlines())
    return [line for line in lines if line]


def numbers(token: str) -> np.ndarray:
    return np.array([float(x) for x in token.split(",")])


def experiment(dataset: Path) -> dict:
    return json.loads((dataset / "experiment.json").read_text())


def truth_particles(dataset: Path, camera: str):
    """Both frames of every snapshot of Δt_0 from truth.h5, read here: positions (N, 3)
    m and their true image positions on ``camera`` (N, 2) px, the visible ones."""
    with h5py.File(dataset / "truth.h5", "r") as f:
        g = f["particles/dt0"]
        x = np.concatenate([g["positions_a"][:], g["positions_b"][:]]).reshape(-1, 3)
        xy = np.concatenate([g[f"{camera}/xy_a"][:], g[f"{camera}/xy_b"][:]]).reshape(-1, 2)
        seen = np.concatenate([g[f"{camera}/visible_a"][:], g[f"{camera}/visible_b"][:]])
    return x[seen.ravel()], xy[seen.ravel()]


def openlpt_pinhole(text: str, x_mm: np.ndarray) -> np.ndarray:
    """OpenLPT's PINHOLE projection, re-implemented from its documented model: X_c = R X
    + t, (u, v) = (f_x X_c/Z_c + c_x, f_y Y_c/Z_c + c_y), no distortion when no
    coefficient exceeds 1e-8."""
    v = values(text)
    assert v[0] == "PINHOLE" and not (numbers(v[7]) > 1e-8).any()
    k = np.array([numbers(v[i]) for i in (4, 5, 6)])
    r = np.array([numbers(v[i]) for i in (9, 10, 11)])
    c = r @ x_mm.T + numbers(v[15])[:, None]
    return np.column_stack([k[0, 0] * c[0] / c[2] + k[0, 2], k[1, 1] * c[1] / c[2] + k[1, 2]])


def openlpt_polynomial(text: str, x_mm: np.ndarray) -> np.ndarray:
    """OpenLPT's POLYNOMIAL: u = Σ a_i X^p Y^q Z^r, v likewise."""
    v = values(text)
    n = int(v[4])
    u = np.array([numbers(row) for row in v[5 : 5 + n]])
    w = np.array([numbers(row) for row in v[5 + n : 5 + 2 * n]])
    assert len(v) == 5 + 2 * n and (u[:, 1:] == w[:, 1:]).all()
    terms = np.prod(x_mm[:, None, :] ** u[None, :, 1:], axis=2)
    return np.column_stack([terms @ u[:, 0], terms @ w[:, 0]])


def stated(readme: str, folder: str, camera: str) -> tuple[float, float]:
    """The rms and max error the README states for a camera of a folder."""
    block = readme.split(f"\n {folder}/:")[1]
    found = re.search(rf"{camera}\s+\w+\s+error rms ([\d.e-]+) px, max ([\d.e-]+) px", block)
    return float(found.group(1)), float(found.group(2))


# -- the files written -------------------------------------------------------------------


def test_the_files_written(export, dataset):
    spec = experiment(dataset)
    cams, n_dt = list(spec["cameras"]), len(spec["dt"])
    expected = {"README.txt", "config.txt", "frames.csv", "run_ipr.py"}
    expected |= {f"{d}/{c}.txt" for c in cams for d in ("camFile", "camFileTrue")}
    for k in range(n_dt):
        expected |= {f"config_dt{k}.txt", f"config_true_dt{k}.txt", f"tracerConfig_dt{k}.txt"}
        expected |= {f"imgFile/dt{k}/{c}ImageNames.txt" for c in cams}
        expected |= {
            f"imgFile/dt{k}/{c}/{m:06d}_{f}.tif"
            for c in cams
            for m in range(spec["frames_per_dt"])
            for f in "ab"
        }
    written = {str(p.relative_to(export)) for p in export.rglob("*") if p.is_file()}
    assert written == expected
    assert (export / "config.txt").read_text() == (export / "config_dt0.txt").read_text()


def test_config_fields_as_openlpt_reads_them(export, dataset):
    spec = experiment(dataset)
    cams = list(spec["cameras"])
    for k, dt in enumerate(spec["dt"]):
        for config, folder, results in (
            ("config", "camFile", "Results/dt"),
            ("config_true", "camFileTrue", "Results/true_dt"),
        ):
            v = values((export / f"{config}_dt{k}.txt").read_text())
            assert v[0] == f"0,{2 * spec['frames_per_dt'] - 1}"
            assert int(v[1]) == round(1 / dt)  # an integer, Hz
            assert v[2] == "0" and int(v[3]) == len(cams)
            for c, name in enumerate(cams):
                path, top = v[4 + c].split(",")
                assert path == f"{folder}/{name}.txt" and (export / path).is_file()
                assert int(top) == 2 ** spec["bit_depth"] - 1
                assert v[4 + len(cams) + c] == f"imgFile/dt{k}/{name}ImageNames.txt"
            rest = v[4 + 2 * len(cams) :]
            box = numbers(rest[0]).reshape(3, 2)  # xmin,xmax,ymin,ymax,zmin,zmax (mm)
            half = np.array([20, 25, 30]) / 2  # the rig's lit volume, mm
            voxel = float(rest[1])
            assert 0.055 < voxel < 0.065  # the rig's 60 µm voxel
            assert box[:, 1] == pytest.approx(half + 2 * voxel, abs=1e-5)
            assert box[:, 0] == pytest.approx(-half - 2 * voxel, abs=1e-5)
            assert rest[2:] == [f"{results}{k}/", "Tracer", f"tracerConfig_dt{k}.txt", "0,-1"]


def test_tracer_config_fields(export, dataset):
    spec = experiment(dataset)
    for k in range(len(spec["dt"])):
        v = values((export / f"tracerConfig_dt{k}.txt").read_text())
        assert len(v) == 17
        assert all(re.fullmatch(r"\d+", v[i]) for i in (1, 4, 5, 6, 8, 9, 13, 14, 15)), v
        assert float(v[0]) >= 2  # the link radius, voxel
        assert [float(x) for x in v[8:15]] == [4, 4, 0.1, 0.8, 1.0, 1, 2]  # GUI defaults
        assert float(v[16]) == 2
    # the 2-D peak threshold: between the noise and the particle images' peaks
    image = tifffile.imread(export / "imgFile/dt0/cam1/000000_a.tif").astype(float)
    peaks = image[(image == cv2.dilate(image, np.ones((3, 3)))) & (image > 100)]
    assert 6 * 3 < int(v[15]) < np.median(peaks)


def test_image_lists_and_images(export, dataset):
    spec = experiment(dataset)
    with open(export / "frames.csv") as stream:
        frames = list(csv.DictReader(stream))
    assert len(frames) == len(spec["dt"]) * spec["frames_per_dt"] * 2
    for k in range(len(spec["dt"])):
        for name in spec["cameras"]:
            lines = (export / f"imgFile/dt{k}/{name}ImageNames.txt").read_text().splitlines()
            count = 2 * spec["frames_per_dt"]
            assert len(lines) == max(count, 5)  # OpenLPT's OTF reads five frames
            assert lines[count:] == lines[: len(lines) - count]  # padded by repetition
            offsets = set()
            for row in (r for r in frames if int(r["dt"]) == k):
                m, f, i = int(row["snapshot"]), row["frame"], int(row["frame_index"])
                assert i == 2 * m + (f == "b")
                assert lines[i] == f"imgFile/dt{k}/{name}/{m:06d}_{f}.tif"
                with tifffile.TiffFile(export / lines[i]) as tif:
                    assert tif.pages[0].compression == 1  # uncompressed: OpenLPT's libtiff
                    written = tif.asarray().astype(int)
                rendered = tifffile.imread(
                    dataset / "particles" / f"dt{k}" / name / f"{m:06d}_{f}.tif"
                ).astype(int)
                bright = written > 0
                offsets |= set(np.unique(rendered[bright] - written[bright]).tolist())
                assert (rendered[~bright] <= min(offsets)).all()  # clipped at 0
            assert len(offsets) == 1 and 5 <= offsets.pop() <= 15  # the sensor's offset


def test_plate_pinholes_project_the_truth_as_the_readme_states(export, dataset):
    """Each camFile/ PINHOLE, projected by the re-implementation above and by OpenCV,
    lands the truth's particles where the README says. Tolerance: rms below 0.5 px, so
    that the model's error stays inside OpenLPT's 0.8 px matching strip (measured on
    this 3-plane dataset: 0.06–0.20 px rms, 0.13–0.59 px at most: the pinhole has no
    refraction and no tilted sensor)."""
    readme = (export / "README.txt").read_text()
    for name in experiment(dataset)["cameras"]:
        text = (export / f"camFile/{name}.txt").read_text()
        v = values(text)
        assert v[0] == "PINHOLE" and [int(x) for x in v[3].split(",")] == [512, 512]
        r = np.array([numbers(v[i]) for i in (9, 10, 11)])
        r_inv = np.array([numbers(v[i]) for i in (12, 13, 14)])
        t, centre = numbers(v[15]), numbers(v[16])
        assert r @ r.T == pytest.approx(np.eye(3), abs=1e-12) and np.linalg.det(r) > 0
        assert r_inv == pytest.approx(r.T, abs=1e-15)
        assert centre == pytest.approx(-r.T @ t, abs=1e-9)
        assert np.linalg.norm(centre) == pytest.approx(717 + 200, rel=0.1)  # ~0.9 m off
        x, xy = truth_particles(dataset, name)
        mine = openlpt_pinhole(text, x * 1e3)
        k = np.array([numbers(v[i]) for i in (4, 5, 6)])
        opencv = cv2.projectPoints(x * 1e3, cv2.Rodrigues(r)[0], t, k, np.zeros(5))[0]
        assert np.abs(mine - opencv.reshape(-1, 2)).max() < 1e-8
        d = np.linalg.norm(mine - xy, axis=1)
        rms, worst = stated(readme, "camFile", name)
        assert np.sqrt(np.mean(d**2)) == pytest.approx(rms, rel=0.005)
        assert d.max() == pytest.approx(worst, rel=0.005)
        assert rms < 0.5


def test_true_polynomials_project_the_truth_within_the_target(export, dataset, tmp_path):
    """Each camFileTrue/ POLYNOMIAL lands the truth's particles within 0.01 px (the
    export's target) of their true image positions, as the README states."""
    readme = (export / "README.txt").read_text()
    for name in experiment(dataset)["cameras"]:
        text = (export / f"camFileTrue/{name}.txt").read_text()
        v = values(text)
        assert v[0] == "POLYNOMIAL" and v[3].startswith("REF_Z,")  # cameras look along Z
        assert numbers(v[3].split(",", 1)[1]) == pytest.approx([-15.12, 15.12], abs=0.01)
        x, xy = truth_particles(dataset, name)
        d = np.linalg.norm(openlpt_polynomial(text, x * 1e3) - xy, axis=1)
        rms, worst = stated(readme, "camFileTrue", name)
        assert np.sqrt(np.mean(d**2)) == pytest.approx(rms, rel=0.005)
        assert d.max() == pytest.approx(worst, rel=0.005) and worst < 0.01


def test_the_polynomial_order_grows_until_the_target_is_met():
    """The full lpt-challenge rig (a 100 mm wide volume): a cubic misses 0.01 px, so a
    higher order is written."""
    from simulator.rigs import load_rig
    from validation.export.openlpt_cameras import (
        TrueImages,
        fit_polynomial,
        project_file,
        true_camera_files,
        view_volume,
    )

    rig = load_rig("lpt-challenge")
    volume = view_volume(rig)
    camera = rig.cameras[0]
    x = np.random.default_rng(3).uniform(volume.lower, volume.upper, (2000, 3))
    exact = camera.project(x)
    cubic = project_file(fit_polynomial(camera, volume, 3), x * 1e3)
    assert np.nanmax(np.linalg.norm(cubic - exact, axis=1)) > 0.01
    one = SimpleNamespace(cameras=(camera,), camera_names=("cam1",))
    (best,) = true_camera_files(one, volume, TrueImages(x, [exact]))
    assert "order 3" not in best.detail and best.max_px < 0.01


def test_the_readme_states_models_errors_and_guesses(export):
    readme = (export / "README.txt").read_text()
    for needle in (
        "camFile/: what OpenLPT's plate calibration gives",
        "camFileTrue/: the true cameras",
        "Background subtracted",
        "Voxel to mm",
        "2-D peak threshold",
        "run_ipr.py config_dt0.txt",
        "divide\nby 1000",
    ):
        assert needle in readme, needle


# -- OpenLPT itself, where its environment exists ----------------------------------------


def run_openlpt(folder: Path, *args: str) -> None:
    done = subprocess.run(
        [str(OPENLPT_PYTHON), "run_ipr.py", *args],
        cwd=folder,
        env=dict(os.environ, OMP_NUM_THREADS="1"),
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]


@needs_openlpt
@pytest.mark.parametrize("config", ["config_dt0.txt", "config_true_dt0.txt"])
def test_openlpt_projects_the_camera_files_as_reimplemented(export, dataset, config, tmp_path):
    x, _ = truth_particles(dataset, "cam1")
    np.savetxt(tmp_path / "p.csv", x * 1e3, delimiter=",", header="x_mm,y_mm,z_mm", comments="")
    out = tmp_path / "xy.csv"
    run_openlpt(export, config, "--project", str(tmp_path / "p.csv"), "--out", str(out))
    xy = np.loadtxt(out, delimiter=",", skiprows=1)
    listed = values((export / config).read_text())
    for c in range(len(experiment(dataset)["cameras"])):
        text = (export / listed[4 + c].split(",")[0]).read_text()
        model = openlpt_pinhole if values(text)[0] == "PINHOLE" else openlpt_polynomial
        mine = model(text, x * 1e3)
        assert np.abs(xy[xy[:, 0] == c][:, 1:] - mine).max() < 1e-6


@needs_openlpt
@pytest.mark.slow
@pytest.mark.parametrize(
    ("config", "least"), [("config_true_dt0.txt", 0.9), ("config_dt0.txt", 0.8)]
)
def test_openlpt_reconstructs_the_exported_frame(export, dataset, config, least):
    """OpenLPT's IPR on frame a of dt0 through the run_ipr.py the export ships: the
    positions file synptv score reads, most particles within a voxel (true cameras: 90 %;
    the plate pinholes, 0.1–0.3 px off: 80 %)."""
    from validation.truth.truth_file import TruthFile

    positions = f"Results/{config}.csv"
    run_openlpt(export, config, "--frames", "0", "0", "--positions", positions, "--dt", "0")
    with open(export / positions) as stream:
        rows = list(csv.DictReader(stream))
    assert {(r["dt"], r["snapshot"], r["frame"]) for r in rows} == {("0", "0", "a")}
    found = np.array([[float(r[k]) for k in "xyz"] for r in rows])
    truth = TruthFile(dataset).runs(0, 1)[0]
    seen = sum(truth.visible[c][0, 0].astype(int) for c in experiment(dataset)["cameras"]) >= 3
    true = truth.positions[0, 0][seen]
    voxel = 60e-6
    near = np.abs(found[:, None, :] - true[None, :, :]).max(axis=2) <= voxel
    assert near.any(axis=0).mean() > least  # found
    assert near.any(axis=1).mean() > least  # not ghosts


# -- bad input -----------------------------------------------------------------------------


def refused(capsys, tmp_path: Path, dataset: Path, layout: str = "openlpt", out="o") -> str:
    before = set(tmp_path.iterdir())
    argv = ["export", "--dataset", str(dataset), "--format", layout, "--out", str(tmp_path / out)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1, err
    assert set(tmp_path.iterdir()) == before  # nothing written, no partial folder
    return err


def test_a_dataset_without_particle_images_is_refused(capsys, tmp_path, dataset):
    copy_ = tmp_path / "copy"
    shutil.copytree(dataset, copy_)
    spec = experiment(copy_)
    spec["particle_images"] = None
    (copy_ / "experiment.json").write_text(json.dumps(spec))
    err = refused(capsys, tmp_path, copy_)
    assert "experiment.json" in err and "particle_images" in err and "--keep-images" in err


def test_a_missing_particle_image_is_named(capsys, tmp_path, dataset):
    copy_ = tmp_path / "copy"
    shutil.copytree(dataset, copy_)
    (copy_ / "particles/dt1/cam3/000001_b.tif").unlink()
    assert "000001_b.tif" in refused(capsys, tmp_path, copy_)


def test_one_camera_is_refused(capsys, tmp_path):
    text = RIG.read_text()
    one = text[: text.index("[[cameras]]", text.index("[[cameras]]") + 1)]
    (tmp_path / "one.toml").write_text(one)
    dataset = render(tmp_path / "one", str(tmp_path / "one.toml"), particles=20)
    err = refused(capsys, tmp_path, dataset)
    assert "experiment.json" in err and "cameras" in err and "at least two cameras" in err


def test_an_unknown_format_and_an_existing_folder_are_refused(capsys, tmp_path, dataset):
    assert "--format" in refused(capsys, tmp_path, dataset, layout="openlpt2")
    (tmp_path / "taken").mkdir()
    assert "taken" in refused(capsys, tmp_path, dataset, out="taken")
    assert not any((tmp_path / "taken").iterdir())


def test_the_threshold_rule():
    """2-D peak threshold: the larger of 0.3 × the faintest camera's typical peak and six
    background σ of the noisiest."""
    from validation.export.openlpt import ImageLevels, peak_threshold

    assert peak_threshold([ImageLevels(10, 2, 1000), ImageLevels(10, 3, 600)]) == 180
    assert peak_threshold([ImageLevels(10, 40, 300)]) == math.ceil(6 * 40)
