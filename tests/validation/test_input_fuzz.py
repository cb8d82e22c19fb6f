"""Fuzzed input files: every command either accepts its input or refuses it in one line.

Hypothesis spoils the scenario TOML of ``synptv run``, the rig TOML of ``synptv
render`` and the experiment.json of ``synptv calibrate`` and ``synptv ptv`` (values of
any type and size, fields removed or added, arbitrary bytes). Whatever the file, the
command must either reach its work (replaced here by a stand-in that stops it: the work
itself is tested elsewhere) or exit with status 2 and one line on stderr that names the
file; and it must write nothing anywhere, in its ``--out`` or outside.
"""

import json
import math
import os
import tempfile
import tomllib
from contextlib import contextmanager
from importlib import resources
from pathlib import Path
from unittest import mock

import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from simulator.presets import flow_preset
from simulator.rigs import load_rig
from validation.cli import main
from validation.run.render_dataset import RenderSettings, write_dataset

FUZZ = settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)


class ReachedTheWork(Exception):
    """Raised by the stand-in for a command's work: the input was accepted."""


def _stop(*args, **kwargs):
    raise ReachedTheWork


# -- spoiling a parsed file ---------------------------------------------------------------
SCALARS = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(min_value=-(2**63), max_value=2**63 - 1),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0, -1, 1e9, 1e300, -1e-300, "../../x", "/tmp/x", "", "cam1", "ü"]),
    st.text(max_size=12),
)
VALUES = st.recursive(
    SCALARS,
    lambda inner: (
        st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=6), inner, max_size=3)
    ),
    max_leaves=8,
)


def _paths(tree, prefix=()):
    """Every key path of a nested dict/list."""
    items = tree.items() if isinstance(tree, dict) else enumerate(tree)
    for key, value in items:
        yield (*prefix, key)
        if isinstance(value, dict | list):
            yield from _paths(value, (*prefix, key))


@st.composite
def spoilt(draw, spec: dict, values=VALUES):
    """``spec`` (deep-copied) with one to three fields replaced, removed or added."""
    spec = json.loads(json.dumps(spec))
    for _ in range(draw(st.integers(1, 3))):
        paths = list(_paths(spec))
        if not paths:
            break
        path = draw(st.sampled_from(paths))
        parent = spec
        for key in path[:-1]:
            parent = parent[key]
        action = draw(st.sampled_from(["replace", "remove", "add"]))
        if action == "replace":
            parent[path[-1]] = draw(values)
        elif action == "remove":
            del parent[path[-1]]
        elif isinstance(parent, dict):
            parent[draw(st.text(min_size=1, max_size=8))] = draw(values)
    return spec


# -- writing TOML (the standard library only reads it) ------------------------------------
def _toml_value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return (
            "nan"
            if math.isnan(value)
            else ("inf" if value > 0 else "-inf")
            if math.isinf(value)
            else repr(value)
        )
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return (
            "{" + ", ".join(f"{json.dumps(k)} = {_toml_value(v)}" for k, v in value.items()) + "}"
        )
    raise TypeError(value)


def to_toml(spec: dict) -> str:
    """TOML text for a parsed document (None values, which TOML lacks, are left out)."""
    lines = []
    for key, value in spec.items():
        if value is None:
            continue
        lines.append(f"{json.dumps(key)} = {_toml_value(_without_none(value))}")
    return "\n".join(lines) + "\n"


def _without_none(value):
    if isinstance(value, dict):
        return {k: _without_none(v) for k, v in value.items() if v is not None}
    if isinstance(value, list):
        return [_without_none(v) for v in value if v is not None]
    return value


def _preset_toml(package: str, folder: str, name: str) -> dict:
    return tomllib.loads((resources.files(package) / folder / f"{name}.toml").read_text())


# -- the check ------------------------------------------------------------------------------
def _tree(root: Path) -> dict:
    return {str(p.relative_to(root)): p.stat().st_mtime_ns for p in sorted(root.rglob("*"))}


@contextmanager
def _workspace():
    """A fresh folder to run in, removed afterwards."""
    with tempfile.TemporaryDirectory() as folder:
        yield Path(folder)


def assert_accepted_or_refused_in_one_line(argv, file: Path, root: Path, capsys) -> None:
    """Run ``synptv argv``; the input must be accepted or refused in one line naming
    ``file``, and nothing may be written under ``root`` (which holds ``file``)."""
    before = _tree(root)
    try:
        code = main(argv)
    except ReachedTheWork:
        code = None
    event("accepted" if code is None else "refused")
    err = capsys.readouterr().err
    if code is not None:
        lines = err.strip().splitlines()
        assert code == 2 and len(lines) == 1, err
        assert file.name in lines[0] or str(file) in lines[0], lines[0]
        assert "np.float64" not in lines[0] and "Traceback" not in lines[0]
    assert _tree(root) == before


