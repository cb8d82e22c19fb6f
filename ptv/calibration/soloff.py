"""Soloff, Adrian & Liu (1997): a polynomial world → pixel mapping per camera.

Each image coordinate of each camera is a polynomial F(X) in the world point,
cubic in X₁ = X and X₂ = Y and quadratic in X₃ = Z, with the 19 terms (docs/calibration.md §6)

    1, X₁, X₂, X₃, X₁², X₁X₂, X₂², X₁X₃, X₂X₃, X₃², X₁³, X₁²X₂, X₁X₂², X₂³,
    X₁²X₃, X₁X₂X₃, X₂²X₃, X₁X₃², X₂X₃²,

fitted by linear least squares in coordinates normalised to [−1, 1] over the
calibration points. Being quadratic in Z, it needs at least three planes.

``project`` is the polynomial itself. Soloff's model has no rays, so ``pixel_to_ray``
builds one: for each pixel it finds, by a 2-D Newton iteration in (X, Y) started from
an affine inverse, the points on several Z levels (by default the calibration planes)
that map to it, and fits the straight line X = X₀ + a (Z − Z̄), Y = Y₀ + b (Z − Z̄)
through them by least squares. **This is a straight-line approximation of Soloff's
inverse, which is in general a curve**; the approximation is what ray-based
triangulation and matching see. Soloff's own reconstruction, :func:`reconstruct`,
does not use it except as a start: it solves F_c(X) = x_c for all cameras at once by
Gauss–Newton, X ← X + (JᵀJ)⁻¹Jᵀ(x_obs − F(X)) with J stacked over cameras.

The polynomial extrapolates outside the calibrated volume like any global model;
``project`` and ``pixel_to_ray`` only reject points that fall off the image.
"""

import logging
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ptv.calibration.observations import PlaneObservation, stack_planes
from ptv.camera_model import on_image
from ptv.rays import Rays
from ptv.triangulate import triangulate

log = logging.getLogger(__name__)

#: Exponents (of X₁, X₂, X₃) of the 19 Soloff terms, in docs/calibration.md §6 order.
SOLOFF_EXPONENTS = np.array(
    [
        (0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1),
        (2, 0, 0), (1, 1, 0), (0, 2, 0), (1, 0, 1), (0, 1, 1), (0, 0, 2),
        (3, 0, 0), (2, 1, 0), (1, 2, 0), (0, 3, 0),
        (2, 0, 1), (1, 1, 1), (0, 2, 1), (1, 0, 2), (0, 1, 2),
    ]
)  # fmt: skip

#: Newton (inverse on a plane) and Gauss–Newton (reconstruction) iteration caps.
_NEWTON_STEPS = 30
_GAUSS_NEWTON_STEPS = 30
#: Convergence tolerance on the step, in normalised world units (scale ~ half the volume).
_STEP_TOL = 1e-13


def _powers(u: np.ndarray) -> np.ndarray:
    """u**k for k = 0..3, shape (N, 3, 4)."""
    return u[:, :, None] ** np.arange(4)


def soloff_design(u: np.ndarray) -> np.ndarray:
    """The 19 monomials of normalised points u (N, 3), shape (N, 19)."""
    pw = _powers(np.asarray(u, dtype=float))
    e = SOLOFF_EXPONENTS
    return pw[:, 0, e[:, 0]] * pw[:, 1, e[:, 1]] * pw[:, 2, e[:, 2]]


def soloff_design_derivatives(u: np.ndarray) -> np.ndarray:
    """∂(monomials)/∂u_i of normalised points u (N, 3), shape (N, 3, 19)."""
    pw = _powers(np.asarray(u, dtype=float))
    e = SOLOFF_EXPONENTS
    terms = [pw[:, i, e[:, i]] for i in range(3)]
    out = np.empty((len(u), 3, len(e)))
    for i in range(3):
        lower = pw[:, i, np.maximum(e[:, i] - 1, 0)] * e[:, i]
        others = [terms[k] for k in range(3) if k != i]
        out[:, i] = lower * others[0] * others[1]
    return out


