"""Scenarios: presets load, dict round trip, errors that name file and field, rig paths."""

import json
import logging
import shutil
from dataclasses import fields, replace
from importlib import resources

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from ptv.settings import PipelineSettings, StatisticsSettings
from simulator.rigs import load_rig
from validation.run.scenario import (
    PtvSection,
    ScenarioError,
    load_scenario,
    scenario_from_dict,
    scenario_presets,
)

RIG_PRESET = resources.files("simulator") / "rig_presets" / "paper-stereo.toml"


def write(path, text):
    """Write ``text`` to ``path`` (its folders created) and return the path."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def json_round_trip(scenario):
    """The scenario as it comes back from a JSON file: tuples become lists."""
    return scenario_from_dict(json.loads(json.dumps(scenario.as_dict(), allow_nan=False)))


def test_the_shipped_presets_include_the_documented_ones():
    assert {"default", "paper-8hz", "paper-10hz", "paper-12hz"} <= set(scenario_presets())


@pytest.mark.parametrize("name", scenario_presets())
def test_every_preset_loads_with_a_usable_flow_and_rig(name):
    scenario = load_scenario(name)
    assert scenario.name == name
    assert set(scenario.ptv.methods) <= set(scenario.calibration.methods)
    if scenario.flow.kind == "ks":
        scenario.flow.as_preset()
    else:  # a DNS's u' is measured: its prescribed scales before it has run
        assert "box side" in scenario.flow.describe()
    load_rig(scenario.rig.name)


@pytest.mark.parametrize("name", scenario_presets())
def test_presets_round_trip_through_json(name):
    scenario = load_scenario(name)
    assert json_round_trip(scenario) == scenario


@given(
    seed=st.integers(0, 2**63 - 1),
    count=st.integers(1, 10**5),
    electrons=st.floats(1e-3, 1e6),
    gain=st.floats(1e-3, 10.0),
    r_low=st.floats(5e-5, 1e-2),  # from η of the default flow (49 µm)
    r_ratio=st.floats(1.001, 9.9),  # to the analysis volume's diagonal (99.3 mm)
    shared=st.booleans(),
)
def test_any_valid_scenario_round_trips_through_json(
    seed, count, electrons, gain, r_low, r_ratio, shared
):
    base = load_scenario("default")
    scenario = replace(
        base,
        seed=seed,
        particles=replace(
            base.particles, count=count, electrons=electrons, shared_first_frame=shared
        ),
        sensor=replace(base.sensor, gain=gain),
        ptv=replace(base.ptv, r_min=r_low, r_max=r_low * r_ratio),
    )
    assert json_round_trip(scenario) == scenario


def test_missing_tables_and_fields_take_the_defaults(tmp_path):
    scenario = load_scenario(write(tmp_path / "minimal.toml", 'name = "minimal"\n'))
    assert scenario.seed == 0 and scenario.description == ""
    derived = ("analysis_size", "r_min", "r_max", "plateau")  # test_derived_ptv.py
    assert replace(scenario.ptv, **{k: getattr(PtvSection(), k) for k in derived}) == PtvSection()
    assert json_round_trip(scenario) == scenario


def test_the_ptv_table_names_its_settings_as_the_settings_do():
    settings = {f.name for cls in (PipelineSettings, StatisticsSettings) for f in fields(cls)}
    # analysis_size: a centred box's sizes, where StatisticsSettings.analysis_volume is corners
    assert {f.name for f in fields(PtvSection)} - settings == {"methods", "analysis_size"}


def test_the_ptv_table_defaults_are_the_settings_defaults():
    pipeline = PipelineSettings()
    shared = {f.name for f in fields(PtvSection)} - {"methods", "analysis_size"}
    for name in shared:
        owner = pipeline if name in {f.name for f in fields(pipeline)} else pipeline.statistics
        assert getattr(PtvSection(), name) == getattr(owner, name), name


def test_the_old_ptv_keys_are_read_under_their_new_names_with_a_warning(tmp_path, caplog):
    body = (
        'name = "s"\n[ptv]\nr_range = [1.0e-3, 30.0e-3]\nbins = 12\n'
        "analysis_volume = [0.06, 0.06, 0.006]\n"
    )
    with caplog.at_level(logging.WARNING):
        ptv = load_scenario(write(tmp_path / "s.toml", body)).ptv
    assert (ptv.r_min, ptv.r_max, ptv.n_bins) == (1e-3, 30e-3, 12)
    assert ptv.analysis_size == (0.06, 0.06, 0.006)
    old = [r.getMessage() for r in caplog.records if "is an old name" in r.getMessage()]
    assert [message.split(".toml: ")[1] for message in old] == [
        "ptv.r_range is an old name, read as ptv.r_min and ptv.r_max: write that",
        "ptv.bins is an old name, read as ptv.n_bins: write that",
        "ptv.analysis_volume is an old name, read as ptv.analysis_size: write that",
    ]


def test_an_integer_is_accepted_for_a_float_field(tmp_path):
    path = write(tmp_path / "s.toml", 'name = "s"\n[particles]\nelectrons = 1500\n')
    electrons = load_scenario(path).particles.electrons
    assert electrons == 1500.0 and type(electrons) is float


@pytest.mark.parametrize(
    ("body", "field"),
    [
        ("[camera]\nexposure = 1.0\n", "camera"),
        ('[flow]\nturbulence = "strong"\n', "turbulence"),
        ("flow = 3\n", "[flow]"),
        ('[particles]\ncount = "many"\n', "count"),
        ("[particles]\ncount = 2000.0\n", "count"),
        ("[particles]\nshared_first_frame = 1\n", "shared_first_frame"),
        ('[ptv]\nmethods = "tsai"\n', "methods"),
        ("seed = -1\n", "seed"),
        ("seed = 1.5\n", "seed"),
        ("[sensor]\ngain = -0.4\n", "gain"),
        ('[flow]\npreset = "lem-11hz"\n', "flow.preset"),
        ('[flow]\nspectrum = "von-karman"\n', "flow.spectrum"),
        ('[calibration]\nmethods = ["model-free", "dlt"]\n', "calibration.methods"),
        ('[calibration]\nplate = "warped"\n', "calibration.plate"),
        (
            '[calibration]\nmethods = ["model-free"]\n[ptv]\nmethods = ["model-free", "tsai"]\n',
            "ptv.methods",
        ),
        ("[calibration]\nplanes = 2\n", "calibration.planes"),
        ("[particles]\nframes = 1\n", "particles.frames"),
        ("[particles]\ndiameter = 0.0\n", "particles.diameter"),
        ("[ptv]\nanalysis_size = [0.07, 0.07]\n", "ptv.analysis_size"),
        ("[ptv]\nr_min = 35e-3\nr_max = 0.5e-3\n", "ptv.r_min and ptv.r_max"),
        ("[ptv]\nr_min = 0.0\n", "ptv.r_min and ptv.r_max"),
        ("[ptv]\nr_min = -1e-3\n", "ptv.r_min and ptv.r_max"),
        ("[ptv]\nr_range = [35e-3, 0.5e-3]\n", "ptv.r_min and ptv.r_max"),
        ("[ptv]\nplateau = [2e-3, 2e-3]\n", "ptv.plateau"),
        ("[ptv]\nr_range = [1e-3]\n", "ptv.r_range must be a list of 2 numbers"),
        ('[ptv]\nr_min = "0.5 mm"\n', "ptv.r_min"),
        ("[ptv]\nr_range = [1e-3, 30e-3]\nr_max = 30e-3\n", "give ptv.r_max only"),
        ('[rig]\nname = "no-such-rig"\n', "rig.name"),
        ("[ptv]\nmethods = []\n", "ptv.methods"),
        ("[checks]\nc1_r_min_eta = 0.0\n", "checks.c1_r_min_eta"),
        ("[ptv]\nkolmogorov_c2 = -2.0\n", "kolmogorov_c2"),
        ("[ptv]\nmax_speed = 0.0\n", "max_speed"),
        ("[particles]\nelectrons = inf\n", "particles.electrons"),
        ("[particles]\ndiameter = nan\n", "particles.diameter"),
        ("[ptv]\nr_max = inf\n", "ptv.r_max"),
        ("[particles]\ncount = 1_000_000_000\n", "particles.count"),
        ("[particles]\nframes = 100_000_000\n", "particles.frames"),
        ("[flow]\nmodes = 10_000_000\n", "flow.modes"),
        ("[ptv]\nmin_cameras = 1\n", "ptv.min_cameras"),
        ("[ptv]\nmin_cameras = 3\n", "ptv.min_cameras"),
        ("[ptv]\nmin_cameras = 2.5\n", "min_cameras"),
        ("[ptv]\nr_max = 0.2\n", "ptv.r_max reaches 200 mm, beyond the 99.32 mm"),
        ("[ptv]\nplateau = [2e-3, 0.15]\n", "ptv.plateau reaches 150 mm"),
        ("[ptv]\nr_min = 2e-5\n", "ptv.r_min starts at 0.02 mm, below the flow's"),
        ("[ptv]\nplateau = [1e-5, 20e-3]\n", "ptv.plateau starts at 0.01 mm, below"),
        ("[ptv]\ntolerance = 0.0\n", "tolerance must be a finite number > 0"),
        ("[ptv]\nmax_speed = -1.5\n", "max_speed must be a finite number > 0"),
        ("[recording]\nframes = 100\n", "recording.frame_rate: give the frame rate"),
        ("[recording]\nframe_rate = 4e3\ntau_tau_eta = 0.1\n", "recording.frame_rate"),
        ("[recording]\nframe_rate = 0.5\n", "recording.frame_rate must be from 1"),
        ("[recording]\ntau_tau_eta = 5.0\n", "recording.tau_tau_eta: a frame every 5"),
        ("[recording]\nframe_rate = 20.0\n", "recording.frame_rate: a frame every"),
        ("[recording]\ntau_tau_eta = 0.1\nframes = 5\n", "recording.frames must be from 10"),
        ("[recording]\ntau_tau_eta = 0.1\nframes = 16\n", "recording.frames (16) must exceed"),
        ("[recording]\ntau_tau_eta = 0.1\nsteps = [1, 1]\n", "recording.steps"),
        ("[recording]\ntau_tau_eta = 0.1\nsteps = [3]\n", "recording.steps"),
        ("[recording]\ntau_tau_eta = 0.1\nsequences = 0\n", "recording.sequences"),
        ("[recording]\ntau_tau_eta = 0.1\nfit_window = 6\n", "recording.fit_window"),
        ("[recording]\ntau_tau_eta = 0.1\nfit_window = 3\n", "recording.fit_window"),
        ("[recording]\ntau_tau_eta = 0.1\nframes = 100_000\n", "recording.frames: 2000 tracers"),
        ("[recording]\ntau_tau_eta = 0.1\nrate = 4\n", "unknown field(s) 'rate'"),
        ("[recording]\ntau_tau_eta = 0.1\nmax_acceleration = 0.0\n", "max_acceleration"),
        (
            '[flow]\nkind = "dns"\nepsilon = 1e-5\ngrid = 64\ndt_tau_eta = [0.1, 0.2]\n'
            "[ptv]\nr_range = [1e-3, 25e-3]\nplateau = [2e-3, 20e-3]\n"
            "[particles]\nframes = 2\n[recording]\ntau_tau_eta = 0.1\nsequences = 3\n",
            "particles.frames (2) is the DNS's number of snapshots",
        ),
    ],
)
def test_bad_fields_are_errors_that_name_the_file_and_the_field(tmp_path, body, field):
    path = write(tmp_path / "bad.toml", f'name = "bad"\n{body}')
    with pytest.raises(ScenarioError) as error:
        load_scenario(path)
    assert str(path) in str(error.value)
    assert field in str(error.value)


def test_a_scenario_without_a_name_is_an_error(tmp_path):
    path = write(tmp_path / "anonymous.toml", "seed = 3\n")
    with pytest.raises(ScenarioError, match="name") as error:
        load_scenario(path)
    assert str(path) in str(error.value)


def test_invalid_toml_is_an_error_naming_the_file(tmp_path):
    path = write(tmp_path / "broken.toml", 'name = "broken"\n[flow\n')
    with pytest.raises(ScenarioError, match="TOML") as error:
        load_scenario(path)
    assert str(path) in str(error.value)


def test_a_missing_file_and_an_unknown_preset_are_clear_errors(tmp_path):
    missing = tmp_path / "nowhere.toml"
    with pytest.raises(ScenarioError, match="does not exist") as error:
        load_scenario(missing)
    assert str(missing) in str(error.value)
    with pytest.raises(ScenarioError, match="'paper-11hz'") as error:
        load_scenario("paper-11hz")
    assert "default" in str(error.value)  # the message lists the presets


@pytest.mark.parametrize("rig", ["myrig.toml", "rigs/myrig.toml"])
def test_a_relative_rig_file_is_taken_relative_to_the_scenario_file(tmp_path, monkeypatch, rig):
    folder = tmp_path / "cases"
    rig_file = folder / rig
    rig_file.parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(RIG_PRESET, rig_file)
    path = write(folder / "scenario.toml", f'name = "s"\n[rig]\nname = "{rig}"\n')
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    for given_path in (path, "../cases/scenario.toml"):
        scenario = load_scenario(given_path)
        assert (elsewhere / scenario.rig.name).resolve() == rig_file.resolve()
        load_rig(scenario.rig.name)


def test_absolute_rig_paths_and_rig_presets_are_kept(tmp_path):
    absolute = tmp_path / "rigs" / "abs.toml"
    absolute.parent.mkdir()
    shutil.copyfile(RIG_PRESET, absolute)
    for rig in (str(absolute), "conventional"):
        path = write(tmp_path / "cases" / "s.toml", f'name = "s"\n[rig]\nname = "{rig}"\n')
        assert load_scenario(path).rig.name == rig


def test_with_seed_changes_only_the_seed():
    scenario = load_scenario("default")
    reseeded = scenario.with_seed(np.int64(scenario.seed + 7))
    assert reseeded.seed == scenario.seed + 7 and type(reseeded.seed) is int
    assert reseeded == replace(scenario, seed=scenario.seed + 7)
    assert {**reseeded.as_dict(), "seed": scenario.seed} == scenario.as_dict()
    assert scenario.seed == load_scenario("default").seed  # the original is untouched


@pytest.mark.parametrize("name", ["../../../esc", "/tmp/esc", "a b", ".."])
def test_scenario_names_that_would_leave_the_working_folder_are_refused(tmp_path, name):
    path = write(tmp_path / "bad.toml", f"name = {name!r}\n".replace("'", '"'))
    with pytest.raises(ScenarioError, match="name must be 1 to 64 letters") as error:
        load_scenario(path)
    assert str(path) in str(error.value)


def test_a_recording_is_refused_before_any_work_when_it_would_not_fit_in_memory():
    from validation.run.recording_section import check_recording, recording_memory

    scenario = load_scenario("tr")
    need = recording_memory(scenario.particles.count, scenario.recording.frames)
    check_recording(scenario, "tr", memory=2.01 * need)  # fits in half
    with pytest.raises(ScenarioError, match=r"recording\.frames: 2000 tracers over 200 frames"):
        check_recording(scenario, "tr", memory=1.99 * need)


def test_a_recording_round_trips_and_frame_pair_scenarios_have_none():
    scenario = load_scenario("tr")
    assert scenario.recording is not None and json_round_trip(scenario) == scenario
    assert "recording" not in load_scenario("ci").as_dict()
