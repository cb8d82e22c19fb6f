"""Forward refraction: the direction in which a camera sees a point behind flat interfaces.

Every ray from the camera centre C to a point P through parallel planes stays in the
plane spanned by C, P and the normal n̂ (docs/optics.md §4.3). With heights

    h_0 = d_0 − n̂·C (camera → first plane),  h_m = d_m − d_{m−1} (inner layers),
    h_L = n̂·P − d_{L−1} (last plane → point),

the radial offset ρ = |(P − C) − ((P − C)·n̂) n̂| and μ_m = n_0/n_m, the ray leaves
C at an angle θ_0 to n̂ such that Σ_m h_m tan θ_m = ρ, with sin θ_m = μ_m sin θ_0
(docs/optics.md §4.3 also gives it in s = sin θ_0). In u = tan θ_0, since
tan θ_m = μ_m u / √(1 + (1 − μ_m²) u²),

    g(u) = u [h_0 + Σ_{m≥1} h_m μ_m q_m^{−1/2}] − ρ = 0,   q_m = 1 + (1 − μ_m²) u²,
    g'(u) = h_0 + Σ_{m≥1} h_m μ_m q_m^{−3/2}.

When every μ_m ≤ 1 (the camera sits in the optically thinnest medium, e.g. air)
each term is concave and increasing in u, and so is g; g grows linearly, without the
singularity that f(s) has at s → 1 (grazing rays), and tan θ_m ≤ μ_m u makes the
paraxial (apparent-depth) solution u_0 = ρ / Σ_m h_m μ_m a lower bound of the root.
Newton started there increases monotonically to the root (tangents of a concave
function lie above it), quadratically near it. Otherwise (some μ_m > 1, so g is
singular at u_max = 1/√(μ_m² − 1)) a bracketed Newton is used: a step that leaves
the bracket is replaced by bisection. Iterations stop when the change of θ_0,
|Δu|/(1 + u²), is below 1e-12 rad for every point. The direction is
d = (u ê + n̂)/√(1 + u²) with ê = ρ⃗/ρ.

The same solution gives the virtual (apparent) images of P seen along the chief ray
(used for defocus blur). With z measured from the first plane into the stack, the
backward extension of the medium-0 rays from P meets the line through P parallel to
n̂ (sagittal image) at z_s and their envelope (tangential image) at z_t:

    z_s = Σ_{m≥1} h_m tan θ_m / tan θ_0 = Σ_{m≥1} h_m μ_m q_m^{−1/2},
    z_t = Σ_{m≥1} h_m (d tan θ_m/du) = Σ_{m≥1} h_m μ_m q_m^{−3/2},

both equal to the paraxial apparent depth Σ h_m n_0/n_m at normal incidence. Their
distances from C along the chief ray are (h_0 + z)√(1 + u²).
"""

import logging
from dataclasses import dataclass

import numpy as np

from simulator.optics.interfaces import FlatInterfaces

logger = logging.getLogger(__name__)

#: Newton tolerance on θ_0, rad (1e-12 rad ≈ 1e-8 px for f/pitch ~ 1e4 px).
NEWTON_TOLERANCE = 1e-12
#: Iteration cap; points not converged by then are returned as invalid.
NEWTON_MAX_ITERATIONS = 60


@dataclass(frozen=True, eq=False)
class ChiefRays:
    """Solution of the forward refraction problem for N points.

    Attributes
    ----------
    directions : ndarray, shape (N, 3)
        Unit direction of the ray leaving the camera centre toward each point
        (medium 0), world frame; NaN where invalid.
    tangent : ndarray, shape (N,)
        u = tan θ_0, θ_0 being the angle between that ray and n̂; NaN where invalid.
    heights : ndarray, shape (L + 1, N)
        h_m, m: the path length of each medium projected on n̂.
    valid : ndarray of bool, shape (N,)
        False where the point is not beyond the last plane (h_L < 0) or Newton
        failed to converge.
    """

    directions: np.ndarray
    tangent: np.ndarray
    heights: np.ndarray
    valid: np.ndarray


def _check_center(center: np.ndarray, stack: FlatInterfaces) -> float:
    h0 = stack.camera_height(center)
    if not h0 > 0:
        raise ValueError(
            f"camera centre {np.asarray(center).tolist()} must lie on the camera side of the "
            f"first interface (n̂·C < {stack.offsets[0]!r}); its distance to it is {h0!r} m"
        )
    return h0


