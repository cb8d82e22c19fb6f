"""A scenario's Navier–Stokes flow: the fields of its kind, refused by name otherwise,
before anything is allocated."""

import re

import pytest

from validation.run.scenario import ScenarioError, load_scenario, scenario_from_dict

DNS = {"kind": "dns", "epsilon": 1e-5, "grid": 64, "dt_tau_eta": [0.1, 0.2]}
PTV = {"r_min": 1e-3, "r_max": 25e-3, "plateau": [2e-3, 20e-3]}


def scenario(flow: dict, ptv: dict = PTV):
    return scenario_from_dict({"name": "t", "flow": flow, "ptv": ptv}, source="t.toml")


def test_a_dns_flow_takes_its_defaults_and_keeps_its_own_fields():
    flow = scenario(DNS).flow
    assert (flow.nu, flow.kmax_eta, flow.spacing, flow.preset) == (1e-6, 1.5, 1.0, None)
    written = scenario(DNS).as_dict()["flow"]
    assert written["kind"] == "dns" and "spectrum" not in written and "preset" not in written


def test_a_ks_flow_is_written_as_before_without_its_kind():
    assert "kind" not in load_scenario("ci").as_dict()["flow"]


@pytest.mark.parametrize(
    ("change", "ptv", "message"),
    [
        ({"spectrum": "pope"}, PTV, "flow.spectrum: a field of kinematic simulation"),
        ({"u_rms": 0.1}, PTV, "flow.u_rms: a field of kinematic simulation"),
        ({"epsilon": None}, PTV, "flow.epsilon: a DNS flow needs"),
        ({"grid": 63}, PTV, "flow.grid: n must be even"),
        ({"grid": 16}, PTV, "flow.grid: n must be at least 32"),
        ({"grid": 70}, PTV, "flow.grid: n = 70 is not FFT-friendly"),
        ({"kmax_eta": 0.8}, PTV, "flow.kmax_eta must be from 1"),
        ({"spacing": 0.5}, PTV, "flow.spacing must be from 1"),
        ({"grid": 1024}, PTV, "flow.grid: n = 1024 needs about"),
        ({"file": "f.h5"}, PTV, "flow.file is not a field of a 'dns' flow"),
        (
            {},
            {**PTV, "r_max": 35e-3},
            "ptv.r_max reaches 35 mm, beyond half the DNS box",
        ),
        ({}, {}, "ptv.r_min and ptv.r_max and ptv.plateau: a DNS must give them"),
        (
            {},
            {"r_min": 0.5e-3, "r_max": 25e-3, "plateau": [2e-3, 20e-3]},
            "ptv.r_min starts at 0.5 mm, below the flow's Kolmogorov length",
        ),
    ],
)
def test_bad_dns_fields_are_refused_by_name(change, ptv, message):
    flow = {k: v for k, v in {**DNS, **change}.items() if v is not None}
    with pytest.raises(ScenarioError, match=re.escape(message)):
        scenario(flow, ptv)


def test_a_ks_flow_refuses_the_fields_of_a_dns():
    with pytest.raises(ScenarioError, match=r"flow\.grid is not a field of a 'ks' flow"):
        scenario({"preset": "lem-10hz", "grid": 64}, {})
