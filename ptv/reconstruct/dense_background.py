"""Background level and noise of a dense particle image, from its darkest pixels.

The median of an image at 0.05–0.16 particles per pixel lies well above the background
(most pixels carry some particle light), so the level is taken as the **mode** of the
pixel values, and the noise from the pixels below it, which particle light cannot
reach: for Gaussian noise of σ around the level μ, a fraction 0.3173 of the pixels
below μ lie below μ − σ. The histogram's peak is refined by a parabola through the log
counts of its three highest bins (a Gaussian peak), after smoothing over ±σ/2.
"""

import logging
from dataclasses import dataclass

import numpy as np

logger = logging.getLogger(__name__)

#: P(v < μ − σ | v < μ) for Gaussian noise.
_BELOW_ONE_SIGMA = 0.31731


@dataclass(frozen=True)
class BackgroundLevel:
    """Background of one image.

    Attributes
    ----------
    level : float
        Most frequent pixel value (the background without particles), image units.
    noise : float
        Its noise σ, image units, > 0.
    """

    level: float
    noise: float


def background_level(image: np.ndarray, *, max_samples: int = 1 << 18) -> BackgroundLevel:
    """Mode and noise of the pixel values of an image (module docstring).

    Parameters
    ----------
    image : ndarray, shape (H, W)
        Camera image, integers (DN) or floats, finite.
    max_samples : int
        Pixels used at most (a regular subsample of the image), >= 1000.

    Returns
    -------
    BackgroundLevel

    Raises
    ------
    ValueError
        Not a finite, non-empty 2-D image.
    """
    img = np.asarray(image)
    if img.ndim != 2 or img.size == 0 or not np.issubdtype(img.dtype, np.number):
        raise ValueError(f"image must be a non-empty 2-D numeric array, got shape {img.shape}")
    step = max(1, int(np.ceil(img.size / max(int(max_samples), 1000))))
    v = img.reshape(-1)[::step].astype(np.float64)
    if not np.isfinite(v).all():
        raise ValueError("image has NaN or infinite pixels")
    lo, mid = np.percentile(v, [0.1, 50.0])
    if mid <= lo:  # more than half the pixels at one value: no measurable noise
        return BackgroundLevel(level=float(mid), noise=1e-12)
    # first guess of σ from the darkest pixels, then a histogram around the mode
    sigma0 = max((mid - lo) / 3.0, 1e-9)
    quantum = _quantum(v)
    if quantum > 0:  # values on a lattice (DN, perhaps offset or scaled): whole steps
        width = quantum * max(1.0, np.floor(sigma0 / (4.0 * quantum)))
        start = lo - quantum / 2
    else:
        width = sigma0 / 8.0
        start = lo - width / 2
    edges = np.arange(start, mid + 3 * sigma0 + width, width)
    counts, edges = np.histogram(v, bins=edges)
    smooth = max(1, round(0.5 * sigma0 / width))
    kernel = np.ones(2 * smooth + 1) / (2 * smooth + 1)
    c = np.convolve(counts.astype(float), kernel, mode="same")
    centres = 0.5 * (edges[1:] + edges[:-1])
    k = int(np.argmax(np.where(centres <= mid + 0.5 * width, c, -1.0)))
    level = float(centres[k])
    if 0 < k < len(c) - 1 and np.all(c[k - 1 : k + 2] > 0):
        a, b, d = np.log(c[k - 1 : k + 2])
        curv = a - 2 * b + d
        if curv < 0:
            level += float(np.clip(0.5 * (a - d) / curv, -0.5, 0.5)) * width
    # the CDF with each bin's values spread uniformly over it (integers: over ±½)
    cumulative = np.concatenate([[np.count_nonzero(v < edges[0])], counts]).cumsum()
    below = float(np.interp(level, edges, cumulative))
    noise = level - float(np.interp(_BELOW_ONE_SIGMA * below, cumulative, edges))
    logger.debug("background level %.3f, noise %.3f", level, noise)
    return BackgroundLevel(level=level, noise=max(noise, 1e-12))


def _quantum(v: np.ndarray) -> float:
    """Step of the lattice the values lie on (DN: 1), or 0 for continuous values."""
    u = np.unique(v)
    if u.size < 3:
        return 0.0
    d = np.diff(u)
    q = float(d.min())
    ratio = d / q
    if q > 0 and np.all(np.abs(ratio - np.round(ratio)) < 1e-6 * ratio + 1e-9):
        return q
    return 0.0
