"""Dissipation rate ε from the longitudinal structure function, and derived scales.

In the inertial range S2(r) = C2 (εr)^{2/3}, so the local estimator is

    ε(r) = (S2/C2)^{3/2} / r                       (`epsilon_estimate`)

with C2 ≈ 2.0 (C2 = 1.3151 C_K, docs/flow.md §3.4). The paper's Fig. 6 caption writes
ε_r = S2^{3/2}/r without C2 (`epsilon_paper_caption`), which is C2^{3/2} ≈ 2.83 times
larger for C2 = 2 (docs/errata.md E5); both are reported, clearly labelled.
Errors: δε/ε = 1.5 δS2/S2 (and 1.5 δC2/C2 for an uncertain constant).

The plateau value of ε (`plateau_epsilon`) is either the mean of ε(r) over a chosen
inertial range [r_min, r_max] (the paper's Table 3: "averaged over the inertial
range") or its maximum there (docs/claims.md #11).
"""

import logging
from dataclasses import dataclass
from typing import Literal

import numpy as np

from ptv.settings import DEFAULT_C2

__all__ = [
    "NU_WATER",
    "DissipationProfile",
    "Plateau",
    "TurbulenceScales",
    "dissipation_profile",
    "epsilon_estimate",
    "epsilon_paper_caption",
    "plateau_epsilon",
    "turbulence_scales",
]

logger = logging.getLogger(__name__)

#: Kinematic viscosity of water at 20 °C used by the paper, m²/s.
NU_WATER = 1.0e-6


def _arrays(s2, r) -> tuple[np.ndarray, np.ndarray]:
    s2 = np.asarray(s2, dtype=np.float64)
    r = np.asarray(r, dtype=np.float64)
    try:
        np.broadcast_shapes(s2.shape, r.shape)
    except ValueError:
        raise ValueError(f"s2 {s2.shape} and r {r.shape} do not have matching shapes") from None
    if np.any(r[np.isfinite(r)] <= 0):
        raise ValueError("separations r must be > 0")
    return s2, r


def epsilon_estimate(s2, r, *, kolmogorov_c2: float = DEFAULT_C2) -> np.ndarray:
    """ε(r) = (S2/C2)^{3/2}/r, m²/s³.

    Parameters
    ----------
    s2 : array_like
        Longitudinal structure function, m²/s².
    r : array_like, broadcastable with s2
        Separations, m, > 0.
    kolmogorov_c2 : float
        C2 > 0 (default 2.0).

    Returns
    -------
    ndarray
        ε(r); NaN where s2 ≤ 0 or is NaN (a noisy fit can give S2 < 0).
    """
    if not kolmogorov_c2 > 0:
        raise ValueError(f"kolmogorov_c2 must be > 0, got {kolmogorov_c2}")
    s2, r = _arrays(s2, r)
    pos = np.where(s2 > 0, s2, np.nan)
    return (pos / kolmogorov_c2) ** 1.5 / r


def epsilon_paper_caption(s2, r) -> np.ndarray:
    """The paper's uncorrected ε_r = S2^{3/2}/r (Fig. 6 caption, no C2), m²/s³.

    Equal to C2^{3/2} × `epsilon_estimate` (2.83× for C2 = 2). Kept for comparison with
    the paper; not an estimate of ε.
    """
    s2, r = _arrays(s2, r)
    return np.where(s2 > 0, s2, np.nan) ** 1.5 / r


@dataclass(frozen=True)
class DissipationProfile:
    """ε(r) from S2(r).

    Attributes
    ----------
    r : ndarray, shape (B,)
        Separations, m.
    epsilon : ndarray, shape (B,)
        (S2/C2)^{3/2}/r, m²/s³ (NaN where S2 ≤ 0 or not fitted).
    se_epsilon : ndarray, shape (B,)
        1.5 ε sqrt((δS2/S2)² + (δC2/C2)²), m²/s³ (NaN without se_s2).
    epsilon_paper_caption : ndarray, shape (B,)
        The paper's caption formula S2^{3/2}/r **without** C2, m²/s³: C2^{3/2}·epsilon.
    kolmogorov_c2 : float
        C2 used.
    epsilon_boot : ndarray, shape (R, B), or None
        ε from bootstrap replicates of S2 (C2 fixed).
    """

    r: np.ndarray
    epsilon: np.ndarray
    se_epsilon: np.ndarray
    epsilon_paper_caption: np.ndarray
    kolmogorov_c2: float
    epsilon_boot: np.ndarray | None = None


