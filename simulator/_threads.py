"""Chunks of a compiled kernel spread over threads (private).

The kernels of RK4 trajectories and of the exact velocity derivatives take a range of
particle blocks, release the GIL (``nogil=True``) and are called here from
``numba.get_num_threads()`` threads, each with a contiguous range of blocks as numba's
static ``prange`` schedule gives them. As ``parallel=True`` functions they took 8.1 s to
compile on the 2-core development machine, 2.9 s now (benchmarks/bench_first_run.py),
for the same bits and the same speed. ``ptv/_threads.py`` is its twin (``simulator``
and ``ptv`` import nothing of each other).
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
