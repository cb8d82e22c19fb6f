"""KS flow speed and memory: velocity, velocity + acceleration, an RK4 step, peak memory.

Targets (docs/performance.md, issue 2): velocity ≤ 1.5 ns and velocity + Lagrangian acceleration
≤ 2.5 ns per particle·mode (float64, this 2-core machine), an RK4 step of 2000
particles × 200 modes ≤ 2 ms, and ≤ 1 GiB peak memory for 10⁵ particles × 300 modes.

The kernels are compiled for the machine they run on, so the figures go with its vector
extensions (printed). The velocity is also measured on one thread, and compiled for a
Haswell-class CPU (AVX2 and FMA, no AVX-512: ``NUMBA_CPU_NAME=haswell``, in a
subprocess) to show what an AVX2-only machine of the same clock would give.
"""

import json
import os
import subprocess
import sys
import time

import numba
import numpy as np

from benchmarks.machine import machine
from simulator.ks_field import draw_ks_field
from simulator.particles import SHEET, integrate
from simulator.presets import flow_preset
from simulator.spectra import PopeSpectrum

_MEMORY_PROBE = """
import json, resource, numpy as np
from simulator.ks_field import draw_ks_field
from simulator.presets import flow_preset
from simulator.spectra import PopeSpectrum
f = draw_ks_field(PopeSpectrum(flow_preset("lem-10hz").parameters), n_modes=300, rng=0)
x = np.random.default_rng(0).uniform(-0.05, 0.05, (100_000, 3))
f.velocity(x[:10]); f.derivatives(x[:10])  # compile / load the kernels first
before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
u = f.velocity(x); u, dudt, grad, a = f.derivatives(x)
after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(json.dumps({"baseline_mib": before / 1024, "peak_mib": after / 1024}))
"""


_AVX2_PROBE = """
import json, time, numpy as np
from simulator.ks_field import draw_ks_field
from simulator.particles import SHEET
from simulator.presets import flow_preset
from simulator.spectra import PopeSpectrum
f = draw_ks_field(PopeSpectrum(flow_preset("lem-10hz").parameters), n_modes=200, rng=0)
x = SHEET.sample(20_000, np.random.default_rng(1))
f.velocity(x, 0.01)
best = min(
    (lambda t0: (f.velocity(x, 0.01), time.perf_counter() - t0)[1])(time.perf_counter())
    for _ in range(5)
)
print(json.dumps({"ns": best / (x.shape[0] * f.n_modes) * 1e9}))
"""


def _best_time(func, repeats: int) -> float:
    func()
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        func()
        best = min(best, time.perf_counter() - start)
    return best


def run(quick: bool) -> dict:
    """Measure the KS figures; returns a JSON-able dict with targets beside them."""
    params = flow_preset("lem-10hz").parameters
    field = draw_ks_field(PopeSpectrum(params), n_modes=200, rng=0)
    repeats = 3 if quick else 10
    p = 20_000 if quick else 100_000
    x = SHEET.sample(p, np.random.default_rng(1))
    point_modes = p * field.n_modes
    t_vel = _best_time(lambda: field.velocity(x, 0.01), repeats)
    t_acc = _best_time(lambda: field.derivatives(x, 0.01), repeats)

    x2000 = x[:2000]
    steps = 20
    h = 0.02 * params.tau_eta
    times = np.array([0.0, steps * h])
    t_rk4 = _best_time(lambda: integrate(field, x2000, times, h_max=h * (1 + 1e-9)), repeats)

    threads = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        t_one = _best_time(lambda: field.velocity(x, 0.01), repeats)
    finally:
        numba.set_num_threads(threads)
    probe = subprocess.run(
        [sys.executable, "-c", _MEMORY_PROBE], capture_output=True, text=True, check=True
    )
    memory = json.loads(probe.stdout)
    avx2 = subprocess.run(
        [sys.executable, "-c", _AVX2_PROBE],
        capture_output=True,
        text=True,
        check=True,
        env={**os.environ, "NUMBA_CPU_NAME": "haswell"},
    )
    return {
        "machine": machine(),
        "threads": threads,
        "velocity_ns_per_point_mode": t_vel / point_modes * 1e9,
        "velocity_ns_per_point_mode_one_thread": t_one / point_modes * 1e9,
        "velocity_ns_per_point_mode_compiled_for_avx2": json.loads(avx2.stdout)["ns"],
        "velocity_target_ns": 1.5,
        "velocity_and_acceleration_ns_per_point_mode": t_acc / point_modes * 1e9,
        "velocity_and_acceleration_target_ns": 2.5,
        "rk4_step_ms_2000_particles_200_modes": t_rk4 / steps * 1e3,
        "rk4_step_target_ms": 2.0,
        "peak_memory_mib_1e5_particles_300_modes": memory["peak_mib"],
        "memory_before_evaluation_mib": memory["baseline_mib"],
        "peak_memory_target_mib": 1024,
        "particles": p,
        "modes": field.n_modes,
    }
