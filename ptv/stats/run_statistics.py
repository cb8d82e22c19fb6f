"""Second-order statistics of a PTV run: S2(r), ε, the Δt subsets, the mean line, u′.

From the links of every Δt (:class:`ptv.stats.links.RunParticles`), restricted to those
whose X(t) lies in the analysis volume and that are not outliers (bin by X(t),
docs/statistics.md §2):

- S2(r) by the multi-Δt fit ⟨q⟩_k = S2·Δt_k² + N per log-spaced separation bin, errors
  by bootstrap over snapshots (:func:`ptv.stats.structure.structure_function`); the raw
  ⟨q⟩_k/Δt_k² per Δt and the noise term c2 = N(r) beside it. With a shared first frame
  (every Δt measured from the same frame a) S2 uses the particles linked at every Δt,
  less those whose displacements stray from a smooth path in Δt
  (:func:`ptv.tracking.linking.trajectory_residuals`), and the snapshots are resampled jointly over
  the Δt; otherwise every run's links, each run resampled on its own;
- ε(r) = (S2/C2)^{3/2}/r and the paper's uncorrected S2^{3/2}/r, and their plateau;
- the same fit on the paper's Δt subsets (:func:`ptv.stats.multidt.dt_subsets`) and
  their plateau ε;
- the spatially averaged mean displacement against Δt with its line αΔt + β0
  (:mod:`ptv.stats.mean_displacement`);
- u′ from the Eulerian variance fit Var ΔX = u′²Δt² + 2σ_b² per cell
  (:mod:`ptv.stats.eulerian`), whose intercept also estimates the position noise σ_b
  per component. The cell mean is taken over the run's snapshots and subtracted, so
  with few snapshots u′ comes out low by about the variance of a cell mean over them
  (rendered lem-10hz data: −4 % with 30 snapshots per Δt, −25 % with 3).
"""

import logging
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from ptv.bins import LogBins
from ptv.settings import StatisticsSettings
from ptv.stats.dissipation import DissipationProfile, Plateau, dissipation_profile, plateau_epsilon
from ptv.stats.eulerian import (
    EulerianFit,
    Grid,
    UPrime,
    cell_sums,
    eulerian_fit,
    eulerian_moments,
    u_prime,
    u_prime_replicates,
)
from ptv.stats.links import RunParticles, shared_snapshots
from ptv.stats.mean_displacement import (
    MeanDisplacement,
    mean_displacement,
    shared_mean_displacement,
)
from ptv.stats.multidt import dt_subsets
from ptv.stats.resampling import SnapshotBootstrap, block_length
from ptv.stats.snapshots import SnapshotSums
from ptv.stats.structure import (
    StructureFunction,
    double_frame_sums,
    structure_function,
    time_resolved_sums,
)
from ptv.tracking.linking import trajectory_residuals

__all__ = ["PtvStatistics", "S2Population", "Subset", "compute_statistics"]

log = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False)
class Subset:
    """The multi-Δt fit on a subset of the Δt values.

    Attributes
    ----------
    name : str
        "3 largest dt" or "smallest and largest dt".
    used : ndarray of bool, shape (K,)
        Δt used.
    structure : StructureFunction
        The fit.
    profile : DissipationProfile
        ε(r) of the fit.
    plateau : Plateau or None
        Plateau ε (None when no bin of the range was fitted).
    """

    name: str
    used: np.ndarray
    structure: StructureFunction
    profile: DissipationProfile
    plateau: Plateau | None


@dataclass(frozen=True, eq=False)
class S2Population:
    """The particles whose pairs enter S2 when every Δt shares frame a.

    Attributes
    ----------
    snapshot_ids : ndarray of int, shape (S,)
        Snapshots kept at every Δt.
    positions : tuple of S ndarray, shape (P_s, 3)
        X(t) of the particles linked at every Δt and not dropped by the trajectory test,
        m (in the calibration's frame).
    displacements : tuple of S ndarray, shape (P_s, K, 3)
        Their ΔX at every Δt, m.
    trajectory_outliers : int
        Particles linked at every Δt that the trajectory test dropped.
    """

    snapshot_ids: np.ndarray
    positions: tuple[np.ndarray, ...]
    displacements: tuple[np.ndarray, ...]
    trajectory_outliers: int

    @property
    def count(self) -> int:
        """Particles in the population."""
        return sum(len(x) for x in self.positions)