@dataclass(frozen=True, eq=False)
class SoloffCalibration:
    """Soloff's polynomial mapping of one camera.

    Attributes
    ----------
    image_size : tuple of int
        (width, height), px; pixels off [−½, W−½] × [−½, H−½] are not imaged.
    centre, scale : ndarray, shape (3,)
        Normalisation u = (X − centre)/scale of world points, m.
    coefficients : ndarray, shape (19, 2)
        Coefficients of x and y (px) on the ``SOLOFF_EXPONENTS`` monomials of u.
    inverse : ndarray, shape (4, 2)
        Affine start of the inversion: (X, Y) ≈ [x, y, Z, 1] @ inverse (px, m → m).
    z_levels : ndarray, shape (K,)
        Z levels (m, K ≥ 2) whose inverse points define ``pixel_to_ray``'s lines.
    residual_px : ndarray, shape (N,)
        |F(X) − x| of each calibration dot, px.
    """

    image_size: tuple[int, int]
    centre: np.ndarray
    scale: np.ndarray
    coefficients: np.ndarray
    inverse: np.ndarray
    z_levels: np.ndarray
    residual_px: np.ndarray

    @property
    def rms(self) -> float:
        """Root-mean-square fit residual over the calibration dots, px."""
        return float(np.sqrt(np.mean(self.residual_px**2)))

    def evaluate(self, points: np.ndarray) -> np.ndarray:
        """F(X) for world points (N, 3), px, with no visibility check."""
        u = (np.asarray(points, dtype=float) - self.centre) / self.scale
        return soloff_design(u) @ self.coefficients

    def jacobian(self, points: np.ndarray) -> np.ndarray:
        """∂F/∂X at world points (N, 3), shape (N, 2, 3): [..., i, j] = ∂x_i/∂X_j, px/m."""
        u = (np.asarray(points, dtype=float) - self.centre) / self.scale
        d = soloff_design_derivatives(u)  # (N, 3, 19)
        return np.einsum("njt,ti->nij", d, self.coefficients) / self.scale

    def project(self, points: np.ndarray) -> np.ndarray:
        """Pixels (N, 2) of world points (N, 3), m; NaN where off the image or not finite."""
        points = np.asarray(points, dtype=float)
        if points.ndim != 2 or points.shape[1] != 3:
            raise ValueError(f"points must have shape (N, 3), got {points.shape}")
        finite = np.isfinite(points).all(axis=1)
        xy = self.evaluate(np.where(finite[:, None], points, self.centre))
        xy[~(finite & on_image(xy, self.image_size))] = np.nan
        return xy

    def points_at(self, xy: np.ndarray, z: float) -> np.ndarray:
        """(X, Y) on the plane Z = z that map to pixels xy (N, 2), m; NaN if not found.

        A 2-D Newton iteration on F(X, Y, z) = xy from the affine inverse.
        """
        xy = np.asarray(xy, dtype=float)
        ok = np.isfinite(xy).all(axis=1)
        px = np.where(ok[:, None], xy, 0.0)
        n = len(px)
        world = np.empty((n, 3))
        world[:, 2] = z
        world[:, :2] = np.column_stack([px, np.full(n, z), np.ones(n)]) @ self.inverse
        converged = np.zeros(n, dtype=bool)
        todo = np.flatnonzero(ok)
        with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
            for _ in range(_NEWTON_STEPS):
                if todo.size == 0:
                    break
                cur = world[todo]
                residual = self.evaluate(cur) - px[todo]
                jac = self.jacobian(cur)[:, :, :2]
                det = jac[:, 0, 0] * jac[:, 1, 1] - jac[:, 0, 1] * jac[:, 1, 0]
                dx = (jac[:, 1, 1] * residual[:, 0] - jac[:, 0, 1] * residual[:, 1]) / det
                dy = (jac[:, 0, 0] * residual[:, 1] - jac[:, 1, 0] * residual[:, 0]) / det
                world[todo, 0] -= dx
                world[todo, 1] -= dy
                step = np.maximum(np.abs(dx) / self.scale[0], np.abs(dy) / self.scale[1])
                done = (step <= _STEP_TOL) | ~np.isfinite(step)
                converged[todo[done]] = True
                todo = todo[~done]
        good = converged & np.isfinite(world).all(axis=1)
        out = world[:, :2]
        out[~good] = np.nan
        return out

    def pixel_to_ray(self, xy: np.ndarray) -> Rays:
        """Straight-line approximation of the inverse of F for pixels xy (N, 2).

        The least-squares line through the points of ``z_levels`` that map to each
        pixel (exact when Soloff's inverse is straight, e.g. for refraction by flat
        windows that the polynomial reproduces exactly). Origins lie on Z = mean of
        ``z_levels``. NaN rows off the image or where the inversion failed.
        """
        xy = np.asarray(xy, dtype=float)
        if xy.ndim != 2 or xy.shape[1] != 2:
            raise ValueError(f"pixels must have shape (N, 2), got {xy.shape}")
        ok = np.isfinite(xy).all(axis=1) & on_image(xy, self.image_size)
        px = np.where(ok[:, None], xy, 0.0)
        z = np.asarray(self.z_levels, dtype=float)
        pts = np.stack([self.points_at(px, zk) for zk in z])  # (K, N, 2)
        ok &= np.isfinite(pts).all(axis=(0, 2))
        dz = z - z.mean()
        slope = np.einsum("k,knc->nc", dz, pts) / np.sum(dz**2)
        origins = np.column_stack([pts.mean(axis=0), np.full(len(px), z.mean())])
        directions = np.column_stack([slope, np.ones(len(px))])
        directions /= np.linalg.norm(directions, axis=1, keepdims=True)
        origins[~ok] = np.nan
        directions[~ok] = np.nan
        return Rays(origins, directions)


