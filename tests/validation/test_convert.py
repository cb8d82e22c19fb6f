"""``synptv convert``: OpenPTV's and MyPTV's output files back into the positions and
tracks files ``synptv score`` reads. Known positions written in each code's layout
come back to 1e-9 m with their links; the real example files parse to the counts they
hold; bad input is a one-line error that writes nothing."""

import doctest
import json
import re
from pathlib import Path

import numpy as np
import pytest

from validation.cli import main
from validation.convert import myptv, openptv
from validation.convert.myptv import read_myptv
from validation.convert.openptv import read_openptv, read_rt_is
from validation.export.myptv import frame_index
from validation.export.openptv import FIRST_NUMBER, frame_number
from validation.score.positions import read_positions
from validation.score.track_file import read_tracks

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
CAMERAS = {"c1": {"image_size": [48, 32]}, "c2": {"image_size": [48, 32]}}
#: Frame pairs per Δt of the synthetic frame-pair dataset.
SNAPSHOTS = (3, 2)
#: The synthetic recording's frames.
FIRST, LAST = 2, 7


def pair_dataset(folder: Path) -> Path:
    """A frame-pair dataset's experiment.json (no images: convert reads none)."""
    folder.mkdir()
    spec = {
        "cameras": CAMERAS,
        "dt": [1e-3, 2e-3],
        "frames_per_dt": list(SNAPSHOTS),
        "bit_depth": 12,
        "particle_images": "particles/dt{k}/{camera}/{m:06d}_{a|b}.tif",
    }
    (folder / "experiment.json").write_text(json.dumps(spec))
    return folder


def recording(folder: Path) -> Path:
    """A recording's experiment.json, frames FIRST … LAST."""
    folder.mkdir()
    spec = {
        "cameras": CAMERAS,
        "acquisition": "time-resolved",
        "time_resolved": {
            "frame_rate": 1000.0,
            "images": "seq/{camera}/{n:06d}.tif",
            "steps": [1, 2],
            "first": FIRST,
            "last": LAST,
        },
        "bit_depth": 12,
    }
    (folder / "experiment.json").write_text(json.dumps(spec))
    return folder


def known_pairs(seed: int = 0) -> dict:
    """Positions (m) per (k, m, frame) and which frame-a particles are linked: particle i
    of frame a and particle i of frame b of a snapshot are one particle moved."""
    rng = np.random.default_rng(seed)
    truth = {}
    for k, count in enumerate(SNAPSHOTS):
        for m in range(count):
            n = 5 + k + m
            a = rng.uniform([-0.035, -0.035, -0.004], [0.035, 0.035, 0.004], (n, 3))
            b = a + rng.normal(0, 1e-4, (n, 3))
            linked = rng.random(n) < 0.6
            truth[k, m] = (a, b, linked)
    return truth


def _mm(value: float) -> str:
    return repr(float(value) * 1e3)


def write_rt_is(path: Path, xyz: np.ndarray) -> None:
    """An rt_is file as liboptv writes it, full precision: count, id x y z c1 … c4."""
    rows = [f"{i + 1:4d} {' '.join(_mm(v) for v in p)} {i} {i} -1 -1" for i, p in enumerate(xyz)]
    path.write_text("\n".join([str(len(xyz)), *rows]) + "\n")


def write_ptv_is(path: Path, xyz: np.ndarray, prev: np.ndarray, nxt: np.ndarray) -> None:
    rows = [
        f"{p:4d} {q:4d} {' '.join(_mm(v) for v in x)}"
        for p, q, x in zip(prev, nxt, xyz, strict=True)
    ]
    path.write_text("\n".join([str(len(xyz)), *rows]) + "\n")


