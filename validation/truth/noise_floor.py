"""What dot-centre noise alone allows a calibration, from the true cameras (docs/claims.md).

With exact dot projections plus Gaussian centre noise of σ px, a calibration that
models the cameras exactly still triangulates each dot off by the image noise carried
into the water. Linearised, a pixel error n_c of camera c moves its ray sideways by
J_c⁺n_c, where J_c = ∂(pixel)/∂X is the true projection's Jacobian (central
differences of :meth:`simulator.optics.Camera.project`; the ray is its null direction),
and the least-squares point of the rays (``docs/ptv.md §2``) by

    δP = (Σ_c A_c)⁻¹ Σ_c J_c⁺ n_c,     A_c = I − V_c V_cᵀ.

Hence, with no calibration code involved:

- the Table 1 d such a calibration reaches (:func:`noise_floor`), its sampling error,
  and the object-side pixel; the in-sample fit absorbs a share ≈ p/(N·J) of each
  dot's own noise (0.2 % of d), which the claims neglect;
- the rms residual of a least-squares plane map with p terms fitted to N noisy dots:
  σ√(2(1 − p/N)) px for the 2-D distance (:func:`residual_floor`);
- the model error at random points, the noise that the fitted maps carry:
  d·√(p/N · (1/J + ⟨(Z − Z̄)²⟩/Σ_j(Z_j − Z̄)²)) for J planes and Z uniform over their
  span (:func:`model_error_floor`).
"""

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

#: Terms of a cubic 2-D polynomial per output coordinate (the paper's plane maps T_j).
CUBIC_TERMS = 10


@dataclass(frozen=True)
class NoiseFloor:
    """The Table 1 errors that dot-centre noise alone gives.

    Attributes
    ----------
    d : float
        Expected mean 3-D distance, m.
    se_d : float
        Standard error of a mean over the ``dots``, m.
    dots : int
        Dots seen by every camera.
    object_pixel : float
        Mean object-side pixel at the dots, √ of the area one pixel covers across the
        ray, m.
    """

    d: float
    se_d: float
    dots: int
    object_pixel: float


def projection_jacobians(camera, points: np.ndarray, step: float) -> np.ndarray:
    """∂(pixel)/∂X of a true camera at points (N, 3), by central differences: (N, 2, 3)."""
    out = np.empty((len(points), 2, 3))
    for axis in range(3):
        shift = np.zeros(3)
        shift[axis] = step
        out[:, :, axis] = (camera.project(points + shift) - camera.project(points - shift)) / (
            2 * step
        )
    return out


def object_pixel(cameras, point: np.ndarray, *, step: float = 1e-5) -> float:
    """The largest object-side pixel of the cameras at a point, m.

    The sideways shift of a camera's ray that moves its image by one pixel along x or y
    is |J⁺e| (J the projection's Jacobian, e the pixel step; J⁺e is normal to the ray,
    along which the image does not move); the largest over the cameras and both axes.

    Parameters
    ----------
    cameras : sequence of Camera
        True cameras.
    point : ndarray, shape (3,)
        World point, m.
    step : float
        Central-difference step, m.
    """
    point = np.asarray(point, dtype=np.float64).reshape(1, 3)
    sizes = [
        np.linalg.norm(np.linalg.pinv(projection_jacobians(camera, point, step)[0]), axis=0).max()
        for camera in cameras
    ]
    return float(max(sizes))


def noise_floor(
    cameras: Sequence,
    points: np.ndarray,
    noise_px: float,
    *,
    step: float = 2e-5,
    draws: int = 64,
    rng: int = 0,
) -> NoiseFloor:
    """Expected Table 1 d of a calibration limited by dot-centre noise (module docstring).

    Parameters
    ----------
    cameras : sequence of Camera
        The true cameras (``project``: (N, 3) m → (N, 2) px, NaN where not seen).
    points : ndarray, shape (N, 3)
        Dot centres, m.
    noise_px : float
        Dot-centre noise per image axis, px.
    step : float
        Finite-difference step, m.
    draws : int
        Noise draws per dot for E‖δP‖.
    rng : int
        Seed of the draws.

    Returns
    -------
    NoiseFloor
    """
    points = np.asarray(points, dtype=float)
    seen = np.all([np.isfinite(c.project(points)).all(axis=1) for c in cameras], axis=0)
    points = points[seen]
    jacobians = [projection_jacobians(c, points, step) for c in cameras]
    normal = np.zeros((len(points), 3, 3))
    for j in jacobians:
        v = np.cross(j[:, 0], j[:, 1])
        v /= np.linalg.norm(v, axis=1, keepdims=True)
        normal += np.eye(3) - v[:, :, None] * v[:, None, :]
    gains = [np.linalg.solve(normal, np.linalg.pinv(j)) for j in jacobians]  # (N, 3, 2)
    generator = np.random.default_rng(rng)
    distances = np.empty((draws, len(points)))
    for k in range(draws):
        delta = sum(g @ generator.normal(0.0, noise_px, (len(points), 2, 1)) for g in gains)
        distances[k] = np.linalg.norm(delta[:, :, 0], axis=1)
    per_dot = distances.mean(axis=0)
    pixel = np.mean([np.linalg.det(j @ j.transpose(0, 2, 1)) ** -0.25 for j in jacobians])
    return NoiseFloor(
        d=float(per_dot.mean()),
        se_d=float(distances.std() / np.sqrt(len(points))),
        dots=len(points),
        object_pixel=float(pixel),
    )


def residual_floor(noise_px: float, dots_per_plane: Sequence[int], terms: int) -> float:
    """Expected rms of the 2-D residuals of least-squares plane maps, px.

    A map with ``terms`` coefficients per coordinate fitted to N dots leaves each
    coordinate a residual variance σ²(1 − terms/N); the rms is taken over every dot of
    every plane.
    """
    n = np.asarray(dots_per_plane, dtype=float)
    return float(noise_px * np.sqrt(2 * np.sum(n - terms) / np.sum(n)))


def model_error_floor(
    d_noise: float, dots_per_plane: float, plane_z: Sequence[float], terms: int
) -> float:
    """Expected model error at random points from the noise the fitted maps carry, m.

    Parameters
    ----------
    d_noise : float
        :attr:`NoiseFloor.d`, m.
    dots_per_plane : float
        Mean dots N per plane.
    plane_z : sequence of float
        Z_j of the J planes, m.
    terms : int
        Coefficients p of a plane map per coordinate.
    """
    z = np.asarray(plane_z, dtype=float)
    spread = np.sum((z - z.mean()) ** 2)
    mean_square = (z.max() - z.min()) ** 2 / 12  # ⟨(Z − Z̄)²⟩, Z uniform over the span
    return float(d_noise * np.sqrt(terms / dots_per_plane * (1 / len(z) + mean_square / spread)))
