"""Exact two-point statistics of a DNS field: D_LL from its modes, increments along the
grid axes, and the Kármán–Howarth balance of forced stationary turbulence (docs/dns.md §9).

**From the modes.** A periodic field u = Σ_k û_k e^{ik·x} averaged over the directions of
the separation has, with e_k the kinetic energy of the mode pair ±k and |k| = k,

    D_LL(r) = 4 Σ_k e_k G(kr),    B_LL(r) = ⟨u_L(x)u_L(x + r)⟩ = 2 Σ_k e_k g(kr),

g(x) = (sin x − x cos x)/x³ and G = 1/3 − g (the discrete form of the isotropic identity
of docs/flow.md §3.1; exact for the realization, whatever its anisotropy, because the
direction average of each mode depends on k alone). The modes are grouped by their
|k|² (integer in units of (2π/L)²), so the sums run over a few thousand shells.

**Along grid directions.** Increments of the gridded field over whole grid steps (by
periodic shifts, exact on the grid): the longitudinal δu_L = (u(x + r e) − u(x))·e, its
second and third moments S2(r), S3(r), and, with the Lagrangian acceleration field a,
the flux terms ⟨δu·δa⟩(r) and ⟨δu_L δa_L⟩(r), averaged over 13 directions with the
weights of an isotropic rule (the cubic 2/3-rule cut makes the smallest scales
anisotropic: along the axes alone S2 reads 2–3 % low and S3 10–15 % low).

**Kármán–Howarth.** For stationary forced turbulence (stationarity kills ∂B_LL/∂t),
integrating r⁴ times the equation for B_LL from 0 to r gives

    S3(r) = 6ν dS2/dr − (6/r⁴) ∫₀^r y⁴ F_LL(y) dy,

F_LL(y) = ⟨f_L(x)u_L(x + y) + u_L(x)f_L(x + y)⟩ the forcing's longitudinal correlation.
With the band forcing f̂ = ε/(2E_f) û on the band, F_LL = (ε/E_f)·B_LL of the band's modes,
F_LL(0) = 2ε/3, and the balance is −(4/5)εr + 6ν dS2/dr at r much below the band's
scale, with the forcing's correction beyond.
"""

import numpy as np

from simulator.dns.grid import Grid


def _g(x: np.ndarray) -> np.ndarray:
    """(sin x − x cos x)/x³, with its series below x = 10⁻² (1/3 − x²/30 + x⁴/840)."""
    x = np.asarray(x, dtype=float)
    small = np.abs(x) < 1e-2
    safe = np.where(small, 1.0, x)
    exact = (np.sin(safe) - safe * np.cos(safe)) / safe**3
    series = 1.0 / 3.0 - x**2 / 30.0 + x**4 / 840.0
    return np.where(small, series, exact)