@dataclass(frozen=True, eq=False)
class PtvStatistics:
    """Second-order statistics of the measured displacements.

    Attributes
    ----------
    dt_index : ndarray of int, shape (K,)
        Dataset Δt indices the statistics use (runs with links).
    dt : ndarray, shape (K,)
        Their Δt, s.
    bins : LogBins
        Separation bins.
    structure : StructureFunction
        S2 = c1 (m²/s²), noise c2 (m²), raw ⟨q⟩/Δt² per Δt, errors, pair counts.
    profile : DissipationProfile
        ε(r) = (S2/C2)^{3/2}/r and the paper's S2^{3/2}/r, m²/s³.
    plateau : Plateau or None
        Plateau ε over ``settings.plateau`` (None when no bin there was fitted).
    subsets : dict of str to Subset
        The paper's Δt subset study (only subsets smaller than the full set).
    mean_displacement : MeanDisplacement
        Linearity check of ⟨ΔX⟩ in Δt.
    grid : Grid
        Eulerian cells.
    eulerian : EulerianFit
        Per-cell fits of ⟨ΔX⟩ and Var ΔX against Δt.
    u_prime : UPrime or None
        u′ from the fitted variance (None when no cell could be fitted).
    position_noise : ndarray, shape (3,)
        σ_b per component from the variance intercept 2σ_b², averaged over cells, m
        (NaN where the average intercept is negative).
    errors : str
        "bootstrap" or "pairs" (when a run has fewer than two snapshots).
    n_snapshots : ndarray of int, shape (K,)
        Snapshots per Δt used.
    population : S2Population or None
        The particles of S2 with a shared first frame (None: each run's own links).
    bootstrap : SnapshotBootstrap or None
        The replicates every estimate was refitted on (None with ``errors`` "pairs").
    """

    dt_index: np.ndarray
    dt: np.ndarray
    bins: LogBins
    structure: StructureFunction
    profile: DissipationProfile
    plateau: Plateau | None
    subsets: dict[str, Subset]
    mean_displacement: MeanDisplacement
    grid: Grid
    eulerian: EulerianFit
    u_prime: UPrime | None
    position_noise: np.ndarray
    errors: str
    n_snapshots: np.ndarray
    population: S2Population | None = None
    bootstrap: SnapshotBootstrap | None = None


def _plateau(
    profile: DissipationProfile, settings: StatisticsSettings, what: str
) -> Plateau | None:
    """The plateau ε of ``profile`` over ``settings.plateau``; None (logged) if no bin there."""
    try:
        return plateau_epsilon(
            profile,
            r_min=settings.plateau[0],
            r_max=settings.plateau[1],
            method=settings.plateau_method,  # type: ignore[arg-type]
        )
    except ValueError as err:
        log.warning("%s: no plateau ε (%s)", what, err)
        return None


def _eulerian(
    runs: Sequence[RunParticles],
    dt: np.ndarray,
    settings: StatisticsSettings,
    bootstrap: SnapshotBootstrap | None,
):
    """Grid, per-cell fit, u′ (or None; with its bootstrap replicates when ``bootstrap``
    is given) and σ_b per component (NaN where not measurable)."""
    x, d = [], []
    for run in runs:
        sel = run.used
        x.append(run.positions[sel])
        d.append(run.displacements[sel])
    lower, upper = settings.analysis_volume
    grid = Grid(lower, upper, settings.eulerian_cells)
    moments = eulerian_moments(x, d, dt, grid)
    fit = eulerian_fit(moments, min_count=settings.min_cell_count)
    if not fit.valid.any() and grid.n_cells > 1:
        log.warning(
            "no Eulerian cell of %s holds %d displacements at every Δt; using one cell",
            "×".join(map(str, settings.eulerian_cells)),
            settings.min_cell_count,
        )
        grid = Grid(lower, upper, (1, 1, 1))
        moments = eulerian_moments(x, d, dt, grid)
        fit = eulerian_fit(moments, min_count=settings.min_cell_count)
    if fit.valid.any():
        up = u_prime(fit)
        if bootstrap is not None:
            sums = [cell_sums(run.snapshot_arrays(), grid) for run in runs]
            weights = [_run_weights(run, i, bootstrap) for i, run in enumerate(runs)]
            up = replace(up, replicates=u_prime_replicates(sums, weights, moments, fit))
        noise = np.nanmean(fit.noise[fit.valid], axis=0)
        with np.errstate(invalid="ignore"):
            sigma_b = np.sqrt(np.where(noise >= 0, noise / 2.0, np.nan))
    else:
        log.warning("no Eulerian cell could be fitted: no u'")
        up, sigma_b = None, np.full(3, np.nan)
    return grid, fit, up, sigma_b


