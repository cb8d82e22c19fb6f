"""The [ptv] ranges a scenario leaves out follow its rig's sheet and its flow's η and L_int
(validation/run/derived_ptv.py); those it gives are kept."""

import logging

import numpy as np
import pytest

from simulator.rigs import load_rig
from validation.run.scenario import ScenarioError, load_scenario

SLOW_FLOW = "[flow]\nu_rms = 0.05\nepsilon = 1.0e-3\nnu = 1.0e-6\ndt_tau_eta = [0.05, 0.1, 0.2]\n"


def write(tmp_path, body, name="s"):
    path = tmp_path / f"{name}.toml"
    path.write_text(f'name = "{name}"\n{body}')
    return path


def test_the_slow_flow_gets_ranges_from_its_eta_and_integral_length(tmp_path):
    scenario = load_scenario(write(tmp_path, SLOW_FLOW + '[rig]\nname = "box-4cam"\n'))
    # η = (ν³/ε)^(1/4) = 177.8 µm, L_int = u′³/ε = 125 mm; the sheet 100 × 100 × 10 mm
    eta, l_int = (1e-18 / 1e-3) ** 0.25, 0.05**3 / 1e-3
    width, height, thickness = load_rig("box-4cam").sheet.size
    assert np.allclose(scenario.ptv.analysis_size, (0.7 * width, 0.7 * height, 0.8 * thickness))
    r_max = min(0.35 * min(width, height), l_int)  # half the volume's smaller side: 35 mm
    assert np.allclose((scenario.ptv.r_min, scenario.ptv.r_max), (10 * eta, r_max))
    assert np.allclose(scenario.ptv.plateau, (40 * eta, min(l_int / 2, 0.6 * r_max)))
    assert scenario.ptv.max_speed is None and scenario.ptv.min_cameras is None


def test_given_ranges_are_kept(tmp_path):
    body = SLOW_FLOW + "[ptv]\nr_min = 1.0e-3\nr_max = 30.0e-3\nplateau = [5.0e-3, 15.0e-3]\n"
    scenario = load_scenario(write(tmp_path, body))
    assert (scenario.ptv.r_min, scenario.ptv.r_max) == (1e-3, 30e-3)
    assert scenario.ptv.plateau == (5e-3, 15e-3)


def test_the_paper_scenarios_keep_the_paper_ranges():
    for name in ("default", "ci", "paper-8hz", "paper-10hz", "paper-12hz"):
        ptv = load_scenario(name).ptv
        assert (ptv.analysis_size, (ptv.r_min, ptv.r_max), ptv.plateau) == (
            (0.07, 0.07, 0.008),
            (0.5e-3, 35e-3),
            (2e-3, 20e-3),
        )


def test_a_dns_must_give_its_ranges(tmp_path):
    body = '[flow]\nkind = "dns"\nepsilon = 1.0e-4\ngrid = 64\ndt_tau_eta = [0.05, 0.1]\n'
    missing = r"ptv.r_min and ptv.r_max and ptv.plateau: a DNS must give"
    with pytest.raises(ScenarioError, match=missing):
        load_scenario(write(tmp_path, body))


def test_a_field_file_keeps_the_paper_ranges_with_a_warning(caplog):
    from validation.run.derived_ptv import derive_ptv_ranges

    scenario = load_scenario("default")
    with caplog.at_level(logging.WARNING):
        derived = derive_ptv_ranges(scenario, set(), (0.1, 0.1, 0.01), None, "f.toml")
    assert (derived.ptv.r_min, derived.ptv.r_max) == (0.5e-3, 35e-3)
    assert derived.ptv.plateau == (2e-3, 20e-3)
    assert "ptv.r_max = 35 mm is the paper flow's default, not derived" in caplog.text
    assert "ptv.plateau = 2–20 mm is the paper flow's default, not derived" in caplog.text


def test_a_flow_whose_range_comes_out_empty_is_refused(tmp_path):
    # η = 2.8 mm: 40η = 113 mm, beyond the 35 mm the sheet's analysis volume holds
    body = "[flow]\nu_rms = 0.01\nepsilon = 1.0e-8\nnu = 1.0e-5\ndt_tau_eta = [0.05, 0.1]\n"
    with pytest.raises(ScenarioError, match=r"ptv\.r_min and ptv\.r_max derived from the flow"):
        load_scenario(write(tmp_path, body))


def test_a_plateau_that_cannot_start_at_40_eta_takes_the_widest_the_volume_allows(
    tmp_path, caplog
):
    """η = 0.75 mm (ν 4·10⁻⁶, ε 10⁻⁴): 40η = 30 mm lies beyond the 21 mm the volume
    allows the plateau, 10η = 7.5 mm does not; the plateau runs from 10η with a warning,
    and the checks name it."""
    from validation.run.verdict import plateau_row

    body = "[flow]\nu_rms = 0.02\nepsilon = 1.0e-4\nnu = 4.0e-6\ndt_tau_eta = [0.05, 0.1]\n"
    with caplog.at_level(logging.WARNING):
        scenario = load_scenario(write(tmp_path, body))
    eta = (4e-6**3 / 1e-4) ** 0.25
    lo, hi = scenario.ptv.plateau
    assert lo == pytest.approx(10 * eta) and hi == pytest.approx(0.6 * 35e-3)
    assert "the widest plateau the volume allows" in caplog.text
    row = plateau_row(scenario.ptv.plateau, eta)
    assert row["value"] == pytest.approx(10) and "below 40η" in row["tolerance"]
    assert "informative" in row
    assert plateau_row((2e-3, 20e-3), 49.2e-6) is None  # the paper's: 40.6η


def test_independent_pairs_whose_radius_reaches_the_spacing_are_warned_about(tmp_path, caplog):
    """3000 tracers in the 100 × 100 × 10 mm sheet, u′ = 2 cm/s: at Δt = 20 and 25 ms the
    radius 5u′Δt + 5σ_b (2.15, 2.65 mm) takes a second particle from the density
    3·10⁷ m⁻³ with probability 1 − exp(−n 4π r³/3): 71 % and 90 %."""
    from validation.run.derived_ptv import independent_pair_ambiguity

    body = (
        "[flow]\nu_rms = 0.02\nepsilon = 1.0e-4\nnu = 1.0e-6\n"
        "dt_tau_eta = [0.05, 0.1, 0.15, 0.2, 0.25]\n"
        '[rig]\nname = "box-4cam"\n'
        "[particles]\ncount = 3000\nshared_first_frame = false\n"
    )
    with caplog.at_level(logging.WARNING):
        scenario = load_scenario(write(tmp_path, body))
    assert "at Δt = 20, 25 ms" in caplog.text and "71, 90 %" in caplog.text
    assert "the largest Δt this seeding links unambiguously is 15 ms" in caplog.text
    n = 3000 / (0.1 * 0.1 * 0.01)
    radius = 5 * 0.02 * np.array([5, 10, 15, 20, 25]) * 1e-3 + 5 * 30e-6
    expected = 1 - np.exp(-n * 4 / 3 * np.pi * radius**3)
    got = independent_pair_ambiguity(scenario, (0.1, 0.1, 0.01), 0.02, "s")
    np.testing.assert_allclose(got, expected, rtol=1e-6)
