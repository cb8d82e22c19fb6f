"""Chunks of a compiled kernel spread over threads (private).

The kernels that loop over independent chunks (groups of detections, rows of the pair
loop) take a range of chunks, release the GIL (``nogil=True``) and are called here
from ``numba.get_num_threads()`` threads, each with a contiguous range of chunks as
numba's static ``prange`` schedule gives them. They were ``parallel=True`` functions,
which numba compiles much more slowly (the loop's body goes through its parallel
passes, and the call tree below it is optimised again into the parallel region): on
the 2-core development machine the detector's kernels took 53 s to compile and now
take 34 s, the pair sums 6.2 s and now 0.3 s (benchmarks/bench_first_run.py). The
results are the same bits (each chunk is computed alone, as before), and so is the
speed on one thread; on two threads with another process busy on one of the two cores,
numba's threads made detection 3.5× slower than one thread (76–83 against 22 ms per
2048 × 1088 image), these 1.2× (25.5 ms).
``simulator/_threads.py`` is its twin (``simulator`` and ``ptv`` import nothing of each
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
