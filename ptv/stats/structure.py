"""Noise-free longitudinal structure function S2(r) from displacements at several Δt.

For the measured displacements ΔX at Δt_k and separation r between two particles at
time t (docs/statistics.md §1),

    ⟨q⟩_k = ⟨[(ΔX_j − ΔX_i)·e]²⟩ = S2(r)·Δt_k² + N(r) + O(Δt³),

with N(r) = 4σ_∥²(1 − ρ_∥(r)) for temporally white noise. Per separation bin, the
multi-Δt fit gives S2 = c1 (noise removed) and N = c2; the raw ⟨q⟩_k/Δt_k² (what a
single-Δt PTV measurement reports) is kept beside it.

Data come per snapshot: `time_resolved_sums` (skip-frame: positions at t and the
displacements at all Δt of the same particles) or `double_frame_sums` (one run per Δt,
different snapshots per Δt). Both give a `SnapshotSums`, which `structure_function`
fits with errors from the bootstrap over snapshots (default) or the naive pair count.
"""

import logging
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from ptv.bins import LogBins
from ptv.stats.multidt import (
    fit_multi_dt,
    fit_multi_dt_bootstrap,
    select_dt,
    usable_bootstrap_bins,
)
from ptv.stats.pairs import PairSums, pair_sums
from ptv.stats.snapshots import SnapshotSums

__all__ = [
    "StructureFunction",
    "double_frame_sums",
    "structure_function",
    "time_resolved_sums",
]

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class StructureFunction:
    """Longitudinal S2 per separation bin from a multi-Δt fit.

    Attributes
    ----------
    r : ndarray, shape (B,)
        Mean pair separation in each bin, m (NaN where the bin is empty).
    dt : ndarray, shape (K,)
        Time separations, s.
    s2 : ndarray, shape (B,)
        Noise-free S2 = c1, m²/s²; NaN in bins that were not fitted.
    se_s2 : ndarray, shape (B,)
        Standard error of s2, m²/s².
    noise : ndarray, shape (B,)
        Noise term N = c2, m² (4σ_∥²(1 − ρ_∥) for white noise).
    se_noise : ndarray, shape (B,)
        Standard error of noise, m².
    chi2_dof : ndarray, shape (B,)
        χ²/(n − 2) of the fit (NaN for n = 2 or where not fitted).
    raw_s2 : ndarray, shape (B, K)
        ⟨q⟩_k/Δt_k², the single-Δt estimate, m²/s² (biased upward by N/Δt²).
    se_raw_s2 : ndarray, shape (B, K)
        Its standard error (bootstrap, or naive pair count), m²/s².
    n_pairs : ndarray of int64, shape (B, K)
        Pairs per bin and Δt over all snapshots.
    fitted : ndarray of bool, shape (B,)
        Bins with a fit.
    used : ndarray of bool, shape (K,)
        Δt values used in the fit.
    method : str
        The fit: "wls", "wls-bootstrap" or "gls-bootstrap".
    s2_boot : ndarray, shape (R, B), or None
        s2 refitted on each bootstrap replicate (bootstrap errors only; NaN where not
        fitted), to propagate errors into derived quantities such as ε.
    """

    r: np.ndarray
    dt: np.ndarray
    s2: np.ndarray
    se_s2: np.ndarray
    noise: np.ndarray
    se_noise: np.ndarray
    chi2_dof: np.ndarray
    raw_s2: np.ndarray
    se_raw_s2: np.ndarray
    n_pairs: np.ndarray
    fitted: np.ndarray
    used: np.ndarray
    method: str
    s2_boot: np.ndarray | None = None


def _snapshot_sums(x, d, bins: LogBins, *, shape: str, where: str, binning: str) -> PairSums:
    """Pair sums of one snapshot; errors name the snapshot (and the expected shape)."""
    d = np.asarray(d)
    if d.ndim != shape.count(",") + 1:
        raise ValueError(f"{where}: displacements must have shape {shape}, got {d.shape}")
    try:
        return pair_sums(x, d, bins, binning=binning)
    except ValueError as err:
        raise ValueError(f"{where}: {err}") from err


