"""docs/benchmark-your-code.md: its ``synptv`` commands of frame pairs (§1 OpenPTV, §2
MyPTV) run as the page writes them, on a small rendering, with the code's output
generated from the truth (what a perfect code would write: every particle two cameras
image, in the code's layout, mm to three decimals, linked from frame a to frame b);
converted and scored, it scores yield 1, no ghost, micrometre errors and every link
correct."""

import csv
import json
import re
import shlex
from importlib import resources
from pathlib import Path

import numpy as np
import pytest

from validation.cli import main
from validation.truth.truth_file import TruthFile

PAGE = Path(__file__).resolve().parents[2] / "docs" / "benchmark-your-code.md"
#: The page's render sizes, and the test's: the paper-stereo rig with 16 times fewer
#: pixels (as tests/validation/test_export.py renders it), 2 frame pairs, 60 tracers.
PAGE_SIZES = "--frames 10 --particles 1000"
TEST_SIZES = "--frames 2 --particles 60 --planes 3 --workers 1 --quiet --rig {rig}"
SMALL_SENSOR = {
    "sensor_size = [2048, 1088]": "sensor_size = [512, 272]",
    "pixel_pitch = 5.5e-6": "pixel_pitch = 22e-6",
}
MM = 1e3


def page_commands(sections: tuple[str, ...] = ("1. ", "2. ")) -> list[str]:
    """The ``synptv`` lines of the ``sh`` blocks of the page's sections ``sections``."""
    commands = []
    for part in re.split(r"^## ", PAGE.read_text(), flags=re.MULTILINE):
        if part.startswith(sections):
            for block in re.findall(r"```sh\n(.*?)```", part, flags=re.DOTALL):
                commands += [line for line in block.splitlines() if line.startswith("synptv ")]
    return commands


def small_rig(folder: Path) -> Path:
    text = (resources.files("simulator") / "rig_presets" / "paper-stereo.toml").read_text()
    for old, new in SMALL_SENSOR.items():
        assert old in text
        text = text.replace(old, new)
    path = folder / "rig.toml"
    path.write_text(text)
    return path


def _frames(export: Path) -> list[dict]:
    with (export / "frames.csv").open() as f:
        return list(csv.DictReader(f))


def _imaged(run, m: int) -> tuple[np.ndarray, np.ndarray]:
    """Particles that two cameras image in frames a and b of snapshot m (the score's
    reference)."""
    seen = np.sum([v[m] for v in run.visible.values()], axis=0) >= 2
    return np.flatnonzero(seen[0]), np.flatnonzero(seen[1])


def perfect_openptv(dataset: Path, export: Path) -> None:
    """``res_dt<k>/rt_is.<number>`` and ``ptv_is.<number>`` as liboptv writes them, of
    every imaged particle, numbered by the export's frames.csv."""
    runs = TruthFile(dataset).runs()
    rows = {
        (int(r["dt"]), int(r["snapshot"]), r["frame"]): int(r["number"]) for r in _frames(export)
    }
    for k, m, frame in rows:
        if frame == "b":
            continue
        run = runs[k]
        in_a, in_b = _imaged(run, m)
        for f, members, other in (("a", in_a, in_b), ("b", in_b, in_a)):
            xyz = run.positions[m, "ab".index(f)][members] * MM
            link = [int(np.searchsorted(other, p)) if p in other else None for p in members]
            nxt = [-2 if (f == "b" or i is None) else i for i in link]
            prev = [-1 if (f == "a" or i is None) else i for i in link]
            res = export / f"res_dt{k}"
            res.mkdir(exist_ok=True)
            n = rows[k, m, f]
            rt = [
                f"{i + 1:4d} {x:9.3f} {y:9.3f} {z:9.3f} {i:4d} {i:4d} {-1:4d} {-1:4d}"
                for i, (x, y, z) in enumerate(xyz)
            ]
            ptv = [
                f"{p:4d} {q:4d} {x:10.3f} {y:10.3f} {z:10.3f}"
                for p, q, (x, y, z) in zip(prev, nxt, xyz, strict=True)
            ]
            (res / f"rt_is.{n}").write_text("\n".join([str(len(xyz)), *rt]) + "\n")
            (res / f"ptv_is.{n}").write_text("\n".join([str(len(xyz)), *ptv]) + "\n")


