"""Size, brightness and background of particle images, measured by fitting the images alone.

Each spot's square window of pixels (row j, column i) is fitted, by damped Gauss–Newton
least squares, with a constant background B plus a pixel-integrated Gaussian of total
A digital numbers, centre (x, y) and width σ::

    m_ji = B + A · g(i; x, σ) · g(j; y, σ),
    g(i; x, σ) = ½[erf((i + ½ − x)/(√2σ)) − erf((i − ½ − x)/(√2σ))].

This is the spot the documentation specifies (docs/imaging.md §3), written here apart
from the simulator's renderer and from the PTV stack's detector, so that neither's bug
is shared by the measurement. All spots of a call are fitted at once (arrays of K
windows).
"""

from dataclasses import dataclass

import numpy as np
from scipy.special import erf

__all__ = ["SpotFits", "fit_spots", "fit_windows", "pixel_integrated"]

#: Gauss–Newton iterations (the fits converge in under ten from the moments' start).
ITERATIONS = 30
#: Smallest σ the fit may reach, px (keeps the model defined).
MIN_SIGMA = 0.05


@dataclass(frozen=True)
class SpotFits:
    """Fitted spots.

    Attributes
    ----------
    xy : ndarray, shape (K, 2)
        Centre (x = column, y = row), px.
    sigma : ndarray, shape (K,)
        Gaussian σ, px.
    amount : ndarray, shape (K,)
        A, the spot's total above the background, DN (its photo-electrons times the gain).
    background : ndarray, shape (K,)
        B, DN.
    peak : ndarray, shape (K,)
        The window's brightest pixel less B, DN.
    converged : ndarray of bool, shape (K,)
        An accepted step moved the centre and σ by less than 1e-4 px.
    """

    xy: np.ndarray
    sigma: np.ndarray
    amount: np.ndarray
    background: np.ndarray
    peak: np.ndarray
    converged: np.ndarray


def pixel_integrated(centre: np.ndarray, sigma: np.ndarray, pixels: np.ndarray) -> np.ndarray:
    """Fraction of a 1-D unit Gaussian falling in each pixel.

    Parameters
    ----------
    centre, sigma : ndarray, shape (K,)
        Centre and σ, px.
    pixels : ndarray, shape (K, n)
        Pixel indices (the pixel i spans [i − ½, i + ½)).

    Returns
    -------
    ndarray, shape (K, n)
    """
    scale = np.sqrt(2.0) * sigma[:, None]
    return 0.5 * (
        erf((pixels + 0.5 - centre[:, None]) / scale)
        - erf((pixels - 0.5 - centre[:, None]) / scale)
    )


def _axis(centre, sigma, pixels):
    """g, ∂g/∂centre and ∂g/∂σ of the pixel-integrated Gaussian along one axis, (K, n)."""
    scale = np.sqrt(2.0) * sigma[:, None]
    upper = (pixels + 0.5 - centre[:, None]) / scale
    lower = (pixels - 0.5 - centre[:, None]) / scale
    g = 0.5 * (erf(upper) - erf(lower))
    e_upper, e_lower = np.exp(-(upper**2)), np.exp(-(lower**2))
    d_centre = (e_lower - e_upper) / (np.sqrt(2.0 * np.pi) * sigma[:, None])
    d_sigma = (lower * e_lower - upper * e_upper) / (np.sqrt(np.pi) * sigma[:, None])
    return g, d_centre, d_sigma


def _model(params, columns, rows, *, jacobian=False):
    """The windows' model (K, n, n) and, if asked, its Jacobian (K, n·n, 5)."""
    x, y, sigma, amount, background = params.T
    gx, dx, sx = _axis(x, sigma, columns)
    gy, dy, sy = _axis(y, sigma, rows)
    shape = gy[:, :, None] * gx[:, None, :]
    model = background[:, None, None] + amount[:, None, None] * shape
    if not jacobian:
        return model
    a = amount[:, None, None]
    parts = (
        a * gy[:, :, None] * dx[:, None, :],
        a * dy[:, :, None] * gx[:, None, :],
        a * (sy[:, :, None] * gx[:, None, :] + gy[:, :, None] * sx[:, None, :]),
        shape,
        np.ones_like(shape),
    )
    return model, np.stack([part.reshape(len(part), -1) for part in parts], axis=2)