def calibrate_soloff(
    observations: list[PlaneObservation],
    image_size: tuple[int, int],
    *,
    z_levels: np.ndarray | None = None,
) -> SoloffCalibration:
    """Fit Soloff's 19-term polynomial of one camera to its calibration planes.

    Parameters
    ----------
    observations : list of PlaneObservation
        Identified dots per plane; at least three planes with distinct Z.
    image_size : tuple of int
        (width, height) of the images, px.
    z_levels : array_like, optional
        Z levels (m, at least two distinct) for ``pixel_to_ray``; default the plane Z_j.

    Returns
    -------
    SoloffCalibration
    """
    z_planes = np.array([o.z for o in observations], dtype=float)
    if not np.isfinite(z_planes).all():
        raise ValueError(f"calibration planes need finite Z, got {z_planes.tolist()}")
    distinct = np.unique(z_planes)
    if len(distinct) < 3:
        raise ValueError(
            "Soloff's polynomial is quadratic in Z: it needs at least three calibration "
            f"planes with distinct Z, got {len(distinct)} ({distinct.tolist()})"
        )
    world, pixel = stack_planes(observations)
    n_terms = len(SOLOFF_EXPONENTS)
    if len(world) < n_terms:
        raise ValueError(f"Soloff's polynomial needs at least {n_terms} dots, got {len(world)}")
    lo, hi = world.min(axis=0), world.max(axis=0)
    if np.any(hi[:2] <= lo[:2]):
        raise ValueError("the calibration dots span no area in X and Y")
    centre, scale = (hi + lo) / 2, (hi - lo) / 2
    design = soloff_design((world - centre) / scale)
    coefficients, *_, rank, _ = np.linalg.lstsq(design, pixel, rcond=None)
    if rank < n_terms:
        raise ValueError(
            f"the calibration dots do not determine Soloff's 19 terms (rank {rank}); "
            "they need to span X and Y on every plane"
        )
    inverse = np.linalg.lstsq(
        np.column_stack([pixel, world[:, 2], np.ones(len(world))]), world[:, :2], rcond=None
    )[0]
    levels = distinct if z_levels is None else np.unique(np.asarray(z_levels, dtype=float))
    if len(levels) < 2 or not np.isfinite(levels).all():
        raise ValueError(f"z_levels needs at least two distinct finite values, got {z_levels!r}")
    residual = np.linalg.norm(design @ coefficients - pixel, axis=1)
    log.info("Soloff fit: rms %.3g px, max %.3g px", np.sqrt(np.mean(residual**2)), residual.max())
    return SoloffCalibration(
        image_size=(int(image_size[0]), int(image_size[1])),
        centre=centre,
        scale=scale,
        coefficients=coefficients,
        inverse=inverse,
        z_levels=levels,
        residual_px=residual,
    )


