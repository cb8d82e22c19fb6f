"""A scenario's custom flow: parsing, the Δt set in seconds, refusals that name the
field, and the derived scales that ``synptv render`` and ``synptv run`` print and write.

The references are computed here from the definitions (docs/flow.md §4), not through
the code under test: η = (ν³/ε)^{1/4}, τ_η = (ν/ε)^{1/2}, R_λ = (15 u'⁴/(εν))^{1/2},
L_int = u'³/ε.
"""

import json
import math

import h5py
import pytest

from validation.cli import main
from validation.run.scenario import (
    FlowSection,
    ScenarioError,
    load_scenario,
    scenario_from_dict,
)

U_RMS, EPSILON, NU = 0.12, 0.05, 1.5e-6
RATIOS = [0.05, 0.1, 0.2]

CUSTOM = f"""\
[flow]
u_rms = {U_RMS}
epsilon = {EPSILON}
nu = {NU}
dt_tau_eta = {RATIOS}
modes = 40
unsteadiness = 0.8
"""

#: Sizes that render and run in seconds.
TINY = """\
[calibration]
planes = 3
methods = ["model-free"]

[particles]
count = 300
frames = 4

[ptv]
methods = ["model-free"]
bins = 8
n_boot = 20
"""


def write(path, text):
    """Write ``text`` to ``path`` and return the path."""
    path.write_text(text)
    return path


def scales(u_rms, epsilon, nu):
    """η (m), τ_η (s), R_λ and L_int (m) from their definitions."""
    return {
        "eta": (nu**3 / epsilon) ** 0.25,
        "tau_eta": math.sqrt(nu / epsilon),
        "R_lambda": math.sqrt(15 * u_rms**4 / (epsilon * nu)),
        "L_int": u_rms**3 / epsilon,
    }


EXPECTED = scales(U_RMS, EPSILON, NU)
EXPECTED_DT = [r * EXPECTED["tau_eta"] for r in RATIOS]


def assert_flow_record(record, expected_dt=EXPECTED_DT):
    """A written flow (JSON object or HDF5 attributes) against the definitions."""
    assert str(record["preset"]) == "custom"
    for key, value in {"u_rms": U_RMS, "epsilon": EPSILON, "nu": NU, **EXPECTED}.items():
        assert float(record[key]) == pytest.approx(value, rel=1e-12), key
    assert list(record["dt"]) == pytest.approx(expected_dt, rel=1e-12)
    assert float(record["unsteadiness"]) == 0.8


def test_a_custom_flow_in_kolmogorov_times_gives_its_dt_in_seconds(tmp_path):
    scenario = load_scenario(write(tmp_path / "s.toml", f'name = "s"\n{CUSTOM}'))
    flow = scenario.flow.as_preset()
    assert scenario.flow.preset is None and flow.name == "custom"
    assert list(flow.dt) == pytest.approx(EXPECTED_DT, rel=1e-14)
    assert flow.parameters.eta == pytest.approx(EXPECTED["eta"], rel=1e-14)
    assert scenario.flow.modes == 40 and scenario.flow.unsteadiness == 0.8


def test_a_custom_flow_in_seconds_keeps_its_dt_and_water_is_the_default_nu(tmp_path):
    dt = [2e-4, 5e-4, 1e-3, 2e-3]
    body = f'name = "s"\n[flow]\nu_rms = 0.2\nepsilon = 0.3\ndt = {dt}\n'
    scenario = load_scenario(write(tmp_path / "s.toml", body))
    assert scenario.flow.nu == 1.0e-6
    flow = scenario.flow.as_preset()
    assert list(flow.dt) == pytest.approx(dt, rel=1e-14)
    tau_eta = math.sqrt(1.0e-6 / 0.3)
    assert list(flow.dt_over_tau_eta) == pytest.approx([d / tau_eta for d in dt], rel=1e-14)


def test_a_custom_flow_round_trips_through_json(tmp_path):
    scenario = load_scenario(write(tmp_path / "s.toml", f'name = "s"\n{CUSTOM}'))
    spec = json.loads(json.dumps(scenario.as_dict(), allow_nan=False))
    assert "preset" not in spec["flow"] and "dt" not in spec["flow"]
    assert scenario_from_dict(spec) == scenario


def test_a_preset_flow_keeps_its_fields_and_its_default_unsteadiness():
    flow = load_scenario("default").flow
    assert flow == FlowSection(preset="lem-10hz")
    assert flow.unsteadiness == 0.5
    assert load_scenario("default").as_dict()["flow"] == {
        "preset": "lem-10hz",
        "spectrum": "pope",
        "modes": 200,
        "unsteadiness": 0.5,
    }


GOOD = "u_rms = 0.12\nepsilon = 0.05\n"


