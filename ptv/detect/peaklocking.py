"""Peak-locking diagnostic: are the fractional parts of the positions uniform?

For randomly placed particles the fractional part u = x − ⌊x + ½⌋ ∈ [−½, ½) of an
unbiased position estimate is uniform. A sub-pixel estimator with the periodic bias
x̂ − x = −a sin 2πx (docs/imaging.md §6) piles estimates up at pixel centres (a > 0). Two
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


@dataclass(frozen=True, eq=False)
class FractionSums:
    """What the uniformity tests need of a set of positions: sums that pool by addition.

    Detections of many images (or of chunks computed apart) are tested together by
    adding their sums, without keeping their positions.

    Parameters
    ----------
    counts : ndarray, shape (2, B), int64
        Histograms of frac(x) and frac(y) over B bins from −½ to ½ px.
    sum_cos, sum_sin : ndarray, shape (2,), float64
        Σ cos 2πu and Σ sin 2πu for x and y.
    n : int
        Number of positions.
    """

    counts: np.ndarray
    sum_cos: np.ndarray
    sum_sin: np.ndarray
    n: int

    @classmethod
    def of(cls, positions: Detections | object, *, bins: int = 10) -> "FractionSums":
        """The sums of positions (N, 2), px (or of Detections); N may be 0.

        Raises
        ------
        ValueError
            Wrong shape, non-finite values or bad ``bins``.
        """
        xy = positions.xy if isinstance(positions, Detections) else np.asarray(positions)
        if xy.ndim != 2 or xy.shape[1] != 2:
            raise ValueError(f"positions must have shape (N, 2), got {xy.shape}")
        if not (np.issubdtype(xy.dtype, np.number) and np.isfinite(xy).all()):
            raise ValueError("positions must be finite real numbers")
        if not isinstance(bins, int | np.integer) or isinstance(bins, bool) or bins < 2:
            raise ValueError(f"bins must be an integer >= 2, got {bins!r}")
        frac = xy.astype(np.float64) - np.floor(xy + 0.5)
        idx = np.minimum(((frac + 0.5) * bins).astype(np.int64), bins - 1)
        counts = np.stack([np.bincount(idx[:, a], minlength=bins) for a in range(2)])
        phase = 2.0 * np.pi * frac
        return cls(counts, np.cos(phase).sum(axis=0), np.sin(phase).sum(axis=0), len(xy))

    def __add__(self, other: "FractionSums") -> "FractionSums":
        if self.counts.shape != other.counts.shape:
            raise ValueError("cannot add fraction sums of different bins")
        return FractionSums(
            self.counts + other.counts,
            self.sum_cos + other.sum_cos,
            self.sum_sin + other.sum_sin,
            self.n + other.n,
        )


def peak_locking(positions: Detections | object, *, bins: int = 10) -> PeakLocking:
    """Histogram the fractional parts of positions and test them for uniformity.

    Parameters
    ----------
    positions : Detections, array_like (N, 2) or FractionSums
        Sub-pixel positions (x, y), px; N >= 1, finite. Or the pooled sums of several
        sets of positions (then ``bins`` is theirs).
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
    sums = (
        positions if isinstance(positions, FractionSums) else FractionSums.of(positions, bins=bins)
    )
    n = sums.n
    if n == 0:
        raise ValueError("positions is empty: need at least one (x, y) to test")
    bins = sums.counts.shape[1]
    edges = np.linspace(-0.5, 0.5, bins + 1)
    c, s = sums.sum_cos / n, sums.sum_sin / n
    r = np.hypot(c, s)
    p_h = np.array([_rayleigh_p(n, float(v)) for v in r])
    expected = n / bins
    chi2 = ((sums.counts - expected) ** 2 / expected).sum(axis=1)
    p_c = stats.chi2.sf(chi2, bins - 1)
    result = PeakLocking(
        edges=edges,
        counts=sums.counts,
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
