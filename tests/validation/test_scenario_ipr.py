"""A scenario's [ipr]: read, written back, and refused where IPR cannot run."""

import json

import pytest

from validation.run.ipr_section import (
    IPR_BYTES_PER_PARTICLE,
    WORKER_BYTES,
    IprSection,
    check_ipr_memory,
)
from validation.run.scenario import ScenarioError, load_scenario, scenario_from_dict

FOUR_CAMERAS = (
    '[rig]\nname = "lpt-challenge-small"\n[calibration]\nmethods = ["model-free"]\n'
    '[ptv]\nmethods = ["model-free"]\n'
)


def write(tmp_path, body: str):
    path = tmp_path / "s.toml"
    path.write_text(f'name = "s"\n{body}')
    return path


def test_dense_ci_has_ipr_rungs_through_the_true_cameras_and_its_calibration():
    scenario = load_scenario("dense-ci")
    assert scenario.ipr == IprSection(methods=("model-free",))
    assert scenario.ipr.variants() == ("ipr-true-cameras", "ipr-model-free")
    assert scenario.ipr.settings().mapping_grid == 32.0
    spec = json.loads(json.dumps(scenario.as_dict()))
    assert scenario_from_dict(spec) == scenario


def test_a_scenario_without_ipr_writes_no_ipr_table():
    assert "ipr" not in load_scenario("ci").as_dict()


@pytest.mark.parametrize(
    ("body", "message"),
    [
        ('[ipr]\nmethods = ["model-free"]\n', "IPR needs at least 3 cameras"),
        (FOUR_CAMERAS + '[ipr]\nmethods = ["tsai"]\n', "ipr.methods ['tsai'] are not in"),
        (FOUR_CAMERAS + "[ipr]\nmethods = []\n", "ipr.methods must name at least one"),
        (FOUR_CAMERAS + "[ipr]\notf_regions = [0, 2]\n", "ipr.otf_regions must be"),
        (FOUR_CAMERAS + "[ipr]\notf_regions = [1, 2, 3]\n", "ipr.otf_regions must be"),
        (FOUR_CAMERAS + "[ipr]\nmapping_grid = -1.0\n", "ipr.mapping_grid must be"),
        (FOUR_CAMERAS + "[ipr]\notf_depth_slabs = 0\n", "ipr.otf_depth_slabs must be"),
        (FOUR_CAMERAS + "[ipr]\nshaking = 0\n", "ipr: unknown field(s) 'shaking'"),
        (FOUR_CAMERAS + "[recording]\ntau_tau_eta = 0.1\n[ipr]\n", "[ipr] runs on frame pairs"),
    ],
)
def test_an_ipr_that_cannot_run_is_refused_naming_file_and_field(tmp_path, body, message):
    with pytest.raises(ScenarioError, match=r"s\.toml") as error:
        load_scenario(write(tmp_path, body))
    assert message in str(error.value)


def test_the_memory_estimate_refuses_a_density_before_any_work():
    """Half the machine's memory is the bar: the dense scenario's 9300 tracers on two
    workers fit one that could hold a bit more than the plan, and fail one that cannot."""
    scenario = load_scenario("dense")
    pixels = 4 * 512 * 512
    plan = 2 * (WORKER_BYTES + 9300 * IPR_BYTES_PER_PARTICLE + pixels * 16)
    check_ipr_memory(scenario, "dense", pixels, workers=2, memory=2.01 * plan)
    with pytest.raises(ScenarioError, match=r"^dense: particles\.count: .* 9300 tracers"):
        check_ipr_memory(scenario, "dense", pixels, workers=2, memory=1.99 * plan)