def fit_spots(image: np.ndarray, centres: np.ndarray, *, half_width: int = 4) -> SpotFits:
    """Fit each spot of ``image`` near ``centres`` (module docstring).

    Parameters
    ----------
    image : ndarray, shape (H, W)
        A recorded frame, DN.
    centres : ndarray, shape (K, 2)
        Approximate spot centres (x, y), px; each window of (2 half_width + 1)² pixels
        around the nearest pixel must lie on the sensor.
    half_width : int
        Half the window's side, px.

    Returns
    -------
    SpotFits

    Raises
    ------
    ValueError
        A window reaching past the sensor's edge.
    """
    centres = np.asarray(centres, dtype=np.float64).reshape(-1, 2)
    size = 2 * half_width + 1
    corners = np.rint(centres).astype(np.int64) - half_width
    rows_max, cols_max = image.shape[0] - size, image.shape[1] - size
    if np.any(corners < 0) or np.any(corners[:, 0] > cols_max) or np.any(corners[:, 1] > rows_max):
        raise ValueError(f"a spot's {size} x {size} window reaches past the sensor's edge")
    offsets = np.arange(size)
    rows = corners[:, 1, None] + offsets
    columns = corners[:, 0, None] + offsets
    windows = image[rows[:, :, None], columns[:, None, :]]
    return fit_windows(windows, corners)


def fit_windows(windows: np.ndarray, corners: np.ndarray) -> SpotFits:
    """Fit one spot in each square window of pixels (module docstring).

    Parameters
    ----------
    windows : ndarray, shape (K, n, n)
        Readings, DN.
    corners : ndarray, shape (K, 2)
        (column, row) of each window's first pixel, px: the fitted centres are in the
        frame's pixel coordinates.

    Returns
    -------
    SpotFits
    """
    data = np.asarray(windows, dtype=np.float64)
    offsets = np.arange(data.shape[1], dtype=np.float64)
    columns = corners[:, 0, None] + offsets
    rows = corners[:, 1, None] + offsets
    params = _start(data, columns, rows)
    params, converged = _gauss_newton(params, data, columns, rows)
    x, y, sigma, amount, background = params.T
    return SpotFits(
        xy=np.stack([x, y], axis=1),
        sigma=sigma,
        amount=amount,
        background=background,
        peak=data.reshape(len(data), -1).max(axis=1) - background,
        converged=converged,
    )


def _start(data: np.ndarray, columns: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """Background from the window's border, the rest from the moments above it."""
    border = np.concatenate(
        [data[:, 0, :], data[:, -1, :], data[:, 1:-1, 0], data[:, 1:-1, -1]], axis=1
    )
    background = np.median(border, axis=1)
    signal = np.clip(data - background[:, None, None], 0.0, None)
    amount = np.maximum(signal.sum(axis=(1, 2)), 1.0)
    x = (signal.sum(axis=1) * columns).sum(axis=1) / amount
    y = (signal.sum(axis=2) * rows).sum(axis=1) / amount
    return np.stack([x, y, np.full_like(x, 0.8), amount, background], axis=1)


def _gauss_newton(params, data, columns, rows):
    """Levenberg–Marquardt on every window at once; converged windows stop early."""
    k = len(params)
    flat = data.reshape(k, -1)
    cost = ((_model(params, columns, rows).reshape(k, -1) - flat) ** 2).sum(axis=1)
    damping = np.full(k, 1e-3)
    converged = np.zeros(k, dtype=bool)
    for _ in range(ITERATIONS):
        active = np.flatnonzero(~converged)
        if not active.size:
            break
        p, c, r = params[active], columns[active], rows[active]
        model, jacobian = _model(p, c, r, jacobian=True)
        residual = model.reshape(len(active), -1) - flat[active]
        transposed = jacobian.transpose(0, 2, 1)
        normal = transposed @ jacobian
        gradient = (transposed @ residual[:, :, None])[:, :, 0]
        diagonal = np.diagonal(normal, axis1=1, axis2=2)
        # The ridge keeps a window whose σ sits at its floor (no gradient in σ) solvable.
        ridge = damping[active, None] * diagonal + 1e-12 * diagonal.max(axis=1, keepdims=True)
        damped = normal + ridge[:, :, None] * np.eye(5)
        step = -np.linalg.solve(damped, gradient[:, :, None])[:, :, 0]
        trial = p + step
        trial[:, 2] = np.maximum(trial[:, 2], MIN_SIGMA)
        trial_cost = ((_model(trial, c, r).reshape(len(active), -1) - flat[active]) ** 2).sum(1)
        better = trial_cost <= cost[active]
        converged[active] = better & (np.abs(step[:, :3]).max(axis=1) < 1e-4)
        params[active] = np.where(better[:, None], trial, p)
        cost[active] = np.where(better, trial_cost, cost[active])
        damping[active] = np.where(better, damping[active] * 0.3, damping[active] * 10.0)
    return params, converged
