"""The Δt³ bias of the multi-Δt fit against the truth of its own pairs, with a paired
bootstrap error (docs/statistics.md §4).

On a flow with an energy flux, ⟨q⟩ = N + S2Δt² + βΔt³ + … with β = ⟨δu_L δa_L⟩, and the
fit c₁Δt² + c₂ returns c₁ = S2 + γβ + …, γ the coefficient of Δt² in the fit's (weighted)
line through Δt³. :func:`c1_bias` measures c₁/truth − 1 on trajectories of particles
followed from a shared start, the truth being S2 of their exact velocities at t over the
same pairs. The fit's bootstrap over snapshots and the truth's use the same weights (the
same seed, one stratum of M snapshots in both), so the error is that of the difference:
what the fit and the truth share (which eddies the snapshots caught) cancels, and a bias
of a percent is measurable with tens of snapshots.
"""

import numpy as np

from ptv.bins import LogBins
from ptv.stats.structure import structure_function, time_resolved_sums
from simulator.particles import Box


def dt3_gamma(dt: np.ndarray) -> float:
    """γ of a Δt set, s: the least-squares line c₁Δt² + c₂ through βΔt³ has c₁ = γβ.

    docs/statistics.md §4 gives γ/τ_η = 0.155, 0.218, 0.243 for the Table 4 sets.
    """
    dt = np.asarray(dt, dtype=float)
    design = np.stack([dt**2, np.ones_like(dt)], axis=1)
    (gamma, _), *_ = np.linalg.lstsq(design, dt**3, rcond=None)
    return float(gamma)


def c1_bias(
    times: np.ndarray,
    measured: np.ndarray,
    start: np.ndarray,
    velocity: np.ndarray,
    columns: np.ndarray,
    *,
    region: Box,
    bins: LogBins,
    binning: str,
    n_boot: int,
    rng: np.random.SeedSequence,
) -> dict:
    """The bias of the multi-Δt c₁ against the sample truth of its pairs, per bin.

    Parameters
    ----------
    times : ndarray, shape (T,)
        Times after the shared start, s; times[0] = 0.
    measured : ndarray, shape (M, T, N, 3)
        Measured positions of N particles in each of M snapshots at those times, m.
    start, velocity : ndarray, shape (M, N, 3)
        Their exact positions (m) and velocities (m/s) at t.
    columns : ndarray of int, shape (K,)
        The times (indices into ``times``) of the Δt set fitted.
    region : Box
        Analysis volume: the pairs of the particles measured inside it at t.
    bins : LogBins
    binning : {"start", "midpoint"}
    n_boot : int
        Bootstrap replicates over snapshots.
    rng : numpy.random.SeedSequence
        Seeds the bootstrap of the fit and, identically, of the truth (paired).

    Returns
    -------
    dict
        ``r`` (B,) mean separation of the fit's pairs, m; ``bias`` (B,) c₁/truth − 1;
        ``se`` (B,) its paired bootstrap error; ``fitted`` (B,) bool; ``gamma_weighted``
        (B,) the γ of the fit's weights (:func:`weighted_gamma`), s.
    """
    dt = np.asarray(times)[columns]
    fit_snapshots, truth_snapshots = [], []
    for m in range(measured.shape[0]):
        inside = region.contains(measured[m, 0])
        displacement = (measured[m][columns] - measured[m, :1])[:, inside]
        fit_snapshots.append((measured[m, 0][inside], np.moveaxis(displacement, 0, 1)))
        truth_snapshots.append((start[m][inside], velocity[m][inside][:, None, :]))
    fit = structure_function(
        time_resolved_sums(fit_snapshots, bins, binning=binning), dt, n_boot=n_boot, rng=rng
    )
    truth_sums = time_resolved_sums(truth_snapshots, bins)
    truth = truth_sums.mean[:, 0]
    truth_boot = truth_sums.bootstrap_means(n_boot, rng=rng)[:, :, 0]
    with np.errstate(invalid="ignore", divide="ignore"):
        relative_boot = fit.s2_boot / truth_boot - 1
        se = np.nanstd(relative_boot, axis=0, ddof=1)
        return {
            "r": fit.r,
            "bias": fit.s2 / truth - 1,
            "se": se,
            "fitted": fit.fitted,
            "gamma_weighted": weighted_gamma(dt, fit.se_raw_s2 * dt**2),
        }


def weighted_gamma(dt: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """γ of each bin under the fit's weights 1/σ_k²: the c₁ that a weighted line
    c₁Δt² + c₂ through Δt³ has (:func:`dt3_gamma` with
    weights), s.

    Parameters
    ----------
    dt : ndarray, shape (K,)
        Δt, s.
    sigma : ndarray, shape (B, K)
        Standard error of ⟨q⟩ per bin and Δt, m².

    Returns
    -------
    ndarray, shape (B,)
        NaN where a σ is not finite and positive.
    """
    out = np.full(sigma.shape[0], np.nan)
    for b, s in enumerate(sigma):
        if not np.all(np.isfinite(s) & (s > 0)):
            continue
        design = np.stack([dt**2, np.ones_like(dt)], axis=1) / s[:, None]
        (gamma, _), *_ = np.linalg.lstsq(design, dt**3 / s, rcond=None)
        out[b] = gamma
    return out


def at_separation(bias: dict, r_target: float) -> tuple[float, float, float, float]:
    """(r, bias, se, weighted γ) in the fitted bin nearest ``r_target`` (log distance);
    NaN if none."""
    ok = np.flatnonzero(bias["fitted"] & np.isfinite(bias["r"]) & np.isfinite(bias["bias"]))
    if not ok.size:
        return (np.nan,) * 4
    b = ok[np.argmin(np.abs(np.log(bias["r"][ok] / r_target)))]
    return tuple(float(bias[name][b]) for name in ("r", "bias", "se", "gamma_weighted"))
