"""The Cramér–Rao bound on locating a particle image, in plain NumPy.

A spot is the pixel-integrated Gaussian of σ (px) holding N expected photo-electrons
(docs/imaging.md); pixel (i, j) collects

    μ_ij = N · g_x(i) · g_y(j),   g_x(i) = ½[erf((i + ½ − x)/(√2σ)) − erf((i − ½ − x)/(√2σ))],

and records it with Poisson shot noise plus read noise of variance b² (e⁻²). With the
Gaussian approximation of that noise (variance μ_ij + b²), the Fisher information of
the centre's x is

    I_x = Σ_ij (∂μ_ij/∂x)² / (μ_ij + b²),

and no unbiased estimator of x has a variance below 1/I_x (likewise y). An unweighted
least-squares Gaussian fit reaches 16/9 of this variance in the photon-limited case
and close to the bound where read noise dominates (Mortensen et al. 2010), so its
RMS error should lie within 4/3 of the bound's.

Where a spot lies between those limits, and at the few hundred photo-electrons of a
dim tracer where the fit is not yet in its asymptotic regime, the error an unweighted
least-squares Gaussian actually reaches is measured by :func:`least_squares_errors`:
spots of the same σ, photo-electrons and sub-pixel centre drawn as the sensor specifies
(:func:`validation.truth.sensor_spec.draw_spots`) and fitted with a background and a
pixel-integrated Gaussian over the detector's 5 × 5 window
(:func:`validation.truth.spot_fit.fit_windows`).

This module shares no code with the detector it judges (``ptv.detect``) nor with the
renderer (``simulator.render``).
"""

import numpy as np
from scipy.special import erf

from validation.truth.sensor_spec import SensorSpec, draw_spots
from validation.truth.spot_fit import fit_windows

#: The sums run over the pixels within this many σ of the spot's centre pixel.
WINDOW_SIGMAS = 5.0
#: Half-side of the window a least-squares fit of :func:`least_squares_errors` sees, px
#: (the detector's 5 × 5 window, docs/imaging.md §5).
FIT_HALF_WIDTH = 2


def _axis_profile(
    centre: np.ndarray, sigma: np.ndarray, half_window: int
) -> tuple[np.ndarray, np.ndarray]:
    """Pixel fractions g and their derivatives dg/dcentre along one axis.

    Parameters
    ----------
    centre : ndarray, shape (P,)
        Spot centre, px.
    sigma : ndarray, shape (P,)
        Gaussian σ, px.
    half_window : int
        Pixels summed on each side of the centre pixel.

    Returns
    -------
    g, dg : ndarray, shape (P, 2·half_window + 1)
        Over the pixels round(centre) − half_window … round(centre) + half_window.
    """
    pixels = np.round(centre)[:, None] + np.arange(-half_window, half_window + 1)
    s = np.sqrt(2.0) * sigma[:, None]
    upper = (pixels + 0.5 - centre[:, None]) / s
    lower = (pixels - 0.5 - centre[:, None]) / s
    g = 0.5 * (erf(upper) - erf(lower))
    dg = -(np.exp(-(upper**2)) - np.exp(-(lower**2))) / (np.sqrt(np.pi) * s)
    return g, dg


def localisation_bound(
    xy: np.ndarray, sigma: np.ndarray, electrons: np.ndarray, read_noise: float
) -> np.ndarray:
    """Cramér–Rao standard deviations of the x and y centre of each spot.

    Parameters
    ----------
    xy : ndarray, shape (P, 2)
        Exact spot centres, px.
    sigma : ndarray, shape (P,)
        Gaussian σ of each spot, px.
    electrons : ndarray, shape (P,)
        Expected photo-electrons of each spot, e⁻.
    read_noise : float
        Noise per pixel without signal (read noise and background shot noise), e⁻ rms.

    Returns
    -------
    ndarray, shape (P, 2)
        √(1/I_x), √(1/I_y), px.
    """
    xy = np.asarray(xy, dtype=float)
    sigma = np.asarray(sigma, dtype=float)
    electrons = np.asarray(electrons, dtype=float)
    half_window = int(np.ceil(WINDOW_SIGMAS * sigma.max())) if len(sigma) else 0
    gx, dgx = _axis_profile(xy[:, 0], sigma, half_window)
    gy, dgy = _axis_profile(xy[:, 1], sigma, half_window)
    n = electrons[:, None, None]
    mu = n * gy[:, :, None] * gx[:, None, :]
    variance = mu + read_noise**2
    info_x = np.sum((n * gy[:, :, None] * dgx[:, None, :]) ** 2 / variance, axis=(1, 2))
    info_y = np.sum((n * dgy[:, :, None] * gx[:, None, :]) ** 2 / variance, axis=(1, 2))
    return np.column_stack([1.0 / np.sqrt(info_x), 1.0 / np.sqrt(info_y)])


def least_squares_errors(
    sigma: np.ndarray,
    electrons: np.ndarray,
    fraction: np.ndarray,
    sensor: SensorSpec,
    rng: np.random.Generator,
    *,
    draws: int = 1,
) -> np.ndarray:
    """Errors of an unweighted least-squares Gaussian fit on spots drawn like the given.

    Each spot is drawn ``draws`` times in plain NumPy as the sensor specifies (Poisson
    electrons, read noise, gain, rounding, clipping) at its σ, photo-electrons and
    sub-pixel centre, and fitted over a (2·:data:`FIT_HALF_WIDTH` + 1)² window about its
    centre pixel with a constant background plus a pixel-integrated Gaussian (centre, σ,
    amount free): the estimator the detector's refinement is, without its code.

    Parameters
    ----------
    sigma, electrons : ndarray, shape (P,)
        Gaussian σ (px) and expected photo-electrons of each spot.
    fraction : ndarray, shape (P, 2)
        Sub-pixel centre (x, y) relative to the spot's nearest pixel, in [−½, ½), px.
    sensor : SensorSpec
        The sensor the scenario states.
    rng : numpy.random.Generator
        Shot and read noise of the draws.
    draws : int
        Draws per spot, ≥ 1.

    Returns
    -------
    ndarray, shape (P·draws, 2)
        Fitted − true centre (x, y) of every draw, px; spot p's draws are rows
        p·draws … (p + 1)·draws − 1.
    """
    if not isinstance(draws, int | np.integer) or draws < 1:
        raise ValueError(f"draws must be an integer >= 1, got {draws!r}")
    sigma = np.repeat(np.asarray(sigma, dtype=float), draws)
    electrons = np.repeat(np.asarray(electrons, dtype=float), draws)
    fraction = np.repeat(np.asarray(fraction, dtype=float).reshape(-1, 2), draws, axis=0)
    windows = draw_spots(sigma, electrons, fraction, sensor, rng, half_width=FIT_HALF_WIDTH)
    fits = fit_windows(windows, np.zeros((len(sigma), 2), dtype=np.int64))
    return fits.xy - (FIT_HALF_WIDTH + fraction)