def dissipation_profile(
    r: np.ndarray,
    s2: np.ndarray,
    *,
    se_s2: np.ndarray | None = None,
    s2_boot: np.ndarray | None = None,
    kolmogorov_c2: float = DEFAULT_C2,
    se_kolmogorov_c2: float = 0.0,
) -> DissipationProfile:
    """ε(r) with its uncertainty from S2(r) (e.g. a `StructureFunction`).

    Parameters
    ----------
    r : ndarray, shape (B,)
        Separations, m.
    s2 : ndarray, shape (B,)
        S2, m²/s².
    se_s2 : ndarray, shape (B,), optional
        Standard error of s2, m²/s².
    s2_boot : ndarray, shape (R, B), optional
        Bootstrap replicates of s2 (`StructureFunction.s2_boot`).
    kolmogorov_c2 : float
        C2 (default 2.0).
    se_kolmogorov_c2 : float
        Uncertainty of C2, added in quadrature to se_epsilon (default 0).

    Returns
    -------
    DissipationProfile
    """
    r = np.asarray(r, dtype=np.float64)
    s2 = np.asarray(s2, dtype=np.float64)
    if r.ndim != 1 or s2.shape != r.shape:
        raise ValueError(f"r and s2 must be 1-D of equal length, got {r.shape} and {s2.shape}")
    if se_kolmogorov_c2 < 0:
        raise ValueError(f"se_kolmogorov_c2 must be >= 0, got {se_kolmogorov_c2}")
    eps = epsilon_estimate(s2, r, kolmogorov_c2=kolmogorov_c2)
    if se_s2 is None:
        se = np.full_like(eps, np.nan)
    else:
        se_s2 = np.asarray(se_s2, dtype=np.float64)
        if se_s2.shape != s2.shape:
            raise ValueError(f"se_s2 has shape {se_s2.shape}, expected {s2.shape}")
        with np.errstate(invalid="ignore", divide="ignore"):
            rel = np.hypot(se_s2 / s2, se_kolmogorov_c2 / kolmogorov_c2)
        se = 1.5 * eps * rel
    boot = None
    if s2_boot is not None:
        s2_boot = np.asarray(s2_boot, dtype=np.float64)
        if s2_boot.ndim != 2 or s2_boot.shape[1] != s2.size:
            raise ValueError(f"s2_boot must have shape (R, {s2.size}), got {s2_boot.shape}")
        boot = epsilon_estimate(s2_boot, r[None, :], kolmogorov_c2=kolmogorov_c2)
    return DissipationProfile(
        r=r,
        epsilon=eps,
        se_epsilon=se,
        epsilon_paper_caption=epsilon_paper_caption(s2, r),
        kolmogorov_c2=float(kolmogorov_c2),
        epsilon_boot=boot,
    )


@dataclass(frozen=True)
class Plateau:
    """Plateau value of ε(r) over an inertial range.

    Attributes
    ----------
    epsilon : float
        Plateau ε, m²/s³.
    se_epsilon : float
        Its standard error, m²/s³: the spread over bootstrap replicates when the profile
        has them (which accounts for correlated bins and for picking the maximum), else
        from the per-bin errors taken as independent (mean) or the error at the
        maximum (max), which both understate it.
    method : str
        "mean" or "max".
    r_min, r_max : float
        The range searched, m.
    n_bins : int
        Bins with a finite ε inside the range.
    r_at_max : float
        Separation of the maximum, m (NaN for "mean").
    epsilon_paper_caption : float
        The same plateau of the uncorrected S2^{3/2}/r, m²/s³ (= C2^{3/2}·epsilon).
    replicates : ndarray, shape (R,), or None
        The plateau ε of each bootstrap replicate of the profile, m²/s³ (None without
        them, or where one is not finite): what pairs this plateau with another
        measurement's of the same snapshots.
    """

    epsilon: float
    se_epsilon: float
    method: str
    r_min: float
    r_max: float
    n_bins: int
    r_at_max: float
    epsilon_paper_caption: float
    replicates: np.ndarray | None = None