def write_openptv_pairs(res: Path, truth: dict, k: int, links: bool = True) -> None:
    """One Δt's rt_is (and ptv_is) files, numbered as the export numbers the frames;
    frame b also links on to frame a of the next snapshot (a step that is no
    displacement, which convert must drop)."""
    res.mkdir()
    count = SNAPSHOTS[k]
    for m in range(count):
        a, b, linked = truth[k, m]
        n = len(a)
        write_rt_is(res / f"rt_is.{frame_number(m, 'a')}", a)
        write_rt_is(res / f"rt_is.{frame_number(m, 'b')}", b)
        if not links:
            continue
        ahead = np.where(linked, np.arange(n), -2)
        behind = np.where(linked, np.arange(n), -1)
        onward = np.full(n, -2)
        if m + 1 < count:
            onward[: min(2, n)] = [0, 1][: min(2, n)]  # b(m) → a(m + 1): dropped
        write_ptv_is(res / f"ptv_is.{frame_number(m, 'a')}", a, np.full(n, -1), ahead)
        write_ptv_is(res / f"ptv_is.{frame_number(m, 'b')}", b, behind, onward)


def check_positions(path: Path, truth: dict, with_tracks: bool) -> None:
    """The positions file holds exactly the known positions (to 1e-9 m), the linked
    particles sharing a track in frames a and b, every other position alone in its."""
    positions = read_positions(path, tracks=with_tracks)
    for (k, m), (a, b, linked) in truth.items():
        for f, xyz in enumerate((a, b)):
            rows = (positions.k == k) & (positions.snapshot == m) & (positions.frame == f)
            assert rows.sum() == len(xyz)
            np.testing.assert_allclose(positions.xyz[rows], xyz, rtol=0, atol=1e-9)
        if not with_tracks:
            continue
        here = (positions.k == k) & (positions.snapshot == m)
        ta = positions.track[here & (positions.frame == 0)]
        tb = positions.track[here & (positions.frame == 1)]
        np.testing.assert_array_equal(ta[linked], tb[linked])
        alone = np.concatenate([ta[~linked], tb[~linked]])
        assert len(set(alone)) == len(alone)
        assert not set(alone) & set(ta[linked])
    if with_tracks:
        _, counts = np.unique(
            np.column_stack([positions.k, positions.snapshot, positions.track]),
            axis=0,
            return_counts=True,
        )
        assert counts.max() <= 2


def test_openptv_frame_pairs_round_trip_with_their_links(tmp_path, capsys):
    dataset = pair_dataset(tmp_path / "dataset")
    truth = known_pairs()
    for k in range(len(SNAPSHOTS)):
        write_openptv_pairs(tmp_path / f"res_dt{k}", truth, k)
    out = tmp_path / "out" / "positions.csv"
    argv = ["convert", "--from", "openptv", "--dataset", str(dataset), "--out", str(out)]
    inputs = ["--input", str(tmp_path / "res_dt0"), str(tmp_path / "res_dt1")]
    assert main([*argv, *inputs]) == 0
    check_positions(out, truth, with_tracks=True)
    links = sum(int(linked.sum()) for _, _, linked in truth.values())
    assert f"{links} a → b links" in capsys.readouterr().out


def test_openptv_without_ptv_is_files_gives_positions_without_tracks(tmp_path):
    dataset = pair_dataset(tmp_path / "dataset")
    truth = {key: value for key, value in known_pairs(1).items() if key[0] == 0}
    write_openptv_pairs(tmp_path / "res", truth, 0, links=False)
    out = tmp_path / "positions.csv"
    argv = ["convert", "--from", "openptv", "--dataset", str(dataset)]
    assert main([*argv, "--input", str(tmp_path / "res"), "--out", str(out)]) == 0
    assert out.read_text().splitlines()[0] == "dt,snapshot,frame,x,y,z"
    check_positions(out, truth, with_tracks=False)
    # the working folder that holds res/ is read as its res/
    assert main([*argv, "--input", str(tmp_path), "--out", str(tmp_path / "again.csv")]) == 0
    assert (tmp_path / "again.csv").read_text() == out.read_text()


