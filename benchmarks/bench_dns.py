"""DNS speed and memory: seconds per RK4 step at 64³ and 128³ beside fluidsim's ns3d.

Targets (docs/dns.md §7): synptv's step ≤ 1.5× fluidsim's at both grids, one thread
each, and a 128³ run (with 10⁴ tracers, small) within 1.5 GiB of resident memory.

Each code runs in its own subprocess (clean peak memory, its thread settings): synptv's
solver on one and on two FFT workers, fluidsim's ``ns3d`` (RK4, 2/3 dealiasing,
pyfftw with one thread, forced, no output) on one. The two codes alternate and each
figure is the best step of its runs, so that other work on a shared machine hurts both
alike. fluidsim is an optional extra (``pip install -e ".[dns-peer]"``; CeCILL, and
pyfftw's wheels bundle GPL FFTW): without it the benchmark says so.
"""

import json
import os
import subprocess
import sys
import tempfile

from benchmarks.machine import machine
from simulator.dns.grid import memory_estimate

#: synptv's step over fluidsim's, at most.
TARGET_RATIO = 1.5

#: Peak resident memory of a 128³ run, GiB, at most.
TARGET_MEMORY_GIB = 1.5

_SYNPTV_PROBE = """
import json, resource, sys, time
from simulator.dns.forcing import ConstantPowerForcing
from simulator.dns.grid import dns_setup
from simulator.dns.solver import NavierStokesSolver
from simulator.dns.spinup import initial_state
n, workers, steps = (int(a) for a in sys.argv[1:4])
setup = dns_setup(1e-6, 0.1, n)
solver = NavierStokesSolver(
    setup.grid, nu=setup.nu, forcing=ConstantPowerForcing(0.1), workers=workers
)
state = initial_state(solver, rng=0)
h = solver.max_step(state)
state = solver.advance(state, h)  # compiled kernels loaded, buffers touched
times = []
for _ in range(steps):
    start = time.perf_counter()
    state = solver.advance(state, h)
    times.append(time.perf_counter() - start)
rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
print(json.dumps({"times": times, "peak_rss_bytes": rss}))
"""

_FLUIDSIM_PROBE = """
import contextlib, io, json, resource, sys, time
import numpy as np
n, steps = (int(a) for a in sys.argv[1:3])
with contextlib.redirect_stdout(io.StringIO()):
    from fluidsim.solvers.ns3d.solver import Simul
    p = Simul.create_default_params()
    p.oper.nx = p.oper.ny = p.oper.nz = n
    p.oper.Lx = p.oper.Ly = p.oper.Lz = 2 * np.pi
    p.oper.type_fft = "fft3d.with_pyfftw"
    p.oper.coef_dealiasing = 2 / 3
    p.nu_2 = 0.01
    p.time_stepping.USE_CFL = False
    p.time_stepping.deltat0 = 1e-3
    p.time_stepping.type_time_scheme = "RK4"
    p.init_fields.type = "noise"
    p.forcing.enable = True
    p.forcing.type = "tcrandom"
    p.forcing.nkmin_forcing, p.forcing.nkmax_forcing = 1, 2
    p.forcing.key_forced = ["vx_fft", "vy_fft", "vz_fft"]
    p.forcing.forcing_rate = 1 / 3  # forced per component: 3 × this rate in all
    p.output.HAS_TO_SAVE = False
    sim = Simul(p)
    sim.time_stepping.one_time_step()
    times = []
    for _ in range(steps):
        start = time.perf_counter()
        sim.time_stepping.one_time_step()
        times.append(time.perf_counter() - start)
rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
print(json.dumps({"times": times, "peak_rss_bytes": rss}))
"""


def _probe(code: str, args: list, env: dict) -> dict:
    result = subprocess.run(
        [sys.executable, "-c", code, *map(str, args)],
        capture_output=True,
        text=True,
        env={**os.environ, **env},
    )
    if result.returncode != 0:
        lines = result.stderr.strip().splitlines()
        raise RuntimeError(lines[-1] if lines else f"exit status {result.returncode}")
    return json.loads(result.stdout.strip().splitlines()[-1])


def _fluidsim_missing() -> str | None:
    check = subprocess.run(
        [sys.executable, "-c", "import fluidsim.solvers.ns3d.solver, pyfftw"],
        capture_output=True,
        text=True,
    )
    if check.returncode == 0:
        return None
    return check.stderr.strip().splitlines()[-1]


def run(quick: bool) -> dict:
    """Measure both codes; returns a JSON-able dict with the targets beside the figures."""
    grids = (64,) if quick else (64, 128)
    rounds, steps = (1, 3) if quick else (2, 4)
    one_thread = {"OMP_NUM_THREADS": "1", "NUMBA_NUM_THREADS": "1"}
    missing = _fluidsim_missing()
    figures: dict = {"machine": machine(), "grids": {}}
    with tempfile.TemporaryDirectory() as sim_data:
        peer_env = {**one_thread, "FLUIDSIM_PATH": sim_data, "FLUIDDYN_PATH_SCRATCH": sim_data}
        for n in grids:
            best: dict[str, float] = {}
            rss: dict[str, int] = {}
            runs = [("synptv_1_thread", _SYNPTV_PROBE, [n, 1, steps], one_thread)]
            if missing is None:
                runs.append(("fluidsim_1_thread", _FLUIDSIM_PROBE, [n, steps], peer_env))
            runs.append(("synptv_2_workers", _SYNPTV_PROBE, [n, 2, steps], one_thread))
            for _ in range(rounds):
                for name, code, args, env in runs:
                    out = _probe(code, args, env)
                    best[name] = min(best.get(name, float("inf")), min(out["times"]))
                    rss[name] = max(rss.get(name, 0), out["peak_rss_bytes"])
            grid = {f"s_per_step_{name}": value for name, value in best.items()}
            grid |= {f"peak_rss_gib_{name}": value / 2**30 for name, value in rss.items()}
            grid["memory_estimate_gib_with_1e4_tracers"] = (
                memory_estimate(n, tracers=10_000) / 2**30
            )
            if missing is None:
                peer = best["fluidsim_1_thread"]
                grid["ratio_1_thread"] = best["synptv_1_thread"] / peer
                grid["ratio_2_workers_vs_fluidsim_1_thread"] = best["synptv_2_workers"] / peer
            figures["grids"][str(n)] = grid
    figures["fluidsim"] = "ns3d, pyfftw, one thread" if missing is None else f"absent: {missing}"
    figures["target_ratio"] = TARGET_RATIO
    figures["target_memory_gib_128"] = TARGET_MEMORY_GIB
    if missing is None:
        figures["meets_speed_target_1_thread"] = all(
            g["ratio_1_thread"] <= TARGET_RATIO for g in figures["grids"].values()
        )
    if "128" in figures["grids"]:
        figures["meets_memory_target"] = (
            figures["grids"]["128"]["peak_rss_gib_synptv_1_thread"] <= TARGET_MEMORY_GIB
        )
    return figures
