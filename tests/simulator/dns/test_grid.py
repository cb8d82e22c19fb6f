"""DNS grid and units: the box from ν, ε, N and k_max η; every bad input refused."""

import logging
from math import pi

import numpy as np
import pytest

from simulator.dns import grid as grid_module
from simulator.dns.forcing import ConstantPowerForcing, ForcedBand
from simulator.dns.grid import Grid, dns_setup, memory_estimate


def test_box_side_puts_the_two_thirds_cutoff_at_the_asked_resolution():
    nu, epsilon = 1.0e-6, 0.1
    setup = dns_setup(nu, epsilon, 64, kmax_eta=1.5)
    eta = (nu**3 / epsilon) ** 0.25
    assert setup.eta == pytest.approx(eta, rel=1e-15)
    # k_max = (N/3)(2π/L) by definition: k_max η is what was asked
    assert setup.grid.kmax * eta == pytest.approx(1.5, rel=1e-14)
    assert setup.grid.box_side == pytest.approx(2 * pi * 64 * eta / (3 * 1.5), rel=1e-14)
    assert setup.tau_eta == pytest.approx((nu / epsilon) ** 0.5, rel=1e-15)


def test_wavenumbers_follow_the_rfftn_layout():
    g = Grid(32, 0.5)
    kx, _, kz = g.wavenumbers()
    k0 = 2 * pi / 0.5
    assert kx.shape == (32,) and kz.shape == (17,)
    assert kx[1] == pytest.approx(k0) and kx[-1] == pytest.approx(-k0)
    assert kz[-1] == pytest.approx(16 * k0)
    assert np.array_equal(g.coordinates(), np.arange(32) * 0.5 / 32)
    assert g.spectral_shape == (32, 32, 17)


def test_the_two_thirds_rule_keeps_modes_below_n_over_three():
    g = Grid(96, 1.0)  # N/3 = 32 is an integer: |n| = 32 must be cut (2·32 aliases onto −32)
    keep_x, _, keep_z = g.kept()
    n = np.fft.fftfreq(96, 1 / 96)
    assert set(np.abs(n[keep_x]).astype(int)) == set(range(32))
    assert keep_z.sum() == 32


def test_mode_weights_count_conjugates():
    w = Grid(32, 1.0).mode_weights()
    assert w[0] == w[-1] == 1 and np.all(w[1:-1] == 2)
    assert w.sum() == 32  # the half spectrum stands for all 32 values of n_z


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"n": 16}, "n"),
        ({"n": 30}, "n"),  # even but < 32
        ({"n": 33}, "n"),  # odd
        ({"n": 34}, "n"),  # 2·17: not FFT-friendly
        ({"n": 62}, "n"),  # 2·31
        ({"n": 64.0}, "n"),
        ({"n": 2048}, "n"),  # FFT-friendly, but far more memory than the machine has
        ({"nu": 0.0}, "nu"),
        ({"nu": float("nan")}, "nu"),
        ({"epsilon": -1.0}, "epsilon"),
        ({"epsilon": float("inf")}, "epsilon"),
        ({"kmax_eta": 0.99}, "kmax_eta"),
        ({"kmax_eta": 0.0}, "kmax_eta"),
        ({"tracers": -1}, "tracers"),
    ],
)
def test_bad_inputs_are_refused_naming_the_field(kwargs, field):
    args = {"nu": 1e-6, "epsilon": 0.1, "n": 64} | kwargs
    with pytest.raises(ValueError, match=rf"^{field}\b") as info:
        dns_setup(args.pop("nu"), args.pop("epsilon"), args.pop("n"), **args)
    assert "\n" not in str(info.value)


def test_memory_above_what_is_available_is_refused(monkeypatch):
    monkeypatch.setattr(grid_module, "available_memory", lambda: memory_estimate(64) - 1)
    with pytest.raises(ValueError, match=r"^n = 64 needs about"):
        dns_setup(1e-6, 0.1, 64)
    monkeypatch.setattr(grid_module, "available_memory", lambda: memory_estimate(64))
    dns_setup(1e-6, 0.1, 64)


def test_memory_estimate_grows_with_the_grid_and_the_tracers():
    # the field arrays scale as N³: 8× from 64³ to 128³ once the fixed part is removed
    fixed = memory_estimate(0)
    assert (memory_estimate(128) - fixed) == 8 * (memory_estimate(64) - fixed)
    assert memory_estimate(64, tracers=10_000) > memory_estimate(64)


def test_low_resolution_is_warned_naming_kmax_eta(caplog):
    with caplog.at_level(logging.WARNING, logger="simulator.dns.grid"):
        dns_setup(1e-6, 0.1, 32, kmax_eta=1.2)
    assert any("kmax_eta" in r.getMessage() for r in caplog.records)
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="simulator.dns.grid"):
        dns_setup(1e-6, 0.1, 32, kmax_eta=1.5)
    assert not caplog.records


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [({"n": 31, "box_side": 1.0}, "n"), ({"n": 32, "box_side": -1.0}, "box_side")],
)
def test_grid_refuses_bad_sizes(kwargs, field):
    with pytest.raises(ValueError, match=rf"^{field}\b"):
        Grid(**kwargs)


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [({"epsilon": 0.0}, "epsilon"), ({"band": 0.5}, "band"), ({"band": True}, "band")],
)
def test_forcing_refuses_bad_parameters(kwargs, field):
    with pytest.raises(ValueError, match=rf"^{field}\b"):
        ConstantPowerForcing(**({"epsilon": 1.0} | kwargs))


def test_forced_band_must_lie_below_the_cutoff():
    with pytest.raises(ValueError, match=r"^band = 11"):
        ForcedBand(Grid(32, 2 * pi), ConstantPowerForcing(1.0, band=11.0))
    # shells 1 and 2: 6 + 12 + 8 + 6 lattice vectors with |n|² = 1, 2, 3, 4
    assert ForcedBand(Grid(32, 2 * pi), ConstantPowerForcing(1.0)).modes == 32
