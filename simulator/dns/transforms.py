"""Pruned real 3-D FFTs for fields cut by the 2/3 rule (docs/dns.md §4).

A dealiased field is zero outside the modes with 3|n_i| < N on every axis, so a 3-D
transform need not act along the first two axes on the lines that hold only zeros (or
whose results the cut discards). Done one axis at a time with ``scipy.fft``, in place,
the inverse transform skips 5/9 of the lines along x and 1/3 along y, and the forward one
the same: about 30 % fewer operations than ``irfftn``/``rfftn``, with the same result to
round-off on the kept modes.
"""

import numpy as np
import scipy.fft

from simulator.dns.grid import Grid


class PrunedTransforms:
    """Inverse and forward transforms of (C, N, N, N//2 + 1) ↔ (C, N, N, N) fields.

    Parameters
    ----------
    grid : Grid
        The grid; the kept modes are those of its 2/3 rule.
    workers : int
        Threads of scipy.fft.
    """

    def __init__(self, grid: Grid, *, workers: int = 1) -> None:
        n = grid.n
        kept_y = int(np.sum(grid.kept()[1][: n // 2]))  # n_y = 0 … kept_y − 1 and their negatives
        self.n = n
        self.workers = workers
        self.kept_z = int(np.sum(grid.kept()[2]))  # n_z = 0 … kept_z − 1
        self.y_ranges = (slice(0, kept_y), slice(n - kept_y + 1, n))

    def inverse(self, fh: np.ndarray) -> np.ndarray:
        """Physical field of coefficients that are zero outside the kept modes.

        Parameters
        ----------
        fh : ndarray, shape (C, N, N, N//2 + 1), complex128
            Coefficients; overwritten (on n_z < kept) by the partial transforms.

        Returns
        -------
        ndarray, shape (C, N, N, N), float64
        """
        z = slice(0, self.kept_z)
        for y in self.y_ranges:
            self._in_place(scipy.fft.ifft, fh, (slice(None), slice(None), y, z), axis=1)
        self._in_place(scipy.fft.ifft, fh, (slice(None), slice(None), slice(None), z), axis=2)
        return scipy.fft.irfft(fh, n=self.n, axis=3, workers=self.workers)

    def forward(self, f: np.ndarray) -> np.ndarray:
        """Coefficients of a physical field, exact on the kept modes only.

        Parameters
        ----------
        f : ndarray, shape (C, N, N, N), float64

        Returns
        -------
        ndarray, shape (C, N, N, N//2 + 1), complex128
            rfftn(f) on the modes kept by the 2/3 rule; other entries hold partial sums
            and must be discarded (zeroed) by the caller.
        """
        fh = scipy.fft.rfft(f, axis=3, workers=self.workers)
        z = slice(0, self.kept_z)
        self._in_place(scipy.fft.fft, fh, (slice(None), slice(None), slice(None), z), axis=2)
        for y in self.y_ranges:
            self._in_place(scipy.fft.fft, fh, (slice(None), slice(None), y, z), axis=1)
        return fh

    def _in_place(self, transform, a: np.ndarray, where: tuple, *, axis: int) -> None:
        view = a[where]
        result = transform(view, axis=axis, overwrite_x=True, workers=self.workers)
        if not np.shares_memory(result, a):  # scipy.fft chose a copy: write it back
            view[...] = result
