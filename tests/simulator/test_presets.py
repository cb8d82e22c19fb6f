"""Presets: the paper's Table 3 arithmetic (claims #1–#4 of docs/claims.md)."""

import pytest

from simulator.presets import FLOW_PRESETS, flow_preset

# Table 3 as printed (eta µm, tau_eta ms, R_lambda) and the Table 4 maximum Δt/τ_η.
TABLE3 = {
    "lem-8hz": (56, 3.2, 291, 0.15),
    "lem-10hz": (49, 2.4, 339, 0.21),
    "lem-12hz": (42, 1.7, 388, 0.23),
}


@pytest.mark.parametrize("name", sorted(TABLE3))
def test_presets_reproduce_table3(name):
    eta_um, tau_ms, r_lambda, _ = TABLE3[name]
    p = flow_preset(name).parameters
    assert p.eta * 1e6 == pytest.approx(eta_um, rel=0.05)
    assert p.tau_eta * 1e3 == pytest.approx(tau_ms, rel=0.05)
    assert p.R_lambda == pytest.approx(r_lambda, rel=0.01)  # 10 Hz only with u' = 0.19
    assert p.L_int == pytest.approx(0.04, rel=0.10)
    assert 3.9 <= round(225e-6 / p.eta, 1) <= 5.4  # d_p ≃ 5η, docs/flow.md §4


@pytest.mark.parametrize("name", sorted(TABLE3))
def test_dt_sets_follow_table4(name):
    preset = flow_preset(name)
    assert preset.dt[-1] / preset.parameters.tau_eta == pytest.approx(TABLE3[name][3])
    assert 0.15 <= preset.dt_over_tau_eta[-1] <= 0.23
    assert list(preset.dt) == sorted(preset.dt)


def test_unknown_preset_lists_the_known_ones():
    with pytest.raises(ValueError, match="lem-10hz"):
        flow_preset("lem-11hz")
    assert set(FLOW_PRESETS) == set(TABLE3)