@pytest.mark.parametrize(
    ("body", "field"),
    [
        (f'preset = "lem-10hz"\n{GOOD}dt = [1e-3, 2e-3]\n', "flow.preset"),
        ('preset = "lem-10hz"\nnu = 1e-6\n', "flow.preset"),
        ("u_rms = 0.12\ndt = [1e-3, 2e-3]\n", "flow.epsilon"),
        ("epsilon = 0.05\ndt = [1e-3, 2e-3]\n", "flow.u_rms"),
        (GOOD, "flow.dt"),
        (f"{GOOD}dt = [1e-3, 2e-3]\ndt_tau_eta = [0.1, 0.2]\n", "flow.dt"),
        (f"{GOOD}dt = [1e-3]\n", "flow.dt"),
        (f"{GOOD}dt = [2e-3, 1e-3]\n", "flow.dt"),
        (f"{GOOD}dt = [1e-3, 1e-3, 2e-3]\n", "flow.dt"),
        (f"{GOOD}dt = [-1e-3, 1e-3]\n", "flow.dt"),
        (f"{GOOD}dt_tau_eta = [0.0, 0.1]\n", "flow.dt_tau_eta"),
        (f"{GOOD}dt = 1e-3\n", "flow.dt"),
        (f'{GOOD}dt = ["1 ms", "2 ms"]\n', "flow.dt"),
        (f"{GOOD}dt = [1e-3, 100.0]\n", "flow.dt"),
        (f"{GOOD}dt_tau_eta = [0.1, 1e6]\n", "flow.dt_tau_eta"),
        ("u_rms = 0.12\nepsilon = 0.0\ndt = [1e-3, 2e-3]\n", "flow.epsilon"),
        ("u_rms = 0.12\nepsilon = -0.05\ndt = [1e-3, 2e-3]\n", "flow.epsilon"),
        ("u_rms = 0.12\nepsilon = inf\ndt = [1e-3, 2e-3]\n", "flow.epsilon"),
        (f"{GOOD}nu = 0.0\ndt = [1e-3, 2e-3]\n", "flow.nu"),
        (f"{GOOD}nu = 1.0\ndt = [1e-3, 2e-3]\n", "flow.nu"),
        ("u_rms = 50.0\nepsilon = 0.05\ndt = [1e-3, 2e-3]\n", "flow.u_rms"),
        ('u_rms = "fast"\nepsilon = 0.05\ndt = [1e-3, 2e-3]\n', "flow.u_rms"),
        (f"{GOOD}dt = [1e-3, 2e-3]\nunsteadiness = -1.0\n", "flow.unsteadiness"),
        ("unsteadiness = 100.0\n", "flow.unsteadiness"),
        (f"{GOOD}dt = [1e-3, 2e-3]\nturbulence = 1\n", "turbulence"),
        # R_λ = 0.04: no mode range between the integral and the Kolmogorov scale.
        ("u_rms = 1e-3\nepsilon = 1e-2\ndt = [1e-3, 2e-3]\n", "flow: u_rms, epsilon and nu"),
    ],
)
def test_bad_flows_are_errors_that_name_the_file_and_the_field(tmp_path, body, field):
    path = write(tmp_path / "bad.toml", f'name = "bad"\n[flow]\n{body}')
    with pytest.raises(ScenarioError) as error:
        load_scenario(path)
    message = str(error.value)
    assert str(path) in message and field in message
    assert "\n" not in message


@pytest.mark.parametrize("command", ["render", "run"])
def test_a_bad_flow_exits_2_in_one_line_and_writes_nothing(tmp_path, capsys, command):
    path = write(
        tmp_path / "bad.toml",
        'name = "bad"\n[flow]\nu_rms = 0.1\nepsilon = -1.0\ndt = [1e-3, 2e-3]\n',
    )
    out = tmp_path / "out"
    assert main([command, "--scenario", str(path), "--out", str(out), "--quiet"]) == 2
    printed = capsys.readouterr()
    assert printed.err.count("\n") == 1 and "flow.epsilon" in printed.err
    assert str(path) in printed.err
    assert not out.exists() and printed.out == ""


def test_render_renders_a_custom_flow_and_records_its_scales(tmp_path, capsys):
    path = write(tmp_path / "custom.toml", f'name = "custom"\nseed = 2\n{CUSTOM}\n{TINY}')
    out = tmp_path / "ds"
    argv = ["render", "--scenario", str(path), "--out", str(out), "--workers", "1", "--quiet"]
    assert main(argv) == 0, capsys.readouterr().err
    first = capsys.readouterr().out.splitlines()[0]
    assert first.startswith("flow custom: u' = 0.12 m/s")
    assert f"eta = {EXPECTED['eta'] * 1e6:.1f} um" in first
    assert f"R_lambda = {EXPECTED['R_lambda']:.1f}" in first
    spec = json.loads((out / "experiment.json").read_text())
    assert spec["dt"] == pytest.approx(EXPECTED_DT, rel=1e-12)
    with h5py.File(out / "truth.h5") as truth:
        assert_flow_record(dict(truth["flow"].attrs))
        assert list(truth["flow"].attrs["dt_over_tau_eta"]) == pytest.approx(RATIOS)


def test_run_of_a_custom_flow_writes_its_scales_into_results_json(tmp_path, capsys):
    path = write(tmp_path / "custom.toml", f'name = "custom"\nseed = 2\n{CUSTOM}\n{TINY}')
    out = tmp_path / "run"
    argv = ["run", "--scenario", str(path), "--out", str(out), "--workers", "1", "--quiet"]
    assert main(argv) in (0, 1), capsys.readouterr().err  # 1: a check failed at this size
    assert capsys.readouterr().out.startswith("flow custom: u' = 0.12 m/s")
    results = json.loads((out / "results.json").read_text())
    assert_flow_record(results["flow"])
    assert results["flow"]["dt_over_tau_eta"] == pytest.approx(RATIOS)
    assert results["scenario"]["flow"]["dt_tau_eta"] == RATIOS
