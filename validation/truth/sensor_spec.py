"""What a scenario specifies for its sensor's readings, written apart from the simulator.

A pixel that expects μ photo-electrons (docs/imaging.md §4) collects k ~ Poisson(μ + b)
electrons, b the background, capped at the well, and reads
DN = clip(round(gain (k + r) + offset), 0, 2^B − 1) with read noise r ~ N(0, read²).
:func:`draw_spots` records isolated spots with that sensor in plain NumPy: the
reference that a measurement of the simulator's images is compared with.
"""

from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq
from scipy.stats import norm, poisson

from validation.truth.spot_fit import pixel_integrated

__all__ = [
    "SensorSpec",
    "background_moments",
    "background_pmf",
    "difference_mad_sigma",
    "draw_spots",
    "saturation_probability",
]


@dataclass(frozen=True)
class SensorSpec:
    """The sensor a scenario states (docs/imaging.md §4).

    Attributes
    ----------
    gain : float
        DN per e⁻.
    read_noise : float
        e⁻ rms.
    offset : float
        DN.
    full_well : float
        e⁻.
    bit_depth : int
        ADC bits.
    background : float
        Expected e⁻ per pixel besides the particles.
    """

    gain: float
    read_noise: float
    offset: float
    full_well: float
    bit_depth: int
    background: float

    @property
    def max_dn(self) -> int:
        """2^B − 1."""
        return 2**self.bit_depth - 1


def background_pmf(sensor: SensorSpec) -> np.ndarray:
    """Probability of each reading 0 … 2^B − 1 of a background pixel, shape (2^B,).

    Sums the reading's distribution: Poisson electrons (capped at the well) plus normal
    read noise, scaled, offset, rounded to the nearest DN and clipped to the ADC's range.
    """
    levels = np.arange(sensor.max_dn + 1, dtype=np.float64)
    if sensor.background > 0:
        lo, hi = poisson.ppf([1e-12, 1 - 1e-12], sensor.background)
        counts = np.arange(int(lo), int(hi) + 1)
        weights = poisson.pmf(counts, sensor.background)
    else:
        counts, weights = np.array([0]), np.array([1.0])
    counts = np.minimum(counts, np.floor(sensor.full_well))
    probability = np.zeros_like(levels)
    spread = max(sensor.gain * sensor.read_noise, 1e-12)
    for count, weight in zip(counts, weights, strict=True):
        mean = sensor.gain * count + sensor.offset
        upper = norm.cdf((levels + 0.5 - mean) / spread)
        lower = norm.cdf((levels - 0.5 - mean) / spread)
        upper[-1], lower[0] = 1.0, 0.0
        probability += weight * (upper - lower)
    return probability / probability.sum()


def background_moments(sensor: SensorSpec) -> tuple[float, float]:
    """Exact mean and standard deviation of a background pixel's reading, DN."""
    probability = background_pmf(sensor)
    levels = np.arange(probability.size, dtype=np.float64)
    mean = float(probability @ levels)
    return mean, float(np.sqrt(probability @ (levels - mean) ** 2))


def difference_mad_sigma(sensor: SensorSpec) -> float:
    """The σ a median-absolute-deviation estimate of adjacent-pixel differences gives on
    the exact background distribution, DN: Φ⁻¹(¾)⁻¹ · median|d| / √2.

    d = a − b of two independent readings is an integer; as an estimator that
    interpolates quantiles within unit bins sees it, each value v is spread evenly over
    [v − ½, v + ½]. The result differs from the readings' standard deviation by the
    shape of their distribution (Poisson electrons, rounding), not by chance.
    """
    probability = background_pmf(sensor)
    support = np.flatnonzero(probability > 1e-15)
    p = probability[support[0] : support[-1] + 1]
    d_pmf = np.convolve(p, p[::-1])
    values = np.arange(d_pmf.size) - (p.size - 1)

    def below(x: float) -> float:  # P(|d| ≤ x), d spread over unit bins
        overlap = np.clip(np.minimum(values + 0.5, x) - np.maximum(values - 0.5, -x), 0, 1)
        return float(d_pmf @ overlap)

    median = brentq(lambda x: below(x) - 0.5, 0.0, float(np.abs(values).max()) + 1.0)
    return median / norm.ppf(0.75) / np.sqrt(2.0)


def draw_spots(
    sigma: np.ndarray,
    electrons: np.ndarray,
    fraction: np.ndarray,
    sensor: SensorSpec,
    rng: np.random.Generator,
    *,
    half_width: int = 4,
) -> np.ndarray:
    """Record isolated spots as the specification says, in plain NumPy.

    Parameters
    ----------
    sigma, electrons : ndarray, shape (K,)
        σ (px) and photo-electrons of each spot.
    fraction : ndarray, shape (K, 2)
        Sub-pixel centre (x, y) relative to the window's middle pixel, px.
    sensor : SensorSpec
        The sensor.
    rng : numpy.random.Generator
        Shot and read noise.
    half_width : int
        Window half-side, px.

    Returns
    -------
    ndarray, shape (K, 2 half_width + 1, 2 half_width + 1)
        Readings, DN; the spot's centre is at (half_width + fraction) in each window's
        pixel coordinates.
    """
    size = 2 * half_width + 1
    pixels = np.broadcast_to(np.arange(size, dtype=np.float64), (len(sigma), size))
    centres = half_width + np.asarray(fraction, dtype=np.float64)
    gx, gy = (pixel_integrated(c, sigma, pixels) for c in centres.T)
    expected = electrons[:, None, None] * gy[:, :, None] * gx[:, None, :] + sensor.background
    count = np.minimum(rng.poisson(expected), np.floor(sensor.full_well))
    reading = sensor.gain * (count + rng.normal(0.0, sensor.read_noise, count.shape))
    return np.clip(np.rint(reading + sensor.offset), 0, sensor.max_dn)


def saturation_probability(
    expected: np.ndarray, sensor: SensorSpec, band: tuple[int, int]
) -> np.ndarray:
    """Probability that pixels read within a band of DN (both ends included).

    Parameters
    ----------
    expected : ndarray, shape (n,)
        Each pixel's expected photo-electrons μ (the background is added here).
    sensor : SensorSpec
        The sensor.
    band : (int, int)
        Lowest and highest reading of the band, DN (the ADC clips at 2^B − 1).

    Returns
    -------
    ndarray, shape (n,)
    """
    expected = np.asarray(expected, dtype=np.float64) + sensor.background
    out = np.zeros(expected.shape)
    spread = max(sensor.read_noise, 1e-12)
    low = (band[0] - 0.5 - sensor.offset) / sensor.gain
    high = np.inf if band[1] >= sensor.max_dn else (band[1] + 0.5 - sensor.offset) / sensor.gain
    well = np.floor(sensor.full_well)
    # A pixel that fills its well but for a chance below 1e-12 reads the full well.
    full = poisson.cdf(well - 1, expected) < 1e-12
    out[full] = norm.sf((low - well) / spread) - norm.sf((high - well) / spread)
    for n in np.flatnonzero(~full):
        mean = expected[n]
        lo, hi = poisson.ppf([1e-12, 1 - 1e-12], mean)
        counts = np.arange(int(lo), int(hi) + 1)
        collected = np.minimum(counts, well)
        inside = norm.sf((low - collected) / spread) - norm.sf((high - collected) / spread)
        out[n] = poisson.pmf(counts, mean) @ inside
    return out
