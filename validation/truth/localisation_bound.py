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

This module shares no code with the detector it judges (``ptv.detect``) nor with the
renderer (``simulator.render``).
"""

import numpy as np
from scipy.special import erf

#: The sums run over the pixels within this many σ of the spot's centre pixel.
WINDOW_SIGMAS = 5.0


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