def perfect_myptv(dataset: Path, export: Path) -> None:
    """``trajectories_dt<k>`` as MyPTV's tracking writes them (id x y z, blob indices,
    error, frame index), of every imaged particle, frame indices by the export's
    frames.csv; a particle imaged in both frames of a snapshot is one trajectory."""
    runs = TruthFile(dataset).runs()
    index = {
        (int(r["dt"]), int(r["snapshot"]), r["frame"]): int(r["frame_index"])
        for r in _frames(export)
    }
    lines: dict[int, list[str]] = {}
    trajectory = 0
    for k, run in enumerate(runs):
        for m in range(run.positions.shape[0]):
            in_a, in_b = _imaged(run, m)
            both = np.intersect1d(in_a, in_b)
            ids = {p: trajectory + i for i, p in enumerate(both)}
            trajectory += len(both)
            for f, members in (("a", in_a), ("b", in_b)):
                for p in members:
                    x, y, z = run.positions[m, "ab".index(f), p] * MM
                    lines.setdefault(k, []).append(
                        f"{ids.get(p, -1)}\t{x:.3f}\t{y:.3f}\t{z:.3f}\t0\t0\t0.010\t"
                        f"{index[k, m, f]:.3f}"
                    )
    for k, rows in lines.items():
        (export / f"trajectories_dt{k}").write_text("\n".join(rows) + "\n")


def check_score(folder: Path) -> None:
    """A perfect code's score: every reference particle found, no ghost, the errors of
    mm rounded to three decimals (0.29 µm rms), every link correct."""
    score = json.loads((folder / "score.json").read_text())
    assert score["yield"] == 1.0 and score["ghost_fraction"] == 0.0
    assert score["n_reference"] > 0 and score["n_true_positive"] == score["n_reference"]
    assert max(score["position_rms_um"].values()) < 1.0
    tracks = score["tracks"]
    assert tracks["links"] > 0 and tracks["wrong"] == 0 and tracks["broken"] == 0
    assert tracks["correct"] == tracks["links"]


def test_the_page_runs(tmp_path, monkeypatch):
    commands = page_commands()
    assert [shlex.split(c)[1] for c in commands] == [
        "render",
        "export",
        "convert",
        "score",
        "export",
        "convert",
        "score",
    ]
    monkeypatch.chdir(tmp_path)
    rig = small_rig(tmp_path)
    for command in commands:
        argv = shlex.split(command)[1:]
        if argv[0] == "render":
            assert PAGE_SIZES in command
            argv = shlex.split(command.replace(PAGE_SIZES, TEST_SIZES.format(rig=rig)))[1:]
        if argv[0] == "convert":
            source = argv[argv.index("--from") + 1]
            inputs = argv[argv.index("--input") + 1 : argv.index("--out")]
            export = Path(inputs[0]).parent
            {"openptv": perfect_openptv, "myptv": perfect_myptv}[source](Path("dataset"), export)
            assert len(inputs) == len(TruthFile(Path("dataset")).dt)
        assert main(argv) == 0, command
        if argv[0] == "score":
            check_score(Path(argv[argv.index("--out") + 1]))


@pytest.mark.parametrize("section", ["3. "])
def test_the_recording_commands_parse(section):
    """§3 needs a `synptv run` of minutes: its commands are checked to parse only."""
    from validation.cli import build_parser

    commands = page_commands((section,))
    assert [shlex.split(c)[1] for c in commands] == ["run", "export", "convert", "score"]
    for command in commands:
        build_parser().parse_args(shlex.split(command)[1:])