# -- the commands -------------------------------------------------------------------------------
SCENARIO = _preset_toml("validation", "scenarios", "default")
RIG = _preset_toml("simulator", "rig_presets", "paper-stereo")


@FUZZ
@given(spec=spoilt(SCENARIO))
def test_run_accepts_or_refuses_any_scenario_file(spec, capsys):
    with _workspace() as root, mock.patch("validation.run.experiment.run_stages", _stop):
        path = root / "mine.toml"
        path.write_text(to_toml(spec))
        argv = ["run", "--scenario", str(path), "--out", str(root / "out"), "--quiet"]
        assert_accepted_or_refused_in_one_line(argv, path, root, capsys)


@FUZZ
@given(data=st.binary(max_size=200) | st.text(max_size=200).map(str.encode))
def test_run_refuses_any_bytes_as_a_scenario_file_in_one_line(data, capsys):
    with _workspace() as root, mock.patch("validation.run.experiment.run_stages", _stop):
        path = root / "mine.toml"
        path.write_bytes(data)
        argv = ["run", "--scenario", str(path), "--out", str(root / "out"), "--quiet"]
        assert_accepted_or_refused_in_one_line(argv, path, root, capsys)


@FUZZ
@given(spec=spoilt(RIG))
def test_render_accepts_or_refuses_any_rig_file(spec, capsys):
    with _workspace() as root, mock.patch("validation.run.render_dataset.write_dataset", _stop):
        path = root / "rig.toml"
        path.write_text(to_toml(spec))
        argv = ["render", "--rig", str(path), "--out", str(root / "out"), "--quiet"]
        assert_accepted_or_refused_in_one_line([*argv, "--workers", "1"], path, root, capsys)


@pytest.fixture(scope="module")
def small_dataset(tmp_path_factory):
    """A rendered dataset: 3 plate positions, 2 frame pairs per Δt."""
    folder = tmp_path_factory.mktemp("fuzz") / "ds"
    write_dataset(
        folder,
        load_rig("paper-stereo"),
        flow_preset("lem-10hz"),
        RenderSettings(frames=2, planes=3, particles=100, n_modes=40, seed=1),
    )
    return folder


@contextmanager
def _dataset_with(folder: Path, spec: dict):
    """A copy of ``folder`` (files linked) whose experiment.json is ``spec``."""
    with _workspace() as root:
        copy = root / "ds"
        for path in sorted(folder.rglob("*")):
            target = copy / path.relative_to(folder)
            if path.is_dir():
                target.mkdir(parents=True)
            elif path.name != "experiment.json":
                os.symlink(path, target)
        (copy / "experiment.json").write_text(json.dumps(spec, allow_nan=True))
        yield root, copy


@FUZZ
@given(data=st.data())
def test_calibrate_accepts_or_refuses_any_experiment_json(small_dataset, data, capsys):
    spec = data.draw(spoilt(json.loads((small_dataset / "experiment.json").read_text())))
    with (
        _dataset_with(small_dataset, spec) as (root, copy),
        mock.patch("ptv.calibration.plate_images.find_dots", _stop),
    ):
        argv = ["calibrate", "--dataset", str(copy), "--out", str(root / "cal"), "--quiet"]
        assert_accepted_or_refused_in_one_line(argv, copy / "experiment.json", root, capsys)


#: A calibrated volume for the calibration the ptv fuzz does not read, m.
CALIBRATED = ((-0.05, -0.05, -0.005), (0.05, 0.05, 0.005))


@FUZZ
@given(data=st.data())
def test_ptv_accepts_or_refuses_any_experiment_json(small_dataset, data, capsys, tmp_path_factory):
    spec = data.draw(spoilt(json.loads((small_dataset / "experiment.json").read_text())))
    calibration = small_dataset.parent / "calibration.h5"
    if not calibration.exists():  # any file will do: the pipeline is not reached
        calibration.write_bytes(b"")
    with (
        _dataset_with(small_dataset, spec) as (root, copy),
        mock.patch("ptv.pipeline.double_frame.run_pipeline", _stop),
        mock.patch("ptv.calibration.io.load_calibrations", lambda path: {}),
        mock.patch("ptv.io.dataset.cameras_in_order", lambda dataset, calibrations: []),
        mock.patch("ptv.calibration.io.read_calibrated_volume", lambda path: CALIBRATED),
    ):
        argv = ["ptv", "--dataset", str(copy), "--calibration", str(calibration)]
        argv += ["--out", str(root / "out"), "--quiet"]
        assert_accepted_or_refused_in_one_line(argv, copy / "experiment.json", root, capsys)