def write_myptv(path: Path, truth: dict, k: int, kind: str) -> None:
    """One Δt's MyPTV file: particles (x y z c1 c2 err frame), trajectories (id x y z
    c1 c2 err frame) or smoothed trajectories (id x y z vx vy vz ax ay az frame), the
    frame index as the export names the images, ids shared by a → b only where
    linked."""
    rows, next_id = [], 0
    for m in range(SNAPSHOTS[k]):
        a, b, linked = truth[k, m]
        ids = np.full(len(a), -1)
        ids[linked] = next_id + np.arange(linked.sum())
        next_id += int(linked.sum())
        for f, xyz in zip("ab", (a, b), strict=True):
            frame = f"{frame_index(m, f):.3f}"
            for i, p in enumerate(xyz):
                coordinates = "\t".join(_mm(v) for v in p)
                if kind == "particles":
                    rows.append(f"{coordinates}\t{i}\t{i}\t0.012\t{frame}")
                elif kind == "trajectories":
                    rows.append(f"{ids[i]}\t{coordinates}\t{i}\t{i}\t0.012\t{frame}")
                else:
                    rows.append(
                        f"{ids[i]}\t{coordinates}\t" + "\t".join(["0.1"] * 6) + f"\t{frame}"
                    )
    path.write_text("\n".join(rows) + "\n")


@pytest.mark.parametrize("kind", ["particles", "trajectories", "smoothed"])
def test_myptv_round_trip(tmp_path, kind):
    dataset = pair_dataset(tmp_path / "dataset")
    truth = known_pairs(2)
    for k in range(len(SNAPSHOTS)):
        write_myptv(tmp_path / f"{kind}_dt{k}", truth, k, kind)
    out = tmp_path / "positions.csv"
    inputs = [str(tmp_path / f"{kind}_dt{k}") for k in range(len(SNAPSHOTS))]
    argv = ["convert", "--from", "myptv", "--dataset", str(dataset), "--out", str(out)]
    assert main([*argv, "--input", *inputs]) == 0
    check_positions(out, truth, with_tracks=kind != "particles")
    assert ("track" in out.read_text().splitlines()[0]) == (kind != "particles")


def test_fewer_inputs_than_dt_leave_the_last_out(tmp_path):
    dataset = pair_dataset(tmp_path / "dataset")
    truth = known_pairs(3)
    write_myptv(tmp_path / "particles_dt0", truth, 0, "particles")
    out = tmp_path / "positions.csv"
    argv = ["convert", "--from", "myptv", "--dataset", str(dataset), "--out", str(out)]
    assert main([*argv, "--input", str(tmp_path / "particles_dt0")]) == 0
    assert set(read_positions(out).k) == {0}


def known_tracks(seed: int = 4) -> list[dict]:
    """Three true tracks over the recording's frames (frame n → position, m); one
    starts late and one is broken in two by the code (no link over its gap)."""
    rng = np.random.default_rng(seed)
    tracks = []
    for start, stop in [(FIRST, LAST), (FIRST + 2, LAST), (FIRST, FIRST + 2), (FIRST + 3, LAST)]:
        x0 = rng.uniform(-0.03, 0.03, 3)
        tracks.append({n: x0 + 1e-4 * (n - start) for n in range(start, stop + 1)})
    tracks.append({FIRST + 1: rng.uniform(-0.03, 0.03, 3)})  # never linked
    return tracks


def write_openptv_recording(res: Path, tracks: list[dict]) -> None:
    """rt_is and ptv_is files of the recording, frame n numbered 10001 + n − first, the
    rows of each frame in a shuffled order."""
    res.mkdir()
    rng = np.random.default_rng(5)
    rows = {}
    for n in range(FIRST, LAST + 1):
        members = [t for t, track in enumerate(tracks) if n in track]
        rows[n] = [members[i] for i in rng.permutation(len(members))]
    for n, members in rows.items():
        xyz = np.array([tracks[t][n] for t in members]).reshape(-1, 3)
        nxt = [rows[n + 1].index(t) if n + 1 in tracks[t] and n < LAST else -2 for t in members]
        prv = [rows[n - 1].index(t) if n - 1 in tracks[t] and n > FIRST else -1 for t in members]
        number = FIRST_NUMBER + n - FIRST
        write_rt_is(res / f"rt_is.{number}", xyz)
        write_ptv_is(res / f"ptv_is.{number}", xyz, np.array(prv), np.array(nxt))


