"""Chunks of a compiled kernel spread over threads (private).

The kernel of RK4 trajectories takes a range of particle blocks, releases the GIL
(``nogil=True``) and is called here from ``numba.get_num_threads()`` threads, each with
a contiguous range of blocks as numba's static ``prange`` schedule gives them. As a
``parallel=True`` function it took three times as long to compile (numba compiles the
loop's body a second time into its parallel region), for the same bits and the same
speed. ``ptv/_threads.py`` is its twin (``simulator`` and ``ptv`` import nothing of each
other).
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