def _solve3(lhs: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Batched solve of (N, 3, 3) systems; NaN rows where a system is singular."""
    try:
        return np.linalg.solve(lhs, rhs[..., None])[..., 0]
    except np.linalg.LinAlgError:
        out = np.full(rhs.shape, np.nan)
        for i in range(len(lhs)):
            try:
                out[i] = np.linalg.solve(lhs[i], rhs[i])
            except np.linalg.LinAlgError:
                pass
        return out


def reconstruct(
    calibrations: Sequence[SoloffCalibration], pixels_per_camera: Sequence[np.ndarray]
) -> np.ndarray:
    """Soloff's multi-camera reconstruction of world points by Gauss–Newton.

    Starting from the ray triangulation (:func:`ptv.triangulate.triangulate` with the
    straight-line rays), iterate X ← X + (JᵀJ)⁻¹Jᵀ(x_obs − F(X)), where the residuals
    and the Jacobians J = ∂F/∂X are stacked over the cameras that see the point.

    Parameters
    ----------
    calibrations : sequence of C SoloffCalibration
        One per camera, C ≥ 2.
    pixels_per_camera : sequence of C ndarray, shape (N, 2)
        Row n of every array is the image of point n, px; NaN rows are missing.

    Returns
    -------
    ndarray, shape (N, 3)
        World points, m; NaN where fewer than two cameras see the point or the
        iteration did not converge.
    """
    if len(calibrations) != len(pixels_per_camera) or len(calibrations) < 2:
        raise ValueError(
            "need one pixel array per camera and at least two cameras, got "
            f"{len(calibrations)} calibrations and {len(pixels_per_camera)} pixel arrays"
        )
    obs = [np.asarray(p, dtype=float) for p in pixels_per_camera]
    shapes = {p.shape for p in obs}
    if len(shapes) != 1 or len(obs[0].shape) != 2 or obs[0].shape[1] != 2:
        raise ValueError(f"pixel arrays must all be (N, 2) of one N, got shapes {sorted(shapes)}")
    seen = np.stack([np.isfinite(p).all(axis=1) for p in obs])  # (C, N)
    points = triangulate(calibrations, obs).points
    active = np.flatnonzero((seen.sum(axis=0) >= 2) & np.isfinite(points).all(axis=1))
    converged = np.zeros(len(points), dtype=bool)
    scale = np.min([c.scale for c in calibrations], axis=0)
    with np.errstate(invalid="ignore", over="ignore"):
        for _ in range(_GAUSS_NEWTON_STEPS):
            if active.size == 0:
                break
            cur = points[active]
            jtj = np.zeros((len(active), 3, 3))
            jtr = np.zeros((len(active), 3))
            for cal, p, s in zip(calibrations, obs, seen, strict=True):
                w = s[active]
                residual = np.where(w[:, None], p[active] - cal.evaluate(cur), 0.0)
                jac = cal.jacobian(cur) * w[:, None, None]
                jtj += np.einsum("nia,nib->nab", jac, jac)
                jtr += np.einsum("nia,ni->na", jac, residual)
            step = _solve3(jtj, jtr)
            points[active] = cur + step
            size = np.max(np.abs(step) / scale, axis=1)
            done = (size <= _STEP_TOL) | ~np.isfinite(size)
            converged[active[done]] = True
            active = active[~done]
    good = converged & np.isfinite(points).all(axis=1)
    points[~good] = np.nan
    return points