def _run_weights(run: RunParticles, index: int, bootstrap: SnapshotBootstrap) -> np.ndarray:
    """The bootstrap weights of a run's kept snapshots, shape (R, M_k): the column of the
    snapshot in its stratum (the run's own, or the one every Δt shares); a snapshot the
    strata do not hold (linked at this Δt but not at every Δt) counts once in every
    replicate."""
    strata = bootstrap.snapshot_ids
    stratum = 0 if len(strata) == 1 else index
    offset = sum(len(ids) for ids in strata[:stratum])
    column = {int(m): offset + i for i, m in enumerate(strata[stratum])}
    out = np.ones((bootstrap.replicates, len(run.snapshot_ids)))
    for j, m in enumerate(run.snapshot_ids.tolist()):
        if m in column:
            out[:, j] = bootstrap.weights[:, column[m]]
    return out


def _consistent(joined, dt: np.ndarray, settings: StatisticsSettings):
    """The joined particles whose trajectory residual is not an outlier.

    Parameters
    ----------
    joined : list of (ndarray (P, 3), ndarray (P, K, 3))
        X(t) and ΔX at every Δt per snapshot (:func:`shared_snapshots`), m.
    dt : ndarray, shape (K,)
        s.
    settings : StatisticsSettings
        ``trajectory_threshold``: the limit in multiples of the median residual.

    Returns
    -------
    list of (ndarray, ndarray)
        The same snapshots without the particles above the limit.
    """
    residuals = [trajectory_residuals(dt, d) for _, d in joined]
    limit = settings.trajectory_threshold * np.median(np.concatenate(residuals))
    kept = [(x[r <= limit], d[r <= limit]) for (x, d), r in zip(joined, residuals, strict=True)]
    dropped = sum(len(x) for x, _ in joined) - sum(len(x) for x, _ in kept)
    log.info(
        "%d particle(s) dropped: trajectory residual above %.3g µm (%g × the median)",
        dropped,
        limit * 1e6,
        settings.trajectory_threshold,
    )
    return kept


def _usable(runs: Sequence[RunParticles], settings: StatisticsSettings) -> list[RunParticles]:
    """The runs with at least two used links (the others dropped with a warning)."""
    usable = []
    for run in runs:
        n = int(np.count_nonzero(run.used))
        if n < 2:
            log.warning(
                "Δt_%d = %.4g s dropped from the statistics: %d link(s) in the analysis volume",
                run.k,
                run.dt,
                n,
            )
        else:
            usable.append(run)
    if len(usable) < 2:
        raise ValueError(
            f"only {len(usable)} Δt value(s) with particle links in the analysis volume "
            f"{settings.analysis_volume} m: the multi-Δt method needs at least two "
            "(are the frames empty, or the calibration, volume or max speed wrong? Set "
            "[statistics] analysis_volume to where the particles are, or ask for positions "
            "and links only: synptv ptv --positions-only)"
        )
    return usable


@dataclass(frozen=True)
class _Sample:
    """What the multi-Δt fit is computed from: pair sums, their snapshots, the particles."""

    sums: SnapshotSums
    n_snapshots: np.ndarray
    mean_displacement: MeanDisplacement
    population: S2Population | None
    snapshot_ids: tuple[np.ndarray, ...]


