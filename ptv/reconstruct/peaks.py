"""Peaks of a residual image: local maxima above a threshold, sub-pixel by 3-point fits.

A peak is a pixel above ``threshold`` and at least as bright as its 8 neighbours (ties
go to the first in raster order). Its sub-pixel centre along each axis is the 3-point
Gaussian estimate through the maximum and its two neighbours,
x̂ = i + [ln I₋ − ln I₊] / [2(ln I₋ − 2 ln I₀ + ln I₊)] (docs/imaging.md §5), or the
3-point parabola where a neighbour is not positive (a residual image has negative
pixels), clamped to ±½ px. Fast enough for residual images at every outer iteration of
the reconstruction: one pass over the image, compiled.
"""

from math import log

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def _offset(a, b, c):  # pragma: no cover (compiled)
    """Sub-pixel offset of the maximum b between a (at −1) and c (at +1)."""
    if a > 0.0 and c > 0.0 and b > 0.0:
        la = log(a)
        lb = log(b)
        lc = log(c)
        den = la - 2.0 * lb + lc
        if den < 0.0:
            return min(max(0.5 * (la - lc) / den, -0.5), 0.5)
    den = a - 2.0 * b + c
    if den < 0.0:
        return min(max(0.5 * (a - c) / den, -0.5), 0.5)
    return 0.0


@njit(cache=True, nogil=True)
def _find(image, rows, cols, threshold):  # pragma: no cover (compiled)
    n = 0
    cap = 1024
    xs = np.empty(cap)
    ys = np.empty(cap)
    vs = np.empty(cap)
    for j in range(1, rows - 1):
        for i in range(1, cols - 1):
            v = image[j, i]
            if v <= threshold:
                continue
            # strictly greater than the neighbours before it, >= those after it
            if (
                v <= image[j - 1, i - 1]
                or v <= image[j - 1, i]
                or v <= image[j - 1, i + 1]
                or v <= image[j, i - 1]
                or v < image[j, i + 1]
                or v < image[j + 1, i - 1]
                or v < image[j + 1, i]
                or v < image[j + 1, i + 1]
            ):
                continue
            if n == cap:
                cap *= 2
                xs2 = np.empty(cap)
                ys2 = np.empty(cap)
                vs2 = np.empty(cap)
                xs2[:n] = xs[:n]
                ys2[:n] = ys[:n]
                vs2[:n] = vs[:n]
                xs, ys, vs = xs2, ys2, vs2
            xs[n] = i + _offset(image[j, i - 1], v, image[j, i + 1])
            ys[n] = j + _offset(image[j - 1, i], v, image[j + 1, i])
            vs[n] = v
            n += 1
    return xs[:n].copy(), ys[:n].copy(), vs[:n].copy()


def find_peaks(
    image: np.ndarray, *, threshold: float, shape: tuple[int, int] | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Local maxima of an image above a threshold, with sub-pixel centres.

    Parameters
    ----------
    image : ndarray, shape (H, W), float64
        Image (e.g. a residual: recorded minus projected particles), image units.
    threshold : float
        Pixels at or below it are not peaks, image units.
    shape : (rows, cols), optional
        Only ``image[:rows, :cols]`` is searched (a padded stack of images).

    Returns
    -------
    xy : ndarray, shape (P, 2)
        Sub-pixel centres (x = column, y = row), px; the border pixels are never peaks.
    value : ndarray, shape (P,)
        The maximum pixel's value, image units.
    """
    img = np.asarray(image, dtype=np.float64)
    if img.ndim != 2:
        raise ValueError(f"image must be 2-D, got shape {img.shape}")
    rows, cols = img.shape if shape is None else shape
    x, y, v = _find(img, int(rows), int(cols), float(threshold))
    return np.column_stack([x, y]), v
