"""The Cramér–Rao bound on locating particle images among their neighbours.

:mod:`validation.truth.localisation_bound` bounds an isolated spot of known brightness
and width. On a dense image a spot's light mixes with its neighbours', and a detector
knows neither their brightness nor their width nor the background: the bound here
treats all of them as unknowns. Every spot is the pixel-integrated Gaussian

    μ_k(i, j) = N_k · g(i; x_k, σ_k) · g(j; y_k, σ_k),
    g(i; c, s) = ½[erf((i + ½ − c)/(√2 s)) − erf((i − ½ − c)/(√2 s))],

and a pixel records the sum over spots plus a background b (e⁻), with Poisson shot
noise and read noise r (variance Σ_k μ_k + b + r² in the Gaussian approximation).

For each spot, the Fisher information is summed over the pixels of a window of
(2H + 1)² pixels around it (H = :data:`HALF_WINDOW`), with the parameters
θ = (x_k, y_k, N_k, σ_k for every spot centred in the window; b):

    F = Σ_pixels (∂μ/∂θ)(∂μ/∂θ)ᵀ / (μ + r²),

and no unbiased estimator of its centre has a variance below [F⁻¹]_xx + [F⁻¹]_yy.
Spots centred outside the window but shining into it are taken as known (their light
adds to μ and to the noise): knowing them can only lower the bound, so it stays a
bound. Counted as known, too, is how many spots there are, which a detector must find
out. The window leaves out pixels farther than H px from the spot, which see it only
through its neighbours; at H = 7 and σ ≤ 1 px that changes the bound by far less than
its use needs.

This module shares no code with the detector it judges (``ptv.detect``).
"""

import numpy as np
from scipy.spatial import cKDTree
from scipy.special import erf

#: Half-width H of the window summed around each spot, px.
HALF_WINDOW = 7


def _profiles(
    centres: np.ndarray, sigmas: np.ndarray, first: int, count: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pixel fractions g of spots along one axis and their derivatives by centre and σ.

    Parameters
    ----------
    centres, sigmas : ndarray, shape (K,)
        Spot centres and Gaussian σ, px.
    first, count : int
        The pixels first … first + count − 1.

    Returns
    -------
    g, dg_dcentre, dg_dsigma : ndarray, shape (K, count)
    """
    edges = first - 0.5 + np.arange(count + 1)
    scale = np.sqrt(2.0) * sigmas[:, None]
    u = (edges - centres[:, None]) / scale
    cdf = 0.5 * erf(u)
    pdf = np.exp(-(u**2)) / (np.sqrt(np.pi) * scale)  # the Gaussian's density at each edge
    g = np.diff(cdf, axis=1)
    dg_dcentre = -np.diff(pdf, axis=1)
    dg_dsigma = -np.diff(pdf * (edges - centres[:, None]), axis=1) / sigmas[:, None]
    return g, dg_dcentre, dg_dsigma


def crowded_localisation_bound(
    xy: np.ndarray,
    sigma: np.ndarray,
    electrons: np.ndarray,
    background: float,
    read_noise: float,
    shape: tuple[int, int],
) -> np.ndarray:
    """Cramér–Rao rms error of each spot's centre with its neighbours' light.

    Parameters
    ----------
    xy : ndarray, shape (P, 2)
        Exact spot centres (x = column, y = row), px.
    sigma : ndarray, shape (P,)
        Gaussian σ of each spot, px.
    electrons : ndarray, shape (P,)
        Expected photo-electrons of each spot, e⁻.
    background : float
        Expected background per pixel, e⁻ (shot noise included).
    read_noise : float
        Read noise per pixel, e⁻ rms.
    shape : (int, int)
        Image rows and columns: pixels off the image are not summed.

    Returns
    -------
    ndarray, shape (P,)
        √([F⁻¹]_xx + [F⁻¹]_yy) of each spot, px (module docstring); inf where the
        information matrix is singular.
    """
    xy = np.asarray(xy, dtype=float)
    sigma = np.asarray(sigma, dtype=float)
    electrons = np.asarray(electrons, dtype=float)
    h = HALF_WINDOW
    width = 2 * h + 1
    reach = h + 0.5 + 5.0 * (sigma.max() if len(sigma) else 0.0)
    tree = cKDTree(xy)
    out = np.empty(len(xy))
    for p, (x, y) in enumerate(xy):
        col0, row0 = int(np.round(x)) - h, int(np.round(y)) - h
        near = np.array(tree.query_ball_point((x, y), reach * np.sqrt(2.0)), dtype=np.int64)
        offset = np.abs(xy[near] - [col0 + h, row0 + h]).max(axis=1)
        free = near[offset <= h + 0.5]
        free = np.concatenate([[p], free[free != p]])
        known = near[(offset > h + 0.5) & (offset <= reach)]
        gx, dgx, sgx = _profiles(xy[free, 0], sigma[free], col0, width)
        gy, dgy, sgy = _profiles(xy[free, 1], sigma[free], row0, width)
        n = electrons[free][:, None, None]
        light = n * gy[:, :, None] * gx[:, None, :]
        columns = [
            n * gy[:, :, None] * dgx[:, None, :],
            n * dgy[:, :, None] * gx[:, None, :],
            gy[:, :, None] * gx[:, None, :],
            n * (sgy[:, :, None] * gx[:, None, :] + gy[:, :, None] * sgx[:, None, :]),
        ]
        mean = light.sum(axis=0) + background
        if len(known):
            kx = _profiles(xy[known, 0], sigma[known], col0, width)[0]
            ky = _profiles(xy[known, 1], sigma[known], row0, width)[0]
            mean += np.einsum("k,ki,kj->ij", electrons[known], ky, kx)
        rows = row0 + np.arange(width)
        cols = col0 + np.arange(width)
        on_image = ((rows >= 0) & (rows < shape[0]))[:, None] & ((cols >= 0) & (cols < shape[1]))
        weight = (on_image / (mean + read_noise**2)).ravel()
        # Parameters: x, y, N, σ of each free spot (spot-major), then the background.
        jac = np.stack(columns, axis=1).reshape(4 * len(free), -1)
        jac = np.vstack([jac, np.ones(width * width)])
        info = (jac * weight) @ jac.T
        try:
            inverse = np.linalg.solve(info, np.eye(len(info))[:, :2])
        except np.linalg.LinAlgError:
            out[p] = np.inf
            continue
        out[p] = np.sqrt(inverse[0, 0] + inverse[1, 1])
    return out