def test_openptv_recording_round_trip_as_tracks(tmp_path):
    dataset = recording(tmp_path / "sequence0")
    tracks = known_tracks()
    write_openptv_recording(tmp_path / "res", tracks)
    out = tmp_path / "tracks.csv"
    argv = ["convert", "--from", "openptv", "--input", str(tmp_path / "res")]
    assert main([*argv, "--dataset", str(dataset), "--tracks", str(out)]) == 0
    found = read_tracks(out)
    got = []
    for t in np.unique(found.track):
        rows = found.track == t
        got.append(dict(zip(found.frame[rows].tolist(), found.position[rows], strict=True)))
    assert len(got) == len(tracks)
    for track in tracks:
        (match,) = [g for g in got if set(g) == set(track)]
        for n, x in track.items():
            np.testing.assert_allclose(match[n], x, rtol=0, atol=1e-9)


def test_myptv_recording_frames_from_first(tmp_path):
    dataset = recording(tmp_path / "sequence0")
    path = tmp_path / "trajectories"
    path.write_text("0\t1.0\t2.0\t0.5\t0.000\n0\t1.1\t2.0\t0.5\t1.000\n-1\t5.0\t2.0\t0.5\t1.000\n")
    out = tmp_path / "tracks.csv"
    argv = ["convert", "--from", "myptv", "--input", str(path), "--dataset", str(dataset)]
    assert main([*argv, "--tracks", str(out)]) == 0
    found = read_tracks(out)
    np.testing.assert_array_equal(found.frame, [FIRST, FIRST + 1, FIRST + 1])
    np.testing.assert_array_equal(found.track, [0, 0, 1])


# -- the real example files ------------------------------------------------------------


def test_openptv_example_rt_is_files_parse_to_their_counts():
    res = EXAMPLES / "test-cavity" / "openptv" / "res"
    counts = {}
    for path in sorted(res.glob("rt_is.*")):
        xyz, lines = read_rt_is(path)
        counts[path.name] = len(xyz)
        assert int(path.read_text().split("\n")[0]) == len(xyz) == len(lines)
    assert counts == {"rt_is.10001": 1128, "rt_is.10002": 1118}
    points = read_openptv(res)
    assert len(points.number) == 2246 and not points.linked
    np.testing.assert_array_equal(np.unique(points.number), [10001, 10002])
    np.testing.assert_allclose(points.xyz[0], [22.159e-3, 41.050e-3, 9.228e-3], rtol=1e-12)


def test_myptv_example_particles_file_parses_to_its_counts():
    path = EXAMPLES / "myptv" / "myptv" / "particles"
    points = read_myptv(path)
    table = np.loadtxt(path, ndmin=2)
    assert len(points.number) == len(table) == 281 and not points.linked
    frames, counts = np.unique(points.number, return_counts=True)
    np.testing.assert_array_equal(frames, np.arange(7))
    np.testing.assert_array_equal(counts, [37, 38, 42, 41, 38, 43, 42])
    np.testing.assert_allclose(points.xyz, table[:, :3] * 1e-3, rtol=1e-12)


@pytest.mark.parametrize("module", [openptv, myptv])
def test_the_examples_in_the_docstrings_run(module):
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert result.attempted > 0 and result.failed == 0


# -- bad input -------------------------------------------------------------------------


def _frame_pair_files(tmp_path: Path) -> tuple[Path, Path]:
    dataset = pair_dataset(tmp_path / "dataset")
    truth = {key: value for key, value in known_pairs(6).items() if key[0] == 0}
    write_openptv_pairs(tmp_path / "res", truth, 0)
    return dataset, tmp_path / "res"


def _edit(path: Path, line: int, text: str) -> None:
    lines = path.read_text().split("\n")
    lines[line - 1] = text
    path.write_text("\n".join(lines))


def _bad_count(res):
    _edit(res / "rt_is.10001", 1, "99")


def _bad_number(res):
    _edit(res / "rt_is.10001", 3, "   2 1.0 abc 3.0 0 0 -1 -1")