def _solve_tangents(
    rho: np.ndarray,
    h0: float,
    inner_hmu: np.ndarray,
    inner_a: np.ndarray,
    last_hmu: np.ndarray,
    last_a: float,
    h_last: np.ndarray,
    *,
    all_denser: bool,
) -> tuple[np.ndarray, np.ndarray, int]:
    """Solve u (h₀ + Σ h_k μ_k / √(1 + (1 − μ_k²) u²)) = ρ for u = tan θ₀, per point.

    Plain Newton from the paraxial start when every μ_k ≤ 1 (``all_denser``: every medium
    is at least as dense as the camera's, and the start is a lower bound of the root);
    else Newton safeguarded by bisection within the bracket where every square root is
    real. Returns u, whether each point converged, and the iterations taken.
    """

    def value_and_slope(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        u2 = u * u
        total = np.full_like(u, h0)
        slope = np.full_like(u, h0)
        for hmu, a in zip(inner_hmu, inner_a, strict=True):
            inv = 1.0 / np.sqrt(1.0 + a * u2)
            term = hmu * inv
            total += term
            slope += term * inv * inv
        inv = 1.0 / np.sqrt(1.0 + last_a * u2)
        term = last_hmu * inv
        total += term
        slope += term * inv * inv
        return u * total - rho, slope

    # Paraxial (apparent-depth) start: a lower bound of the root when all μ ≤ 1.
    u = rho / (h0 + float(inner_hmu.sum()) + last_hmu)
    iterations = 0
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        if all_denser:
            for iterations in range(1, NEWTON_MAX_ITERATIONS + 1):  # noqa: B007
                value, slope = value_and_slope(u)
                step = value / slope
                u = u - step
                change = np.abs(step) / (1.0 + u * u)
                if not np.nanmax(change, initial=0.0) > NEWTON_TOLERANCE:
                    break
        else:
            fixed_limit = np.inf
            for hmu, a in zip(inner_hmu, inner_a, strict=True):
                if a < 0 and hmu > 0:
                    fixed_limit = min(fixed_limit, 1.0 / np.sqrt(-a))
            hi = np.full_like(u, fixed_limit)
            if last_a < 0:
                hi = np.where(h_last > 0, np.minimum(hi, 1.0 / np.sqrt(-last_a)), hi)
            lo = np.zeros_like(u)
            u = np.where(u < hi, u, 0.5 * hi)
            for iterations in range(1, NEWTON_MAX_ITERATIONS + 1):  # noqa: B007
                value, slope = value_and_slope(u)
                lo = np.where(value < 0, u, lo)
                hi = np.where(value > 0, u, hi)
                new = u - value / slope
                outside = ~((new > lo) & (new < hi)) & (value != 0)
                bisect = np.where(np.isfinite(hi), 0.5 * (lo + hi), 2.0 * u + 1.0)
                new = np.where(outside, bisect, new)
                change = np.abs(new - u) / (1.0 + new * new)
                u = new
                if not np.nanmax(change, initial=0.0) > NEWTON_TOLERANCE:
                    break
        converged = change <= NEWTON_TOLERANCE
    return u, converged, iterations


def solve_chief_rays(center: np.ndarray, points: np.ndarray, stack: FlatInterfaces) -> ChiefRays:
    """Directions from a camera centre to points behind a stack (vectorised Newton).

    Parameters
    ----------
    center : ndarray, shape (3,)
        Camera (entrance-pupil) centre C in medium 0, m.
    points : ndarray, shape (N, 3)
        Points P, m, expected in the last medium.
    stack : FlatInterfaces
        The refractive planes.

    Returns
    -------
    ChiefRays
        Directions, tan θ_0, heights and validity.
    """
    normal = stack.normal
    h0 = _check_center(center, stack)
    mu = stack.indices[0] / stack.indices[1:]  # μ_1 … μ_L
    inner = stack.thicknesses  # h_1 … h_{L−1}
    rel = points - center
    along = rel @ normal
    radial = rel - along[:, None] * normal
    rho = np.sqrt(np.einsum("ij,ij->i", radial, radial))
    h_last = points @ normal - stack.offsets[-1]
    valid = h_last >= 0
    h_last = np.where(valid, h_last, 0.0)

    # Inner layers have fixed heights; the last one varies per point.
    keep = inner > 0
    inner_hmu = (inner * mu[:-1])[keep]
    inner_a = (1.0 - mu[:-1] ** 2)[keep]
    last_hmu = h_last * mu[-1]
    last_a = 1.0 - mu[-1] ** 2

    u, converged, iterations = _solve_tangents(
        rho, h0, inner_hmu, inner_a, last_hmu, last_a, h_last, all_denser=np.all(mu <= 1.0)
    )
    failed = valid & ~converged
    if failed.any():
        logger.warning(
            "forward refraction: Newton did not converge for %d of %d points",
            int(failed.sum()),
            len(points),
        )
    valid &= converged
    logger.debug("forward refraction: %d Newton iterations for %d points", iterations, len(u))
    with np.errstate(divide="ignore", invalid="ignore"):
        e_hat = radial / np.where(rho > 0, rho, 1.0)[:, None]
        scale = 1.0 / np.sqrt(1.0 + u * u)
    directions = (u * scale)[:, None] * e_hat + scale[:, None] * normal
    directions[~valid] = np.nan
    heights = np.empty((len(mu) + 1, len(points)))
    heights[0] = h0
    heights[1:-1] = inner[:, None]
    heights[-1] = h_last
    return ChiefRays(
        directions=directions, tangent=np.where(valid, u, np.nan), heights=heights, valid=valid
    )


def virtual_image_distances(
    chief: ChiefRays, stack: FlatInterfaces
) -> tuple[np.ndarray, np.ndarray]:
    """Distances from the camera centre to the sagittal and tangential images of each point.

    Parameters
    ----------
    chief : ChiefRays
        Output of :func:`solve_chief_rays`.
    stack : FlatInterfaces
        The same stack.

    Returns
    -------
    sagittal, tangential : ndarray, shape (N,)
        Distances along the chief ray in medium 0, m (see the module docstring);
        NaN where invalid.
    """
    u2 = chief.tangent**2
    mu = stack.indices[0] / stack.indices[1:]
    z_sag = np.zeros_like(u2)
    z_tan = np.zeros_like(u2)
    for m in range(1, len(mu) + 1):
        inv = 1.0 / np.sqrt(1.0 + (1.0 - mu[m - 1] ** 2) * u2)
        hmu = chief.heights[m] * mu[m - 1]
        z_sag += hmu * inv
        z_tan += hmu * inv**3
    h0 = chief.heights[0]
    secant = np.sqrt(1.0 + u2)
    return (h0 + z_sag) * secant, (h0 + z_tan) * secant