def _shared_sample(
    usable: Sequence[RunParticles], dt: np.ndarray, settings: StatisticsSettings
) -> _Sample:
    """The particles linked at every Δt (shared frame a) and their pair sums."""
    ids, joined = shared_snapshots(usable)
    if not joined:
        raise ValueError("no snapshot has particles linked at every Δt")
    linked = sum(len(x) for x, _ in joined)
    log.info(
        "shared first frame: %d particles linked at every Δt in %d snapshots", linked, len(joined)
    )
    if settings.trajectory_threshold is not None and len(usable) >= 4:
        joined = _consistent(joined, dt, settings)
    line = shared_mean_displacement(joined, dt)
    if line is None:
        log.warning(
            "mean displacement: too few snapshots (%d) for the covariance of the %d "
            "shared means; each Δt's links are averaged on their own",
            len(joined),
            len(usable),
        )
        line = mean_displacement(usable)
    return _Sample(
        sums=time_resolved_sums(joined, settings.bins, binning=settings.binning),
        n_snapshots=np.full(len(usable), len(joined), dtype=np.int64),
        mean_displacement=line,
        population=S2Population(
            snapshot_ids=ids,
            positions=tuple(x for x, _ in joined),
            displacements=tuple(d for _, d in joined),
            trajectory_outliers=linked - sum(len(x) for x, _ in joined),
        ),
        snapshot_ids=(ids,),
    )


def _independent_sample(usable: Sequence[RunParticles], settings: StatisticsSettings) -> _Sample:
    """Every run's own links (one independent experiment per Δt) and their pair sums."""
    per_run = [r.snapshot_arrays() for r in usable]
    return _Sample(
        sums=double_frame_sums(per_run, settings.bins, binning=settings.binning),
        n_snapshots=np.array([len(p) for p in per_run], dtype=np.int64),
        mean_displacement=mean_displacement(usable),
        population=None,
        snapshot_ids=tuple(r.snapshot_ids.copy() for r in usable),
    )


def _bootstrap(sample: _Sample, settings: StatisticsSettings) -> SnapshotBootstrap:
    """The snapshot weights every estimate of the run is refitted on, in blocks as long
    as the correlation of successive snapshots asks (or ``settings.snapshot_block``)."""
    correlation = sample.sums.correlation()
    block = settings.snapshot_block
    if block is None:
        block = block_length(correlation)
    if block > 1:
        log.info(
            "successive snapshots correlate (lag-one %.2f, τ = %.2g snapshots): the bootstrap "
            "draws blocks of %d consecutive snapshots; %.3g effective snapshots",
            correlation.rho1,
            correlation.tau,
            block,
            correlation.effective_snapshots,
        )
    weights = sample.sums.bootstrap_weights(settings.n_boot, rng=settings.seed, block=block)
    return SnapshotBootstrap(weights, block, correlation, sample.snapshot_ids, settings.seed)