def _nan(res):
    _edit(res / "rt_is.10001", 2, "   1 nan 2.0 3.0 0 0 -1 -1")


def _short_row(res):
    _edit(res / "rt_is.10002", 2, "   1 1.0 2.0")


def _outside(res):
    (res / "rt_is.10007").write_text("1\n 1 1.0 2.0 0.5 0 0 -1 -1\n")


def _ptv_count(res):
    _edit(res / "ptv_is.10001", 1, "2")
    path = res / "ptv_is.10001"
    path.write_text("\n".join(path.read_text().split("\n")[:3]) + "\n")


def _link_row(res, line: int, nxt: int) -> None:
    """ptv_is.10001's row at ``line`` linked to row ``nxt`` of frame 10002."""
    path = res / "ptv_is.10001"
    fields = path.read_text().split("\n")[line - 1].split()
    _edit(path, line, " ".join(["-1", str(nxt), *fields[2:]]))


def _next_beyond(res):
    _link_row(res, 2, 99)


def _linked_twice(res):
    _link_row(res, 2, 0)
    _link_row(res, 3, 0)


def _moved(res):
    path = res / "ptv_is.10001"
    fields = path.read_text().split("\n")[1].split()
    _edit(path, 2, " ".join([*fields[:2], "123.0", *fields[3:]]))


def _no_files(res):
    for path in res.iterdir():
        path.unlink()


BAD_OPENPTV = [
    (_bad_count, r"rt_is\.10001 line 1: says 99 particles, holds \d+$"),
    (_bad_number, r"rt_is\.10001 line 3, column y: 'abc' is not a number$"),
    (_nan, r"rt_is\.10001 line 2, column x: nan \(every coordinate must be a finite number\)$"),
    (_short_row, r"rt_is\.10002 line 2: expected id x y z and a target index per camera"),
    (
        _outside,
        r"rt_is\.10007 line 2: OpenPTV frame number 10007 is no exposure of Δt_0 .*"
        r"\(10001 … 10006: 3 frame pairs",
    ),
    (_ptv_count, r"ptv_is\.10001 line 1: 2 particles, but rt_is\.10001 holds \d+$"),
    (
        _next_beyond,
        r"ptv_is\.10001 line 2, column next: links to row 99 of rt_is\.10002, "
        r"which holds \d+ particles",
    ),
    (
        _linked_twice,
        r"ptv_is\.10001 line 3, column next: row 0 of rt_is\.10002 is linked "
        r"from line 2 already",
    ),
    (_moved, r"ptv_is\.10001 line 2: x y z differ from row 0 of rt_is\.10001"),
    (_no_files, r"--input .*res: no rt_is\.<number> files"),
]


def _refused(argv: list[str], pattern: str, capsys, out: Path) -> None:
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert err.startswith("synptv convert: error: ")
    assert re.search(pattern, err), err
    assert not out.exists()
    assert not [p for p in out.parent.iterdir() if p.name.startswith(f".{out.name}")]


@pytest.mark.parametrize(
    ("damage", "pattern"), BAD_OPENPTV, ids=lambda v: getattr(v, "__name__", "")
)
def test_bad_openptv_files_are_refused_naming_file_and_line(tmp_path, capsys, damage, pattern):
    dataset, res = _frame_pair_files(tmp_path)
    damage(res)
    out = tmp_path / "positions.csv"
    argv = ["convert", "--from", "openptv", "--input", str(res), "--dataset", str(dataset)]
    _refused([*argv, "--out", str(out)], pattern, capsys, out)