def time_resolved_sums(
    snapshots: Iterable[tuple[np.ndarray, np.ndarray]], bins: LogBins, *, binning: str = "start"
) -> SnapshotSums:
    """Per-snapshot pair sums for time-resolved (skip-frame) data: the same particles,
    from the same X(t), at every Δt.

    Parameters
    ----------
    snapshots : iterable of (positions, displacements)
        Per snapshot: positions X(t), shape (P, 3), m, and the displacements of the same
        particles at each of the K values of Δt, shape (P, K, 3), m.
    bins : LogBins
        Separation bins.
    binning : {"start", "midpoint"}
        Bin and project each pair on its separation at t (default), or on its chord
        midpoint at each Δt (:func:`ptv.stats.pairs.pair_sums`).

    Returns
    -------
    SnapshotSums
        K columns; one stratum, so that the bootstrap resamples the snapshots jointly
        over the Δt.

    Raises
    ------
    ValueError
        No snapshots, or a snapshot of the wrong shapes (the message names it).

    Examples
    --------
    Eight snapshots of 300 particles in a 2 cm cube, each followed over three Δt in an
    expanding flow u = a·x, every position with 5 µm of noise (the one at t shared by
    every Δt):

    >>> import numpy as np
    >>> import ptv
    >>> rng = np.random.default_rng(0)
    >>> a, noise = 10.0, 5e-6  # expansion rate, 1/s; position noise, m
    >>> dt = np.array([1e-3, 2e-3, 4e-3])  # s
    >>> def snapshot():  # X(t) (P, 3) and ΔX at every Δt (P, K, 3), m
    ...     x = rng.uniform(-0.01, 0.01, (300, 3))
    ...     at_t = rng.normal(0, noise, (300, 3))
    ...     moved = [a * x * step + rng.normal(0, noise, (300, 3)) - at_t for step in dt]
    ...     return x + at_t, np.stack(moved, axis=1)
    >>> sums = ptv.time_resolved_sums([snapshot() for _ in range(8)],
    ...                               ptv.LogBins(1e-3, 16e-3, 6))
    >>> sums.n_snapshots, sums.total_count.shape  # snapshots; (bins, Δt)
    (8, (6, 3))
    >>> fit = ptv.structure_function(sums, dt, rng=0)
    >>> bool(np.allclose(fit.s2 / fit.r**2, a**2, rtol=0.05))  # S2 = (a r)², m²/s²
    True
    """
    """Per-snapshot pair sums for time-resolved (skip-frame) data.

    Parameters
    ----------
    snapshots : iterable of (positions, displacements)
        positions, shape (P, 3), m: measured particle positions at t; displacements,
        shape (P, K, 3), m: ΔX = X(t + Δt_k) − X(t) of the same particles for each of
        the K Δt (the same particles at every Δt, see docs/statistics.md §3.3).
    bins : LogBins
        Separation bins.
    binning : {"start", "midpoint"}
        Pairs binned by their separation at t, or by their chord midpoint
        (:func:`ptv.stats.pairs.pair_sums`).

    Returns
    -------
    SnapshotSums
        M snapshots, one stratum.
    """
    sums = [
        _snapshot_sums(x, d, bins, shape="(P, K, 3)", where=f"snapshot {m}", binning=binning)
        for m, (x, d) in enumerate(snapshots)
    ]
    if not sums:
        raise ValueError("no snapshots given")
    return SnapshotSums.from_time_resolved(sums)


def double_frame_sums(
    runs: Sequence[Iterable[tuple[np.ndarray, np.ndarray]]],
    bins: LogBins,
    *,
    binning: str = "start",
) -> SnapshotSums:
    """Per-snapshot pair sums for double-frame data, one run per Δt.

    Parameters
    ----------
    runs : sequence of length K of iterables of (positions, displacements)
        runs[k] holds the snapshots taken at Δt_k: positions, shape (P, 3), m, at the
        first frame; displacements, shape (P, 3), m, to the second frame. Snapshots
        and particle numbers may differ between runs.
    bins : LogBins
        Separation bins.
    binning : {"start", "midpoint"}
        As in :func:`time_resolved_sums`.

    Returns
    -------
    SnapshotSums
        Column k from run k; one stratum per run.

    Examples
    --------
    Eight snapshots of 300 particles in a 2 cm cube per Δt, new particles for each, in
    an expanding flow u = a·x, with 5 µm of noise on each position:

    >>> import numpy as np
    >>> import ptv
    >>> rng = np.random.default_rng(0)
    >>> a, noise = 10.0, 5e-6  # expansion rate, 1/s; position noise, m
    >>> dt = np.array([1e-3, 2e-3, 4e-3])  # s
    >>> def snapshot(step):  # X(t) and ΔX, (P, 3) each, m
    ...     x = rng.uniform(-0.01, 0.01, (300, 3))
    ...     return x, a * x * step + rng.normal(0, np.sqrt(2) * noise, (300, 3))
    >>> runs = [[snapshot(step) for _ in range(8)] for step in dt]
    >>> sums = ptv.double_frame_sums(runs, ptv.LogBins(1e-3, 16e-3, 6))
    >>> sums.n_snapshots, sums.total_count.shape  # snapshots of every run; (bins, Δt)
    (24, (6, 3))
    >>> fit = ptv.structure_function(sums, dt, rng=0)
    >>> bool(np.allclose(fit.s2 / fit.r**2, a**2, rtol=0.05))  # S2 = (a r)², m²/s²
    True
    """
    out = [
        [
            _snapshot_sums(
                x, d, bins, shape="(P, 3)", where=f"run {k}, snapshot {m}", binning=binning
            )
            for m, (x, d) in enumerate(run)
        ]
        for k, run in enumerate(runs)
    ]
    return SnapshotSums.from_double_frame(out)


