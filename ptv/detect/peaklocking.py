"""Peak-locking diagnostic: are the fractional parts of the positions uniform?

For randomly placed particles the fractional part u = x − ⌊x + ½⌋ ∈ [−½, ½) of an
unbiased position estimate is uniform. A sub-pixel estimator with the periodic bias
x̂ − x = −a sin 2πx (PHYSICS.md §8) piles estimates up at pixel centres (a > 0). Two
tests per axis:

- the first Fourier harmonic (Rayleigh test): C = mean cos 2πu, S = mean sin 2πu,
  R = √(C² + S²); under uniformity 2N R² is χ²₂, and Zar's form of the p-value is used.
  For a small sinusoidal bias the density of u is 1 + 2πa cos 2πu, so C ≈ π a and
  ``amplitude`` = C / π estimates a in px (> 0: pulled to pixel centres, < 0: to edges);
- Pearson's χ² of the histogram against a flat one (``bins`` − 1 degrees of freedom),
  which also sees higher harmonics.

Detections from many images can be pooled: the tests gain power as √N, so a bias of
0.005 px needs ~3·10⁴ positions to be seen at p = 10⁻³ while 0.05 px needs ~300.
"""

import logging
from dataclasses import dataclass

import numpy as np
from scipy import stats

from ptv.detect.detections import Detections

logger = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False)
class PeakLocking:
    """Histograms of the fractional positions and their uniformity statistics.

    Parameters
    ----------
    edges : ndarray, shape (B + 1,), float64
        Bin edges of the fractional position, px, from −0.5 to 0.5 (pixel centre at 0).
    counts : ndarray, shape (2, B), int64
        Histograms of frac(x) (row 0) and frac(y) (row 1).
    amplitude : ndarray, shape (2,), float64
        Estimated sinusoidal bias amplitude a = mean(cos 2πu) / π for x and y, px.
    harmonic : ndarray, shape (2,), float64
        First-harmonic amplitude R = |mean exp(2πiu)| for x and y, in [0, 1].
    p_harmonic : ndarray, shape (2,), float64
        Rayleigh-test p-values for x and y (small: not uniform).
    p_chi2 : ndarray, shape (2,), float64
        χ² goodness-of-fit p-values of the histograms for x and y.
    n : int
        Number of positions.
    """

    edges: np.ndarray
    counts: np.ndarray
    amplitude: np.ndarray
    harmonic: np.ndarray
    p_harmonic: np.ndarray
    p_chi2: np.ndarray
    n: int

    @property
    def p_value(self) -> float:
        """Smallest of the four p-values, Bonferroni-corrected (× 4, at most 1)."""
        return float(min(1.0, 4.0 * min(self.p_harmonic.min(), self.p_chi2.min())))

    def locked(self, alpha: float = 1e-3) -> bool:
        """True when uniformity is rejected at level ``alpha`` (after correction)."""
        return self.p_value < alpha


def _rayleigh_p(n: int, r: float) -> float:
    """Rayleigh test p-value for n angles with mean resultant length r (Zar 1999)."""
    rn = n * r
    log_p = np.sqrt(1.0 + 4.0 * n + 4.0 * (n * n - rn * rn)) - (1.0 + 2.0 * n)
    return float(min(1.0, np.exp(log_p)))


def peak_locking(positions: Detections | object, *, bins: int = 10) -> PeakLocking:
    """Histogram the fractional parts of positions and test them for uniformity.

    Parameters
    ----------
    positions : Detections or array_like, shape (N, 2)
        Sub-pixel positions (x, y), px; N >= 1, finite.
    bins : int
        Histogram bins over one pixel, >= 2.

    Returns
    -------
    PeakLocking

    Raises
    ------
    ValueError
        Wrong shape, no positions, non-finite values or bad ``bins``.
    """
    xy = positions.xy if isinstance(positions, Detections) else np.asarray(positions)
    if xy.ndim != 2 or xy.shape[1] != 2:
        raise ValueError(f"positions must have shape (N, 2), got {xy.shape}")
    if xy.shape[0] == 0:
        raise ValueError("positions is empty: need at least one (x, y) to test")
    if not (np.issubdtype(xy.dtype, np.number) and np.isfinite(xy).all()):
        raise ValueError("positions must be finite real numbers")
    if not isinstance(bins, int | np.integer) or isinstance(bins, bool) or bins < 2:
        raise ValueError(f"bins must be an integer >= 2, got {bins!r}")
    xy = xy.astype(np.float64)
    n = xy.shape[0]
    frac = xy - np.floor(xy + 0.5)
    edges = np.linspace(-0.5, 0.5, bins + 1)
    idx = np.minimum(((frac + 0.5) * bins).astype(np.int64), bins - 1)
    counts = np.stack([np.bincount(idx[:, a], minlength=bins) for a in range(2)])
    phase = 2.0 * np.pi * frac
    c = np.cos(phase).mean(axis=0)
    s = np.sin(phase).mean(axis=0)
    r = np.hypot(c, s)
    p_h = np.array([_rayleigh_p(n, float(v)) for v in r])
    expected = n / bins
    chi2 = ((counts - expected) ** 2 / expected).sum(axis=1)
    p_c = stats.chi2.sf(chi2, bins - 1)
    result = PeakLocking(
        edges=edges,
        counts=counts,
        amplitude=c / np.pi,
        harmonic=r,
        p_harmonic=p_h,
        p_chi2=np.asarray(p_c, dtype=np.float64),
        n=n,
    )
    logger.debug(
        "peak locking over %d positions: amplitude %s px, p = %.3g",
        n,
        np.array2string(result.amplitude, precision=4),
        result.p_value,
    )
    return result
