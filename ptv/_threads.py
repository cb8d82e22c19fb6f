"""Chunks of a compiled kernel spread over threads (private).

The kernels that loop over independent chunks (groups of detections, rows of the pair
loop) take a range of chunks, release the GIL (``nogil=True``) and are called here
from ``numba.get_num_threads()`` threads, each with a contiguous range of chunks as
numba's static ``prange`` schedule gives them. They were ``parallel=True`` functions:
numba compiles such a function's whole call tree a second and third time (once into
its parallel region, once into the function), so they took 45 of the 77 s that the
detector's kernels took to compile on the 2-core development machine
(benchmarks/bench_first_run.py); the results are the same bits, each chunk being
computed alone as before. ``simulator/_threads.py`` is its twin (``simulator`` and
``ptv`` import nothing of each other).
"""

from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from itertools import pairwise

import numba


def over_threads(kernel: Callable, n_chunks: int, *args: object) -> None:
    """Run ``kernel(first, stop, *args)`` over chunks ``0 … n_chunks − 1``.

    Parameters
    ----------
    kernel : callable
        A compiled ``nogil`` function doing chunks ``first … stop − 1``; chunks must
        write disjoint outputs.
    n_chunks : int
        Number of chunks.
    *args
        The kernel's other arguments, the same for every chunk.
    """
    threads = max(1, min(numba.get_num_threads(), n_chunks))
    bounds = [n_chunks * t // threads for t in range(threads + 1)]
    if threads == 1:
        kernel(0, n_chunks, *args)
        return
    with ThreadPoolExecutor(threads) as pool:
        done = [pool.submit(kernel, first, stop, *args) for first, stop in pairwise(bounds)]
        for future in done:
            future.result()
