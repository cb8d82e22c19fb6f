"""2-D polynomial maps R² → R² of total degree 1–3 in normalised coordinates.

A degree-3 map has the 10 terms 1, u, v, u², uv, v², u³, u²v, uv², v³ per output
coordinate (Matlab's ``cp2tform('polynomial', 3)``), with u, v the input coordinates
scaled to [−1, 1] over the fitted points so that the least-squares system is well
conditioned.
"""

from dataclasses import dataclass

import numpy as np


def _exponents(degree: int) -> np.ndarray:
    return np.array([(i - j, j) for i in range(degree + 1) for j in range(i + 1)])


@dataclass(frozen=True, eq=False)
class Polynomial2D:
    """A fitted polynomial map.

    Attributes
    ----------
    degree : int
        Total degree (1 to 3).
    centre, scale : ndarray, shape (2,)
        Input normalisation u = (p − centre)/scale.
    coefficients : ndarray, shape (T, 2)
        One column per output coordinate, one row per monomial.
    """

    degree: int
    centre: np.ndarray
    scale: np.ndarray
    coefficients: np.ndarray

    def design(self, points: np.ndarray) -> np.ndarray:
        """Monomials of the normalised points, shape (N, T)."""
        u = (np.asarray(points, dtype=float) - self.centre) / self.scale
        e = _exponents(self.degree)
        return u[:, None, 0] ** e[:, 0] * u[:, None, 1] ** e[:, 1]

    def __call__(self, points: np.ndarray) -> np.ndarray:
        """Mapped points, shape (N, 2)."""
        return self.design(points) @ self.coefficients

    def jacobian(self, points: np.ndarray) -> np.ndarray:
        """Derivative of the map, shape (N, 2, 2): [..., i, j] = ∂out_i/∂in_j."""
        u = (np.asarray(points, dtype=float) - self.centre) / self.scale
        e = _exponents(self.degree)
        du = e[:, 0] * u[:, None, 0] ** np.maximum(e[:, 0] - 1, 0) * u[:, None, 1] ** e[:, 1]
        dv = e[:, 1] * u[:, None, 0] ** e[:, 0] * u[:, None, 1] ** np.maximum(e[:, 1] - 1, 0)
        jac = np.stack([du @ self.coefficients, dv @ self.coefficients], axis=-1)
        return jac / self.scale


def fit_polynomial2d(src: np.ndarray, dst: np.ndarray, *, degree: int = 3) -> Polynomial2D:
    """Least-squares polynomial map taking ``src`` to ``dst``.

    Parameters
    ----------
    src, dst : ndarray, shape (N, 2)
        Corresponding points; N ≥ the number of terms ((d+1)(d+2)/2).
    degree : int
        Total degree, 1 to 3.

    Returns
    -------
    Polynomial2D
    """
    if degree not in (1, 2, 3):
        raise ValueError(f"degree must be 1, 2 or 3, got {degree!r}")
    src = np.asarray(src, dtype=float)
    dst = np.asarray(dst, dtype=float)
    if src.ndim != 2 or src.shape[1] != 2 or dst.shape != src.shape:
        raise ValueError(f"src and dst must both be (N, 2), got {src.shape} and {dst.shape}")
    if not (np.isfinite(src).all() and np.isfinite(dst).all()):
        raise ValueError("src or dst contain NaN or infinite values")
    terms = (degree + 1) * (degree + 2) // 2
    if len(src) < terms:
        raise ValueError(f"a degree-{degree} map needs at least {terms} points, got {len(src)}")
    lo, hi = src.min(axis=0), src.max(axis=0)
    scale = np.where(hi > lo, (hi - lo) / 2, 1.0)
    poly = Polynomial2D(degree, (hi + lo) / 2, scale, np.zeros((terms, 2)))
    coefficients = np.linalg.lstsq(poly.design(src), dst, rcond=None)[0]
    return Polynomial2D(degree, poly.centre, poly.scale, coefficients)
