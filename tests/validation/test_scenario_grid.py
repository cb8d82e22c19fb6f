"""A scenario on a periodic field file of one's own (``kind = "grid"``): the file is
resolved beside the scenario and read as a run will read it; what it cannot serve is
refused by name, with exit status 2 and nothing written."""

import re
import subprocess
import sys

import h5py
import numpy as np
import pytest

from simulator.dns.fieldfile import PeriodicFieldSeries, write_field_file
from validation.run.grid_flow import grid_run_flow
from validation.run.scenario import ScenarioError, load_scenario

N, BOX = 32, 0.05
TIMES = np.arange(6) * 0.05  # s; τ_η = 0.316 s for ν = 1e-6, ε = 1e-5


def _field(path, times=TIMES):
    """A random periodic field with energy at the large scales, one per time."""
    rng = np.random.default_rng(0)
    k = np.fft.fftfreq(N, 1 / N)
    kz = np.fft.rfftfreq(N, 1 / N)
    k2 = k[:, None, None] ** 2 + k[None, :, None] ** 2 + kz[None, None, :] ** 2
    velocity = []
    for _ in times:
        hat = rng.normal(size=(3, N, N, N // 2 + 1)) + 1j * rng.normal(size=(3, N, N, N // 2 + 1))
        hat *= np.exp(-k2 / 8.0)
        velocity.append(np.fft.irfftn(hat, s=(N, N, N), axes=(1, 2, 3)) * 0.5)
    write_field_file(
        path,
        PeriodicFieldSeries(
            box_side=BOX,
            nu=1e-6,
            epsilon=1e-5,
            times=np.asarray(times),
            velocity=np.stack(velocity),
        ),
    )
    return path


def _scenario(folder, file="field.h5", extra_flow="", r_max=20e-3):
    text = f"""
name = "grid-test"
[flow]
kind = "grid"
file = "{file}"
dt_tau_eta = [0.04, 0.08, 0.12, 0.17, 0.21]
{extra_flow}
[particles]
count = 200
frames = 3
[ptv]
methods = ["model-free"]
r_min = 1.0e-3
r_max = {r_max}
plateau = [2.0e-3, 10.0e-3]
[calibration]
methods = ["model-free"]
"""
    path = folder / "scenario.toml"
    path.write_text(text)
    return path


def test_the_file_is_found_beside_the_scenario_and_gives_the_flow(tmp_path):
    _field(tmp_path / "field.h5")
    scenario = load_scenario(_scenario(tmp_path))
    assert scenario.flow.file == str(tmp_path / "field.h5")
    flow = grid_run_flow(scenario.flow, scenario.particles.frames)
    assert flow.scales["box_side"] == BOX and flow.scales["file_snapshots"] == 6
    # the run's 3 snapshots spread over the file, each leaving room for the largest Δt
    starts = flow.tracers.starts
    assert starts[0] == 0.0 and starts[-1] + flow.preset.dt[-1] == pytest.approx(TIMES[-1])
    assert len(flow.inputs["sha256"]) == 64


def _broken(path, how):
    with h5py.File(path, "r+") as f:
        if how == "nan":
            f["u"][1, 0, 0, 0] = np.nan
        elif how == "missing":
            del f["w"]
        elif how == "box":
            f["x"][...] = f["x"][()] * 1.1


@pytest.mark.parametrize(
    ("how", "extra", "r_max", "message"),
    [
        ("absent", "", 20e-3, "no such file"),
        ("nan", "", 20e-3, "dataset 'u' holds NaN or infinite values"),
        ("missing", "", 20e-3, "missing dataset 'w'"),
        ("box", "", 20e-3, "dataset 'x' is not i·box_side/n"),
        ("short", "", 20e-3, "less than the largest Δt"),
        (None, "", 30e-3, "beyond half the file's periodic box (25 mm)"),
        (None, 'spectrum = "pope"', 20e-3, "flow.spectrum: a field of kinematic simulation"),
    ],
)
def test_a_file_that_cannot_serve_is_refused_by_name(tmp_path, how, extra, r_max, message):
    field = tmp_path / "field.h5"
    if how != "absent":
        _field(field, times=TIMES[:4] * 0.2 if how == "short" else TIMES)
    if how in ("nan", "missing", "box"):
        _broken(field, how)
    with pytest.raises(ScenarioError, match=re.escape(message)):
        load_scenario(_scenario(tmp_path, extra_flow=extra, r_max=r_max))


def test_the_command_line_refuses_a_bad_file_with_exit_2_and_writes_nothing(tmp_path):
    _field(tmp_path / "field.h5")
    _broken(tmp_path / "field.h5", "nan")
    out = tmp_path / "out"
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "validation.cli",
            "run",
            "--scenario",
            str(_scenario(tmp_path)),
            "--out",
            str(out),
        ],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 2
    assert "flow.file" in done.stderr and "field.h5" in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1
    assert not out.exists()