def plateau_epsilon(
    profile: DissipationProfile,
    *,
    r_min: float,
    r_max: float,
    method: Literal["mean", "max"] = "mean",
) -> Plateau:
    """ε from the plateau of ε(r) over r_min ≤ r ≤ r_max (the chosen inertial range).

    Parameters
    ----------
    profile : DissipationProfile
        ε(r).
    r_min, r_max : float
        Inertial range, m, 0 < r_min < r_max. Choose it where ε(r) is flat (e.g.
        20η < r < 0.2 L_int); nothing here checks flatness.
    method : {"mean", "max"}
        Mean of ε(r) over the range (paper, Table 3) or its maximum (docs/claims.md
        #11; biased upward by noise when the plateau is flat).

    Returns
    -------
    Plateau
    """
    if not 0 < r_min < r_max:
        raise ValueError(f"need 0 < r_min < r_max, got r_min={r_min}, r_max={r_max}")
    if method not in ("mean", "max"):
        raise ValueError(f"method must be 'mean' or 'max', got {method!r}")
    r = profile.r
    inside = (r >= r_min) & (r <= r_max) & np.isfinite(profile.epsilon)
    n = int(np.count_nonzero(inside))
    if n == 0:
        raise ValueError(f"no bin with a finite ε in [{r_min}, {r_max}] m")
    eps = profile.epsilon[inside]
    caption = profile.epsilon_paper_caption[inside]
    if method == "mean":
        value, value_caption, r_at = float(eps.mean()), float(caption.mean()), np.nan
        se = float(np.sqrt(np.sum(profile.se_epsilon[inside] ** 2)) / n)
    else:
        i = int(np.argmax(eps))
        value, value_caption = float(eps[i]), float(caption[i])
        r_at = float(r[inside][i])
        se = float(profile.se_epsilon[inside][i])
    reps = None
    if profile.epsilon_boot is not None:
        boot = profile.epsilon_boot[:, inside]
        if np.all(np.isfinite(boot)):
            reps = boot.mean(axis=1) if method == "mean" else boot.max(axis=1)
            se = float(np.std(reps, ddof=1))
        else:
            logger.warning("bootstrap ε has non-finite values in range; using per-bin errors")
    return Plateau(
        epsilon=value,
        se_epsilon=se,
        method=method,
        r_min=float(r_min),
        r_max=float(r_max),
        n_bins=n,
        r_at_max=r_at,
        epsilon_paper_caption=value_caption,
        replicates=reps,
    )


@dataclass(frozen=True)
class TurbulenceScales:
    """Scales derived from u′ (rms of one component) and ε (docs/flow.md §4).

    Attributes
    ----------
    u_prime : float
        m/s.
    epsilon : float
        m²/s³.
    nu : float
        Kinematic viscosity, m²/s.
    eta : float
        Kolmogorov length (ν³/ε)^{1/4}, m.
    tau_eta : float
        Kolmogorov time (ν/ε)^{1/2}, s.
    u_eta : float
        Kolmogorov velocity (εν)^{1/4}, m/s.
    taylor_lambda : float
        Taylor microscale sqrt(15 ν u′²/ε), m.
    re_lambda : float
        u′ λ/ν.
    l_int : float
        u′³/ε (the paper's integral length), m.
    """

    u_prime: float
    epsilon: float
    nu: float
    eta: float
    tau_eta: float
    u_eta: float
    taylor_lambda: float
    re_lambda: float
    l_int: float


def turbulence_scales(u_prime: float, epsilon: float, *, nu: float = NU_WATER) -> TurbulenceScales:
    """Kolmogorov and Taylor scales from u′ and ε.

    Parameters
    ----------
    u_prime : float
        rms of one velocity component, m/s, > 0.
    epsilon : float
        Dissipation rate, m²/s³, > 0.
    nu : float
        Kinematic viscosity, m²/s (default 1e-6, water as in the paper).
    """
    for name, v in (("u_prime", u_prime), ("epsilon", epsilon), ("nu", nu)):
        if not (np.isfinite(v) and v > 0):
            raise ValueError(f"{name} must be finite and > 0, got {v}")
    lam = float(np.sqrt(15.0 * nu * u_prime**2 / epsilon))
    return TurbulenceScales(
        u_prime=float(u_prime),
        epsilon=float(epsilon),
        nu=float(nu),
        eta=float((nu**3 / epsilon) ** 0.25),
        tau_eta=float(np.sqrt(nu / epsilon)),
        u_eta=float((epsilon * nu) ** 0.25),
        taylor_lambda=lam,
        re_lambda=float(u_prime * lam / nu),
        l_int=float(u_prime**3 / epsilon),
    )