BAD_MYPTV = [
    (
        "1.0\t2.0\t3.0\t0\t0\t0.01\t0.500\n",
        r"line 1, column frame \(the last\): '0.500' is not a frame index",
    ),
    ("1.0\t2.0\t3.0\n", r"line 1: expected x y z … frame \(a particles file\)"),
    ("0\t1.0\t2.0\t3.0\t0.000\n1\tx\t2.0\t3.0\t0.000\n", r"line 2, column x: 'x' is not a number"),
    (
        "-3\t1.0\t2.0\t3.0\t0.000\n",
        r"line 1, column id: -3 \(a trajectory id ≥ 0, or −1 for none\)",
    ),
    (
        "4\t1.0\t2.0\t3.0\t0.000\n4\t1.5\t2.0\t3.0\t0.000\n",
        r"line 2: code track 4 holds a second point in this frame \(the first at .* line 1\)",
    ),
    ("1.0\t2.0\t3.0\t0\t0\t0.01\t6.000\n", r"line 1: MyPTV frame index 6 is no exposure of Δt_0"),
    ("\n\n", r"no particles \(an empty file\)"),
]


@pytest.mark.parametrize(("text", "pattern"), BAD_MYPTV)
def test_bad_myptv_files_are_refused_naming_file_and_line(tmp_path, capsys, text, pattern):
    dataset = pair_dataset(tmp_path / "dataset")
    path = tmp_path / "particles_dt0"
    path.write_text(text)
    out = tmp_path / "positions.csv"
    argv = ["convert", "--from", "myptv", "--input", str(path), "--dataset", str(dataset)]
    _refused([*argv, "--out", str(out)], pattern, capsys, out)


def test_bad_command_lines_are_refused(tmp_path, capsys):
    pairs, res = _frame_pair_files(tmp_path)
    sequence = recording(tmp_path / "sequence0")
    (tmp_path / "recorded" / "sequence0").mkdir(parents=True)
    out = tmp_path / "o.csv"
    base = ["convert", "--from", "openptv", "--input", str(res)]
    cases = [
        ([*base, "--dataset", str(pairs), "--tracks", str(out)], r"holds frame pairs: write --out"),
        (
            [*base, "--dataset", str(sequence), "--out", str(out)],
            r"time-resolved recording.*--tracks",
        ),
        ([*base, "--dataset", str(pairs)], r"give --out positions.csv .* or --tracks tracks.csv"),
        (
            [*base, res.as_posix(), res.as_posix(), "--dataset", str(pairs), "--out", str(out)],
            r"--input: 3 inputs, but .* has 2 Δt",
        ),
        (
            [*base, "--dataset", str(tmp_path / "none"), "--out", str(out)],
            r"--dataset .*none: no such folder",
        ),
        (
            [*base, "--dataset", str(tmp_path / "recorded"), "--out", str(out)],
            r"a recorded dataset; name the recording .*sequence0",
        ),
        (
            [
                "convert",
                "--from",
                "openptv",
                "--input",
                str(tmp_path / "nowhere"),
                "--dataset",
                str(pairs),
                "--out",
                str(out),
            ],
            r"--input .*nowhere: no such folder",
        ),
        (
            [*base, "--dataset", str(pairs), "--out", str(tmp_path)],
            r"--out .* is a folder, not a file",
        ),
    ]
    for argv, pattern in cases:
        _refused(argv, pattern, capsys, out)


def test_a_recording_outside_its_frames_is_refused(tmp_path, capsys):
    sequence = recording(tmp_path / "sequence0")
    write_openptv_recording(tmp_path / "res", known_tracks())
    (tmp_path / "res" / "rt_is.10007").write_text("1\n 1 1.0 2.0 0.5 0 0 -1 -1\n")
    out = tmp_path / "tracks.csv"
    argv = ["convert", "--from", "openptv", "--input", str(tmp_path / "res")]
    pattern = r"rt_is\.10007 line 2: OpenPTV frame number 10007 is recorded frame 8, outside"
    _refused([*argv, "--dataset", str(sequence), "--tracks", str(out)], pattern, capsys, out)


def test_a_recording_needs_links(tmp_path, capsys):
    sequence = recording(tmp_path / "sequence0")
    path = tmp_path / "particles"
    path.write_text("1.0\t2.0\t3.0\t0\t0\t0.01\t0.000\n")
    out = tmp_path / "tracks.csv"
    argv = ["convert", "--from", "myptv", "--input", str(path), "--dataset", str(sequence)]
    _refused(
        [*argv, "--tracks", str(out)], r"particles: no links .* scored by its tracks", capsys, out
    )