def compute_statistics(
    runs: Sequence[RunParticles],
    settings: StatisticsSettings,
    *,
    shared_first_frame: bool = False,
    subsets: dict[str, np.ndarray] | None = None,
) -> PtvStatistics:
    """Multi-Δt statistics of the links in the analysis volume (module docstring).

    Parameters
    ----------
    runs : sequence of RunParticles
        One per Δt (runs without links are dropped with a warning).
    settings : StatisticsSettings
        Analysis volume, bins, plateau range, C2, bootstrap, Eulerian cells.
    shared_first_frame : bool
        The runs share their first frames (:attr:`ptv.io.dataset.Dataset.shared_first_frame`):
        S2 then uses the particles linked at every Δt, with snapshots resampled jointly
        over all Δt (:func:`ptv.stats.links.shared_snapshots`,
        :func:`ptv.stats.structure.time_resolved_sums`); otherwise every run's links,
        each run resampled on its own.
    subsets : dict of str to ndarray of bool, shape (K,), optional
        Δt subsets to refit on the same pairs, by name (default: the paper's,
        :func:`ptv.stats.multidt.dt_subsets`); K counts the runs with links.

    Returns
    -------
    PtvStatistics

    Raises
    ------
    ValueError
        Fewer than two Δt with links in the analysis volume.

    Examples
    --------
    Runs at three Δt of eight snapshots of 300 particles in a 2 cm cube, in an expanding
    flow u = a·x with 5 µm of noise on each position: S2(r) = (a r)² is found free of the
    noise, and u′ = a L/√12 per component over the cube of side L.

    >>> import numpy as np
    >>> import ptv
    >>> rng = np.random.default_rng(0)
    >>> a, noise, side = 10.0, 5e-6, 0.02  # 1/s, m, m
    >>> dt = np.array([1e-3, 2e-3, 4e-3])  # s
    >>> def run(k):  # the links of Δt_k, 8 snapshots of 300
    ...     x = rng.uniform(-side / 2, side / 2, (8, 300, 3))
    ...     d = a * x * dt[k] + rng.normal(0, np.sqrt(2) * noise, x.shape)
    ...     snapshots = np.arange(8)
    ...     return ptv.RunParticles(
    ...         k=k, dt=dt[k], positions=x.reshape(-1, 3), displacements=d.reshape(-1, 3),
    ...         offsets=300 * np.arange(9), snapshot_ids=snapshots,
    ...         detections=np.full((8, 2, 2), 300), matches=np.full((8, 2), 300),
    ...         links=np.full(8, 300), processed=snapshots,
    ...         in_analysis=np.ones(2400, dtype=bool), outlier=np.zeros(2400, dtype=bool))
    >>> settings = ptv.StatisticsSettings(
    ...     analysis_volume=((-side / 2,) * 3, (side / 2,) * 3),
    ...     r_min=1e-3, r_max=16e-3, n_bins=6, plateau=(2e-3, 8e-3), n_boot=50,
    ...     eulerian_cells=(1, 1, 1))
    >>> found = ptv.compute_statistics([run(k) for k in range(3)], settings)
    >>> s2 = found.structure
    >>> bool(np.allclose(s2.s2 / s2.r**2, a**2, rtol=0.05))  # m²/s²
    True
    >>> bool(abs(found.u_prime.value / (a * side / np.sqrt(12)) - 1) < 0.02)  # m/s
    True
    """
    usable = _usable(runs, settings)
    dt = np.array([r.dt for r in usable])
    bins = settings.bins
    if shared_first_frame:
        sample = _shared_sample(usable, dt, settings)
    else:
        sample = _independent_sample(usable, settings)
    errors = "bootstrap"
    bootstrap = None
    if sample.n_snapshots.min() < 2:
        log.warning(
            "a Δt has a single snapshot: S2 errors from the pair count (they underestimate)"
        )
        errors = "pairs"
    else:
        bootstrap = _bootstrap(sample, settings)

    def fit(use=None) -> StructureFunction:
        return structure_function(
            sample.sums,
            dt,
            errors=errors,
            n_boot=settings.n_boot,
            use=use,
            rng=settings.seed,
            weights=None if bootstrap is None else bootstrap.weights,
        )

    def profile_of(sf: StructureFunction) -> DissipationProfile:
        return dissipation_profile(
            np.where(np.isfinite(sf.r), sf.r, bins.centres),
            sf.s2,
            se_s2=sf.se_s2,
            s2_boot=sf.s2_boot,
            kolmogorov_c2=settings.kolmogorov_c2,
        )

    structure = fit()
    profile = profile_of(structure)
    refits = {}
    for name, use in (dt_subsets(dt) if subsets is None else subsets).items():
        sf = fit(use)
        prof = profile_of(sf)
        refits[name] = Subset(name, use, sf, prof, _plateau(prof, settings, name))
    grid, eul, up, sigma_b = _eulerian(usable, dt, settings, bootstrap)
    return PtvStatistics(
        dt_index=np.array([r.k for r in usable], dtype=np.int64),
        dt=dt,
        bins=bins,
        structure=structure,
        profile=profile,
        plateau=_plateau(profile, settings, "all Δt"),
        subsets=refits,
        mean_displacement=sample.mean_displacement
        if bootstrap is None or bootstrap.block == 1
        else sample.mean_displacement.with_correlated_snapshots(bootstrap.correlation.tau),
        grid=grid,
        eulerian=eul,
        u_prime=up,
        position_noise=sigma_b,
        errors=errors,
        n_snapshots=sample.n_snapshots,
        population=sample.population,
        bootstrap=bootstrap,
    )
