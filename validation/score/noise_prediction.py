"""The noise terms of the multi-Δt fit predicted from the noise measured against the
truth: what c2 should be, for the checks of a run (docs/claims.md §4, ``c2``)."""

from dataclasses import dataclass

import numpy as np

from ptv.bins import LogBins
from validation.score.tolerances import float_array


def direction_moments(bins: LogBins, box_size, *, points: int = 3000, rng: int = 0) -> np.ndarray:
    """⟨r̂_i²⟩ of the pairs of uniform points in a box, per separation bin.

    Parameters
    ----------
    bins : LogBins
        Separation bins.
    box_size : sequence of 3 floats
        The analysis box, m.
    points : int
        Monte Carlo points (pairs: points²/2).
    rng : int
        Seed.

    Returns
    -------
    ndarray, shape (B, 3)
        Mean squared direction cosines (rows sum to 1; NaN in empty bins).
    """
    x = np.random.default_rng(rng).uniform(-0.5, 0.5, (points, 3)) * np.asarray(box_size)
    sums = np.zeros((bins.n_bins, 3))
    count = np.zeros(bins.n_bins)
    edges = bins.edges
    for i in range(points - 1):
        d = x[i + 1 :] - x[i]
        r = np.linalg.norm(d, axis=1)
        b = np.searchsorted(edges, r) - 1
        ok = (b >= 0) & (b < bins.n_bins)
        for i_comp in range(3):
            cos2 = (d[ok, i_comp] / r[ok]) ** 2
            sums[:, i_comp] += np.bincount(b[ok], weights=cos2, minlength=bins.n_bins)
        count += np.bincount(b[ok], minlength=bins.n_bins)
    with np.errstate(invalid="ignore"):
        return sums / count[:, None]


@dataclass(frozen=True)
class NoisePrediction:
    """The noise terms of the multi-Δt fit predicted from the measured displacement noise.

    For two particles with independent noise, ⟨((Δb_j − Δb_i)·e)²⟩ = 2 Σ_i σ_ΔX,i²
    ⟨e_i²⟩(r), with the direction moments ⟨e_i²⟩ of the pairs in the analysis box
    (:func:`direction_moments`) and σ_ΔX,i²(Δt) the displacement-noise variance measured
    against the truth. For white noise σ_ΔX² is constant and
    c2 = 2 Σ σ_ΔX,i² ⟨e_i²⟩ (4σ² for isotropic noise). On rendered images part of the
    detection error is common to frames a and b (mostly the light of an unresolved
    neighbour, which moves with respect to the particle), so σ_ΔX² grows with Δt,
    concavely in Δt²: the intercept a fit
    finds then depends on how it weighs the Δt values, between that of the line through
    the two smallest Δt and that of the least-squares line through all.

    Where the truth gives the errors of the particles themselves, ⟨((Δb_j − Δb_i)·e)²⟩
    is summed over their actual pairs instead (:mod:`validation.truth.pair_noise`): on
    dense images the noisier particles (overlapped by a neighbour) and the errors shared
    by blended neighbours are not spread evenly over the separations. The lines are then
    fitted per bin.

    Attributes
    ----------
    c2 : ndarray, shape (B,)
        From the least-squares line σ_ΔX² = n0 + n1·Δt² through every Δt (or that of the
        pair noise), m².
    c2_low : ndarray, shape (B,)
        From the line through the two smallest Δt (≤ ``c2``), m².
    c1_noise : ndarray, shape (B,)
        2 Σ n1_i ⟨e_i²⟩: the part of the noise that grows as Δt², which the fit adds to
        c1, m²/s².
    """

    c2: np.ndarray
    c2_low: np.ndarray
    c1_noise: np.ndarray


def _intercept_and_slope(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares line y = n0 + n1·x per column of y (K, 3)."""
    design = np.stack([np.ones_like(x), x], axis=1)
    (n0, n1), *_ = np.linalg.lstsq(design, y, rcond=None)
    return n0, n1


def predicted_noise(detection: dict, bins: LogBins, box_size) -> NoisePrediction:
    """The noise terms of the fit from ``detection.json`` (:class:`NoisePrediction`).

    Parameters
    ----------
    detection : dict
        ``dt`` (K,), s, and either ``pair_noise_m2`` (K, B), m², the noise term over the
        actual pairs (:mod:`validation.truth.pair_noise`), used where present, or
        ``displacement_noise_m`` (K, 3), m, with the direction moments of uniform pairs
        in the box.
    bins : LogBins
        Separation bins.
    box_size : sequence of 3 floats
        The analysis box, m.
    """
    x = np.asarray(detection["dt"], dtype=float) ** 2
    if detection.get("pair_noise_m2") is not None:
        per_pair = np.array([float_array(row) for row in detection["pair_noise_m2"]])
        c2, c2_low, c1_noise = _noise_lines(x, per_pair)
    else:
        variance = np.asarray(detection["displacement_noise_m"], dtype=float) ** 2
        to_bins = 2.0 * direction_moments(bins, box_size)
        c2, c2_low, c1_noise = (to_bins @ v for v in _noise_lines(x, variance))
    return NoisePrediction(c2, np.minimum(c2_low, c2), c1_noise)


def _noise_lines(x: np.ndarray, noise: np.ndarray) -> tuple[np.ndarray, ...]:
    """Intercept, intercept of the line through the two smallest Δt, and slope of the
    lines through each column of ``noise`` (K, M) against Δt² (``x``, K); NaN where a
    column holds a NaN. A single Δt gives its value, twice, and slope 0."""
    finite = np.isfinite(noise).all(axis=0)
    filled = np.where(np.isfinite(noise), noise, 0.0)
    if x.size < 2:
        constant = np.where(finite, filled.mean(axis=0), np.nan)
        return constant, constant, np.zeros_like(constant)
    n0, n1 = _intercept_and_slope(x, filled)
    n0_low, _ = _intercept_and_slope(x[:2], filled[:2])
    return tuple(np.where(finite, v, np.nan) for v in (n0, n0_low, n1))