def shell_energies(
    velocity_hat: np.ndarray, grid: Grid, *, band: float | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """The field's kinetic energy per distinct |k|.

    Parameters
    ----------
    velocity_hat : ndarray, shape (3, N, N, N//2 + 1), complex
        rfftn coefficients of the velocity ('backward' normalisation).
    grid : Grid
    band : float, optional
        Keep only the modes with 0 < |k| ≤ band·(2π/L) (the forced band).

    Returns
    -------
    k : ndarray, shape (S,)
        The distinct |k| of the modes kept (|k| > 0), 1/m.
    energy : ndarray, shape (S,)
        Kinetic energy of all the modes of that |k|, m²/s² (Σ energy = ½⟨|u|²⟩).
    """
    n = grid.n
    weights = grid.mode_weights()
    power = np.sum(np.abs(velocity_hat) ** 2, axis=0) * weights / (2.0 * float(n) ** 6)
    kx, ky, kz = (k / grid.k0 for k in grid.wavenumbers())
    n2 = np.rint(kx[:, None, None] ** 2 + ky[None, :, None] ** 2 + kz[None, None, :] ** 2)
    n2 = n2.astype(np.int64).ravel()
    keep = n2 > 0
    if band is not None:
        keep &= n2 <= band**2 + 1e-9
    sums = np.bincount(n2[keep], weights=power.ravel()[keep])
    shells = np.flatnonzero(np.bincount(n2[keep]))  # the |k|² that hold modes
    return np.sqrt(shells) * grid.k0, sums[shells]


def modal_dll(k: np.ndarray, energy: np.ndarray, r: np.ndarray) -> np.ndarray:
    """D_LL(r) = 4 Σ e_k G(kr) of shell energies (module docstring), m²/s², r's shape."""
    r = np.asarray(r, dtype=float)
    x = np.multiply.outer(r.ravel(), k)
    return (4.0 * (1.0 / 3.0 - _g(x)) @ energy).reshape(r.shape)


def modal_dll_slope(k: np.ndarray, energy: np.ndarray, r: np.ndarray) -> np.ndarray:
    """dD_LL/dr = −4 Σ e_k k g′(kr), g′(x) = sin x/x² − 3g(x)/x (its series −x/15 + x³/210
    below x = 10⁻²), m/s², r's shape."""
    r = np.asarray(r, dtype=float)
    x = np.multiply.outer(r.ravel(), k)
    small = np.abs(x) < 1e-2
    safe = np.where(small, 1.0, x)
    slope = np.where(small, -x / 15.0 + x**3 / 210.0, np.sin(safe) / safe**2 - 3 * _g(safe) / safe)
    return (-4.0 * (slope * k) @ energy).reshape(r.shape)


def modal_correlation(k: np.ndarray, energy: np.ndarray, r: np.ndarray) -> np.ndarray:
    """B_LL(r) = 2 Σ e_k g(kr) of shell energies, m²/s², r's shape."""
    r = np.asarray(r, dtype=float)
    x = np.multiply.outer(r.ravel(), k)
    return (2.0 * _g(x) @ energy).reshape(r.shape)


def forcing_flux(
    k_band: np.ndarray, energy_band: np.ndarray, epsilon: float, r: np.ndarray
) -> np.ndarray:
    """The forcing term (6/r⁴)∫₀^r y⁴ F_LL(y) dy of the Kármán–Howarth balance, m³/s³.

    F_LL(y) = (ε/E_f)·2 Σ_band e_k g(ky); the integral is taken by Gauss–Legendre on 64
    nodes over [0, r] (the band's kr stays below a few π, where 64 nodes are exact to
    round-off).

    Parameters
    ----------
    k_band, energy_band : ndarray, shape (S,)
        Shell energies of the forced band (:func:`shell_energies` with ``band``).
    epsilon : float
        The injected power ε, m²/s³.
    r : ndarray, shape (R,)
        Separations, m, > 0.

    Returns
    -------
    ndarray, shape (R,)
        (6/r⁴)∫₀^r y⁴ F_LL(y) dy: (4/5)εr where r is small against the band's scale.
    """
    r = np.asarray(r, dtype=float)
    nodes, weights = np.polynomial.legendre.leggauss(64)
    e_f = float(np.sum(energy_band))
    out = np.empty_like(r)
    for i, ri in enumerate(r):
        y = 0.5 * ri * (nodes + 1.0)
        f_ll = (epsilon / e_f) * modal_correlation(k_band, energy_band, y)
        out[i] = 6.0 / ri**4 * 0.5 * ri * np.sum(weights * y**4 * f_ll)
    return out


#: The 13 directions (up to sign) of Lebedev's 26-point rule on the sphere, exact for
#: polynomials of degree 7, as integer grid steps, and the weight of each direction (its
#: two signs together): the axes 2/21, the face diagonals 8/105, the body diagonals 9/140.
DIRECTIONS = (
    *(((1, 0, 0), (0, 1, 0), (0, 0, 1))),
    (1, 1, 0), (1, -1, 0), (1, 0, 1), (1, 0, -1), (0, 1, 1), (0, 1, -1),
    (1, 1, 1), (1, 1, -1), (1, -1, 1), (1, -1, -1),
)  # fmt: skip
WEIGHTS = (2 / 21,) * 3 + (8 / 105,) * 6 + (9 / 140,) * 4

#: Powers of r by which each moment is divided before the families of directions are
#: interpolated to a common r (their small-r behaviour, so the ratio is smooth).
_POWERS = {"s2": 2, "s3": 3, "du_da": 2, "dul_dal": 2}


def _family_moments(velocity, acceleration, step, shifts) -> dict[str, np.ndarray]:
    """Moments of the increments along one direction of grid steps ``step``, at
    separations m·step, m in ``shifts``."""
    unit = np.asarray(step, dtype=float) / np.linalg.norm(step)
    out = {name: np.zeros(len(shifts)) for name in _POWERS}
    for i, m in enumerate(shifts):
        shift = tuple(-int(m) * s for s in step)
        du = np.roll(velocity, shift, axis=(1, 2, 3)) - velocity
        longitudinal = np.tensordot(unit, du, axes=1)
        out["s2"][i] = np.mean(longitudinal**2)
        out["s3"][i] = np.mean(longitudinal**3)
        if acceleration is not None:
            da = np.roll(acceleration, shift, axis=(1, 2, 3)) - acceleration
            out["du_da"][i] = np.mean(np.sum(du * da, axis=0))
            out["dul_dal"][i] = np.mean(longitudinal * np.tensordot(unit, da, axes=1))
    return out


def direction_increments(
    velocity: np.ndarray, shifts: np.ndarray, *, acceleration: np.ndarray | None = None
) -> dict[str, np.ndarray]:
    """Moments of the longitudinal increments, averaged over the 13 directions of
    :data:`DIRECTIONS` with their weights: the direction average of an isotropic rule
    (the grid's axes alone would carry the anisotropy of the cubic 2/3-rule cut).

    Each direction's moments are taken at its own separations m·|step|Δx, divided by r^p
    (p their small-r power) and interpolated linearly to r = mΔx.

    Parameters
    ----------
    velocity : ndarray, shape (3, N, N, N)
        u on the grid, m/s.
    shifts : ndarray of int, shape (R,)
        Separations in grid spacings m ≥ 1 (r = mΔx).
    acceleration : ndarray, shape (3, N, N, N), optional
        The Lagrangian acceleration on the grid, m/s², for the flux terms.

    Returns
    -------
    dict of ndarray, shape (R,)
        ``s2`` ⟨δu_L²⟩ (m²/s²), ``s3`` ⟨δu_L³⟩ (m³/s³); with ``acceleration`` also
        ``du_da`` ⟨δu·δa⟩ and ``dul_dal`` ⟨δu_L δa_L⟩ (m²/s³).
    """
    shifts = np.asarray(shifts)
    target = shifts.astype(float)
    names = list(_POWERS) if acceleration is not None else ["s2", "s3"]
    out = {name: np.zeros(len(shifts)) for name in names}
    for step, weight in zip(DIRECTIONS, WEIGHTS, strict=True):
        moments = _family_moments(velocity, acceleration, step, shifts)
        r = shifts * float(np.linalg.norm(step))
        for name in names:
            power = _POWERS[name]
            scaled = np.interp(target, r, moments[name] / r**power)
            out[name] += weight * scaled * target**power
    return out
