"""First calls of the numerical kernels: compiled (a fresh install) against cached.

The kernels are numba functions compiled at their first call and cached on disk. Each
measurement runs in a new Python process with its own ``NUMBA_CACHE_DIR``: ``cold``
in an empty one (every kernel compiles, as on a fresh install), then ``warm`` in the
same one (every kernel loads from the cache, as on later runs). The work is small
inputs through the public functions that ``synptv run`` calls, so that the same
kernels compile with the same argument types, without a run:

- ``flow``: RK4 trajectories and the exact velocity derivatives of a KS field;
- ``render``: a plate image through an oblique window, a particle image and its
  sensor noise;
- ``detect``: the particle detector on a dense 256 × 256 image (blends, so that the
  split stage runs);
- ``statistics``: the pair sums of one snapshot.

``run_kernels`` is all four in one process (numba's own start-up counted once): its
``cold_s − warm_s`` is what a fresh install adds to its first ``synptv run`` when it
runs in one process; with a worker per core, each worker compiles what it calls, at
the same time. Per group, ``compiled`` counts the functions compiled (numba's own
overloads included) and ``compile_s`` the seconds spent compiling; a warm process
compiles nothing. ``--quick`` measures ``run_kernels`` only.

Target (docs/performance.md): ``run_kernels`` cold in ≤ 60 s on the 2-core machine.
"""

import json
import os
import subprocess
import sys
import tempfile
import time

import numba
import numpy as np

from benchmarks.machine import machine

GROUPS = ("flow", "render", "detect", "statistics")
TARGET_S = 60.0

_CHILD = "from benchmarks.bench_first_run import child; child({groups!r})"


def _flow() -> None:
    from simulator.ks_field import draw_ks_field
    from simulator.particles import SHEET, integrate
    from simulator.presets import flow_preset
    from simulator.spectra import PopeSpectrum

    field = draw_ks_field(PopeSpectrum(flow_preset("lem-10hz").parameters), n_modes=50, rng=0)
    x = SHEET.sample(256, np.random.default_rng(1))
    integrate(field, x, np.array([0.0, 1e-4]), h_max=5e-5)
    field.derivatives(x, 0.0)


def _render() -> None:
    from benchmarks.bench_plate import _camera
    from simulator.render.plate import render_plate
    from simulator.target import REALISTIC, PlateDesign, build_plate, traverse_positions

    plate = build_plate(PlateDesign(), traverse_positions(), imperfections=REALISTIC, rng=0)
    render_plate(plate, _camera(), 6)
    _particle_image(np.random.default_rng(0), 100)


def _particle_image(rng: np.random.Generator, n: int) -> np.ndarray:
    """A 12-bit 256 × 256 image of n spots (σ 0.7–1 px, 800–8000 e⁻) with sensor noise."""
    from simulator.render import Sensor, render_particles

    xy = rng.uniform(3, 253, (n, 2))
    sigma = rng.uniform(0.7, 1.0, n)
    electrons = np.exp(rng.uniform(np.log(800), np.log(8000), n))
    image = render_particles(xy, sigma, electrons, shape=(256, 256)).image
    return Sensor(background=5.0).record(image, rng)


def _detect() -> None:
    from ptv.detect import detect_particles

    image = _particle_image(np.random.default_rng(0), 1300)  # 0.02 per pixel
    detect_particles(image)


def _statistics() -> None:
    from ptv.bins import LogBins
    from ptv.stats.pairs import pair_sums

    rng = np.random.default_rng(0)
    x = rng.uniform(-0.035, 0.035, (500, 3))
    pair_sums(x, rng.normal(size=(500, 6, 3)) * 1e-5, LogBins(5e-4, 0.035, 24))


_WORK = {"flow": _flow, "render": _render, "detect": _detect, "statistics": _statistics}


def child(groups: list[str]) -> None:
    """In the measuring process: run the groups' work, print seconds and compiles (JSON)."""
    from numba.core import event

    compiles, depth, spent = [0], [0], [0.0]
    began = [0.0]

    class Compiles(event.Listener):
        def on_start(self, ev: event.Event) -> None:
            """A compile starts (within another one: a function it calls)."""
            compiles[0] += 1
            depth[0] += 1
            if depth[0] == 1:
                began[0] = time.perf_counter()

        def on_end(self, ev: event.Event) -> None:
            """A compile ends."""
            depth[0] -= 1
            if depth[0] == 0:
                spent[0] += time.perf_counter() - began[0]

    event.register("numba:compile", Compiles())
    start = time.perf_counter()
    for group in groups:
        _WORK[group]()
    seconds = time.perf_counter() - start
    print(json.dumps({"seconds": seconds, "compiled": compiles[0], "compile_s": spent[0]}))


def _measure(groups: list[str]) -> dict:
    """Cold, then warm, in a fresh cache folder."""
    with tempfile.TemporaryDirectory(prefix="synptv-bench-cache-") as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache}
        runs = []
        for _ in ("cold", "warm"):
            out = subprocess.run(
                [sys.executable, "-c", _CHILD.format(groups=groups)],
                capture_output=True,
                text=True,
                check=True,
                env=env,
            )
            runs.append(json.loads(out.stdout.splitlines()[-1]))
    cold, warm = runs
    return {
        "cold_s": round(cold["seconds"], 1),
        "warm_s": round(warm["seconds"], 2),
        "compiled": cold["compiled"],
        "compile_s": round(cold["compile_s"], 1),
        "warm_compiled": warm["compiled"],
    }


def run(quick: bool) -> dict:
    """Cold and warm first calls per group (unless ``quick``) and of all together."""
    figures: dict = {"machine": machine(), "numba_threads": numba.config.NUMBA_NUM_THREADS}
    if not quick:
        figures["groups"] = {group: _measure([group]) for group in GROUPS}
    figures["run_kernels"] = _measure(list(GROUPS))
    figures["target_s"] = TARGET_S
    figures["meets_target"] = figures["run_kernels"]["cold_s"] <= TARGET_S
    return figures
