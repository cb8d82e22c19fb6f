"""Log-spaced separation bins, and how a pair's separation is taken for its bin
(:mod:`ptv.stats.pairs` bins the pairs; the statistics' settings,
:class:`ptv.settings.StatisticsSettings`, name the bins)."""

from dataclasses import dataclass

import numpy as np

#: How a pair's separation is taken: at t ("start") or by the chord midpoint of t and
#: t + Δt ("midpoint", :mod:`ptv.stats.pairs`).
BINNINGS = ("start", "midpoint")


@dataclass(frozen=True)
class LogBins:
    """Logarithmically spaced separation bins.

    Parameters
    ----------
    r_min, r_max : float
        Outer edges, m, 0 < r_min < r_max.
    n_bins : int
        Number of bins ≥ 1.

    Examples
    --------
    >>> import ptv
    >>> bins = ptv.LogBins(r_min=1e-3, r_max=16e-3, n_bins=4)
    >>> bins.edges  # m
    array([0.001, 0.002, 0.004, 0.008, 0.016])
    >>> bins.centres.round(6)  # geometric, m
    array([0.001414, 0.002828, 0.005657, 0.011314])
    """

    r_min: float
    r_max: float
    n_bins: int

    def __post_init__(self) -> None:
        if not (0 < self.r_min < self.r_max < np.inf):
            raise ValueError(f"need 0 < r_min < r_max, got r_min={self.r_min}, r_max={self.r_max}")
        if not isinstance(self.n_bins, int | np.integer) or self.n_bins < 1:
            raise ValueError(f"n_bins must be an integer >= 1, got {self.n_bins!r}")

    @property
    def edges(self) -> np.ndarray:
        """Bin edges, shape (n_bins + 1,), m."""
        return np.geomspace(self.r_min, self.r_max, self.n_bins + 1)

    @property
    def centres(self) -> np.ndarray:
        """Geometric bin centres, shape (n_bins,), m."""
        e = self.edges
        return np.sqrt(e[1:] * e[:-1])
