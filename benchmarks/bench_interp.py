"""Spline interpolation of periodic spectral fields: prefilter and evaluation times.

For a 15-component field (u, ∇u and ∂u/∂t at the tracers) on 64³ and 128³ grids: the time
of :func:`simulator.dns.interpolate.spline_coefficients` (the spectral prefilter, one
inverse FFT per component) and of :func:`simulator.dns.interpolate.interpolate` at 10⁴ and
10⁵ random points spread over several periodic boxes, for the quintic spline (the default)
and the cubic one. Times are the median and the best of the repeats after a warm-up call
(numba compilation not counted); the machine is shared, so the median is the figure to
quote and the best shows the spread. The evaluation is also timed on one thread, and the
ordering of the points by cell (part of every evaluation) on its own.
"""

import time
from functools import partial

import numba
import numpy as np
import scipy.fft

from benchmarks.machine import machine
from simulator.dns import interp_kernels
from simulator.dns.interpolate import DEFAULT_ORDER, ORDERS, interpolate, spline_coefficients

COMPONENTS = 15
BOX = 2 * np.pi  # m


def _times(func, repeats: int) -> tuple[float, float]:
    """Median and best wall time of ``func()`` over ``repeats`` calls after a warm-up, s."""
    func()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        func()
        times.append(time.perf_counter() - start)
    return float(np.median(times)), min(times)


def _one_thread(func, repeats: int) -> float:
    threads = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        return _times(func, repeats)[0]
    finally:
        numba.set_num_threads(threads)


def run(quick: bool) -> dict:
    """Measure the interpolation figures; returns a JSON-able dict."""
    grids = (64,) if quick else (64, 128)
    counts = (10_000,) if quick else (10_000, 100_000)
    repeats = 3 if quick else 7
    rng = np.random.default_rng(0)
    figures = []
    for n in grids:
        field_hat = scipy.fft.rfftn(rng.standard_normal((COMPONENTS, n, n, n)), axes=(1, 2, 3))
        for order in ORDERS:
            prefilter = _times(partial(spline_coefficients, field_hat, order=order), repeats)
            coeffs = spline_coefficients(field_hat, order=order)
            for count in counts:
                points = rng.uniform(-BOX, 2 * BOX, (count, 3))
                evaluate = partial(interpolate, coeffs, BOX, points, order=order)
                median, best = _times(evaluate, repeats)
                one = _one_thread(evaluate, repeats)
                sort = _times(partial(interp_kernels.sort_order, points, n / BOX, n), repeats)[0]
                figures.append(
                    {
                        "grid": n,
                        "order": order,
                        "points": count,
                        "prefilter_ms_median": round(prefilter[0] * 1e3, 1),
                        "interpolate_ms_median": round(median * 1e3, 2),
                        "interpolate_ms_best": round(best * 1e3, 2),
                        "interpolate_ns_per_point_median": round(median / count * 1e9),
                        "interpolate_ns_per_point_one_thread": round(one / count * 1e9),
                        "sort_ns_per_point": round(sort / count * 1e9, 1),
                    }
                )
            del coeffs
    return {
        "machine": machine(),
        "threads": numba.get_num_threads(),
        "components": COMPONENTS,
        "default_order": DEFAULT_ORDER,
        "repeats": repeats,
        "figures": figures,
    }