def _check_fit_options(sums, dt: np.ndarray, errors, method, min_pairs) -> None:
    """Refuse the options of :func:`structure_function` that it cannot fit with."""
    if not isinstance(sums, SnapshotSums):
        raise ValueError(f"sums must be a SnapshotSums, got {type(sums).__name__}")
    if dt.size != sums.n_columns:
        raise ValueError(f"sums have {sums.n_columns} Δt columns but dt has {dt.size} values")
    if errors not in ("bootstrap", "pairs"):
        raise ValueError(f"errors must be 'bootstrap' or 'pairs', got {errors!r}")
    if method not in ("wls", "gls"):
        raise ValueError(f"method must be 'wls' or 'gls', got {method!r}")
    if errors == "pairs" and method == "gls":
        raise ValueError("method='gls' needs a covariance between Δt: use errors='bootstrap'")
    if not isinstance(min_pairs, int | np.integer) or min_pairs < 2:
        raise ValueError(f"min_pairs must be an integer >= 2, got {min_pairs!r}")


def structure_function(
    sums: SnapshotSums,
    dt: np.ndarray,
    *,
    errors: Literal["bootstrap", "pairs"] = "bootstrap",
    method: Literal["wls", "gls"] = "wls",
    n_boot: int = 200,
    use: np.ndarray | None = None,
    min_pairs: int = 20,
    rng: np.random.Generator | int | None = None,
    weights: np.ndarray | None = None,
) -> StructureFunction:
    """Fit ⟨q⟩ = S2·Δt² + N in every separation bin.

    Parameters
    ----------
    sums : SnapshotSums
        Per-snapshot sums with K columns, one per Δt.
    dt : ndarray, shape (K,)
        Time separations, s, at least 2 distinct.
    errors : {"bootstrap", "pairs"}
        "bootstrap": σ (or the covariance) of ⟨q⟩ and the errors of S2 from resampling
        snapshots (needs ≥ 2 snapshots per run); "pairs": σ² = Var(q)/N_pairs with
        analytic WLS errors, which treats pairs as independent and so underestimates.
    method : {"wls", "gls"}
        "wls" (default): weights 1/σ² from the bootstrap σ of each ⟨q⟩; the errors of
        S2 are the spread of the refitted S2 over replicates, which accounts for the
        correlation between Δt of time-resolved data. "gls": weights from the full
        bootstrap covariance between Δt (docs/statistics.md §3.3). With the covariance estimated
        from the same data GLS came out biased low on synthetic skip-frame data (≈ −0.4σ
        with 40 snapshots, −0.15σ with 1000; not regressed by a test) and no more
        precise than WLS, so it is not the default.
    n_boot : int
        Bootstrap replicates.
    use : ndarray of bool, shape (K,), or of int, optional
        Δt subset to fit (e.g. `largest_dt(dt, 3)`); raw_s2 is given for all.
    min_pairs : int
        A bin is fitted when every fitted Δt has at least this many pairs in total
        (and, with bootstrap, every replicate has one).
    rng : numpy.random.Generator, int or None
        Randomness of the bootstrap.
    weights : ndarray, shape (R, M), optional
        The bootstrap's snapshot weights, drawn beforehand
        (:meth:`ptv.stats.snapshots.SnapshotSums.bootstrap_weights`: in blocks where
        snapshots are correlated, and the same for every estimate of a run so that their
        replicates pair up); ``n_boot`` and ``rng`` are then not used.

    Returns
    -------
    StructureFunction

    Examples
    --------
    Eight snapshots of 300 particles in a 2 cm cube per Δt in an expanding flow u = a·x,
    where every pair has δu·e = a r: S2(r) = (a r)². Each position carries 5 µm of noise,
    which adds N = 4σ² to every ⟨q⟩ and biases the estimate of one Δt alone by N/Δt²;
    the multi-Δt fit removes it.

    >>> import numpy as np
    >>> import ptv
    >>> rng = np.random.default_rng(0)
    >>> a, noise = 10.0, 5e-6  # expansion rate, 1/s; position noise, m
    >>> dt = np.array([1e-3, 2e-3, 4e-3])  # s
    >>> def snapshot(step):  # X(t) and ΔX, (P, 3) each, m
    ...     x = rng.uniform(-0.01, 0.01, (300, 3))
    ...     return x, a * x * step + rng.normal(0, np.sqrt(2) * noise, (300, 3))
    >>> runs = [[snapshot(step) for _ in range(8)] for step in dt]
    >>> sums = ptv.double_frame_sums(runs, ptv.LogBins(1e-3, 16e-3, 6))
    >>> fit = ptv.structure_function(sums, dt, rng=0)
    >>> fit.method, fit.s2.shape  # one S2 per separation bin
    ('wls-bootstrap', (6,))
    >>> bool(np.allclose(fit.s2 / fit.r**2, a**2, rtol=0.05))  # m²/s²
    True
    >>> bool(fit.raw_s2[0, 0] > 1.3 * (a * fit.r[0]) ** 2)  # smallest r, smallest Δt
    True
    """
    dt = np.asarray(dt, dtype=np.float64)
    _check_fit_options(sums, dt, errors, method, min_pairs)
    idx = select_dt(use, dt)
    used = np.isin(np.arange(dt.size), idx)
    n_pairs = sums.total_count
    b = n_pairs.shape[0]
    y = sums.mean
    ok = np.all(n_pairs[:, idx] >= min_pairs, axis=1)

    if errors == "pairs":
        sigma = sums.naive_sem
        ok &= np.all(np.isfinite(sigma[:, idx]) & (sigma[:, idx] > 0), axis=1)
        se_y = sigma
        fit_name = "wls"
        y_boot = None
    else:
        gls = method == "gls"
        y_boot = (
            sums.bootstrap_means(n_boot, rng=rng)
            if weights is None
            else sums.weighted_means(weights)
        )
        with np.errstate(invalid="ignore"):
            se_y = np.std(y_boot, axis=0, ddof=1)
        fit_name = "gls-bootstrap" if gls else "wls-bootstrap"
        ok[ok] = usable_bootstrap_bins(dt, y_boot[:, ok], gls=gls, use=idx)

    s2 = np.full(b, np.nan)
    se_s2, noise, se_noise, chi2 = (np.full(b, np.nan) for _ in range(4))
    s2_boot = None if y_boot is None else np.full((y_boot.shape[0], b), np.nan)
    if np.any(ok):
        if y_boot is None:
            fit = fit_multi_dt(dt, y[ok], sigma=sigma[ok], use=idx)
        else:
            fit = fit_multi_dt_bootstrap(dt, y[ok], y_boot[:, ok], gls=gls, use=idx)
            s2_boot[:, ok] = fit.c1_boot
        s2[ok], se_s2[ok], noise[ok], se_noise[ok] = fit.c1, fit.se_c1, fit.c2, fit.se_c2
        chi2[ok] = fit.chi2_dof
    n_skip = int(np.count_nonzero(~ok))
    if n_skip:
        logger.info("structure function: %d of %d bins not fitted (too few pairs)", n_skip, b)
    logger.info("structure function: %s fit of %d bins on %d Δt", fit_name, b - n_skip, idx.size)
    dt2 = dt**2
    return StructureFunction(
        r=sums.mean_separation,
        dt=dt,
        s2=s2,
        se_s2=se_s2,
        noise=noise,
        se_noise=se_noise,
        chi2_dof=chi2,
        raw_s2=y / dt2,
        se_raw_s2=se_y / dt2,
        n_pairs=n_pairs,
        fitted=ok,
        used=used,
        method=fit_name,
        s2_boot=s2_boot,
    )
