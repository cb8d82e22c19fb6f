"""What the statistics of a rendered dataset should recover: sample truth and exact D_LL.

- the sample-truth S2(r): the exact velocities at t of the particles in the analysis
  volume, over all snapshots of all Δt runs, in the PTV run's separation bins; and, per
  measurement, over the pairs its S2 actually used (:func:`population_truth`);
- the exact D_LL(r) of the spectrum at the same separations;
- the plateau ε of the same estimator (ε(r) = (S2/C2)^{3/2}/r averaged over the
  plateau range) applied to both, beside the input ε: the estimator on the exact D_LL
  is what the PTV plateau ε should match, and its gap to the input ε is the
  finite-Reynolds plateau deficit;
- references that share no code with the stack (:mod:`validation.truth.independent`):
  the S2 of a subsample of every snapshot by brute force, with the consistency of the
  sample truth with it, and the input ε times the plateau deficit from an independent
  quadrature of the spectrum and estimator.
"""

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ptv.settings import StatisticsSettings
from ptv.stats.dissipation import dissipation_profile, plateau_epsilon
from ptv.stats.pairs import PairSums, pair_sums
from ptv.stats.resampling import SnapshotBootstrap, autocorrelation_time, block_length
from ptv.stats.run_statistics import S2Population
from ptv.stats.snapshots import cluster_mean
from simulator.particles import Box
from simulator.turbulence import TurbulenceParameters
from validation.truth.exact import ExactStructure
from validation.truth.independent import (
    check_edges,
    collect,
    log_edges,
    plateau_epsilon_reference,
    subsample_sums,
)
from validation.truth.pair_noise import PairNoiseSums
from validation.truth.sample import sample_structure_function
from validation.truth.truth_file import TruthFile

#: The brute-force reference: particles per group, groups per snapshot, seed.
REFERENCE_PARTICLES = 300
REFERENCE_GROUPS = 2
REFERENCE_SEED = 0


@dataclass(frozen=True)
class FlowTruth:
    """Reference statistics in the PTV run's separation bins.

    Attributes
    ----------
    r : ndarray, shape (B,)
        Mean separation of the sample pairs per bin, m (NaN where empty).
    s2_sample : ndarray, shape (B,)
        Sample-truth S2, m²/s².
    se_s2_sample : ndarray, shape (B,)
        Its standard error over the snapshots, m²/s².
    s2_exact : ndarray, shape (B,)
        Exact D_LL of the spectrum at ``r``, m²/s².
    epsilon_input : float
        The prescribed ε, m²/s³.
    epsilon_exact : float
        Plateau estimator on the exact D_LL, m²/s³.
    epsilon_sample : float
        Plateau estimator on the sample truth, m²/s³.
    u_rms_sample : float
        RMS velocity component of the particles in the analysis volume at t, m/s.
    parameters : dict
        u', ε, ν and the derived η, τ_η, R_λ, L_int.
    r_reference, s2_reference, se_s2_reference : ndarray, shape (B,)
        Mean separation (m), S2 and its subsampling error (m²/s²) of the brute-force
        reference (:func:`validation.truth.independent.brute_force_s2`).
    sample_over_reference : (float, float)
        ``s2_sample`` over ``s2_reference``, the mean over the bins weighted by the
        reference's precision, and its subsampling error: 1 within a few errors unless
        the shared pair sums are wrong.
    epsilon_reference : float
        The input ε times the plateau deficit from an independent quadrature of the
        spectrum, the plateau of (D_LL/C2)^{3/2}/r taken as the run takes it at
        ``r_reference``, m²/s³.
    snapshot_correlation : dict
        How correlated the sample-truth S2 of successive snapshots is
        (:meth:`ptv.stats.resampling.SnapshotCorrelation.as_dict`) and the ``block`` of
        snapshots every rung's bootstrap draws together for it
        (:func:`ptv.stats.resampling.block_length`), one for the whole run so that the
        rungs' replicates pair up.
    """

    r: np.ndarray
    s2_sample: np.ndarray
    se_s2_sample: np.ndarray
    s2_exact: np.ndarray
    epsilon_input: float
    epsilon_exact: float
    epsilon_sample: float
    u_rms_sample: float
    parameters: dict
    r_reference: np.ndarray
    s2_reference: np.ndarray
    se_s2_reference: np.ndarray
    sample_over_reference: tuple[float, float]
    epsilon_reference: float
    snapshot_correlation: dict

    def as_dict(self) -> dict:
        """JSON-able form (NaN → None)."""

        def listed(a):
            return [None if not np.isfinite(v) else float(v) for v in a]

        return {
            "r": listed(self.r),
            "s2_sample": listed(self.s2_sample),
            "se_s2_sample": listed(self.se_s2_sample),
            "s2_exact": listed(self.s2_exact),
            "epsilon_input": self.epsilon_input,
            "epsilon_exact_d_ll": self.epsilon_exact,
            "epsilon_sample_truth": self.epsilon_sample,
            "plateau_deficit": self.epsilon_exact / self.epsilon_input - 1.0,
            "u_rms_sample": self.u_rms_sample,
            "parameters": self.parameters,
            "r_reference": listed(self.r_reference),
            "s2_reference": listed(self.s2_reference),
            "se_s2_reference": listed(self.se_s2_reference),
            "sample_over_reference": list(self.sample_over_reference),
            "epsilon_reference": self.epsilon_reference,
            "snapshot_correlation": self.snapshot_correlation,
        }


def _plateau(r, s2, settings: StatisticsSettings) -> float:
    profile = dissipation_profile(r, s2, kolmogorov_c2=settings.kolmogorov_c2)
    return plateau_epsilon(
        profile,
        r_min=settings.plateau[0],
        r_max=settings.plateau[1],
        method=settings.plateau_method,  # type: ignore[arg-type]
    ).epsilon


def _pooled(per_snapshot: Sequence[PairSums]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean separation, pair-weighted S2 and its cluster standard error (snapshots as
    clusters) of per-snapshot pair sums, per bin (NaN where empty)."""
    sums = per_snapshot[0]
    for s in per_snapshot[1:]:
        sums = sums + s
    weights = np.array([s.count for s in per_snapshot], dtype=float)
    s2, se = cluster_mean(weights, np.array([s.mean[:, 0] for s in per_snapshot]))
    return sums.mean_separation, s2, se


@dataclass(frozen=True)
class PopulationTruth:
    """The truth of the particles one measurement's S2 used.

    Attributes
    ----------
    s2_sample : ndarray, shape (B,)
        S2 of the exact velocities at t of the true particles behind the measured ones,
        m²/s² (NaN where no pair).
    se_s2_sample : ndarray, shape (B,)
        Its cluster standard error over the snapshots, m²/s².
    dt : ndarray, shape (K,)
        The time separations, s.
    displacement_noise : ndarray, shape (K, 3)
        RMS of measured − true ΔX per Δt and component over the associated particles,
        m (in the world frame).
    pair_noise : ndarray, shape (K, B)
        ⟨[(δ_j − δ_i)·e]²⟩ over the pairs of the associated particles per Δt and
        separation bin, δ their ΔX errors, m² (:mod:`validation.truth.pair_noise`): the
        noise term this S2's c2 should show (NaN where no pair).
    particles : int
        Measured particles of the population.
    associated : int
        Those with a true particle within the association radius (the others, ghosts,
        are left out; two measured particles near one true particle count as one in S2).
    se_c1_over_truth : ndarray, shape (B,), or None
        The paired standard error of the measurement's c1 over ``s2_sample``: the spread
        of their ratio over the bootstrap replicates of the measurement, the truth
        refitted on the same snapshot draws, so that which eddies the snapshots caught
        cancels (None without the measurement's replicates).
    """

    s2_sample: np.ndarray
    se_s2_sample: np.ndarray
    dt: np.ndarray
    displacement_noise: np.ndarray
    pair_noise: np.ndarray
    particles: int
    associated: int
    se_c1_over_truth: np.ndarray | None = None

    def as_dict(self) -> dict:
        """JSON-able form (NaN → None); ``dt`` and ``displacement_noise_m`` as in
        ``detection.json``, so either feeds
        :func:`validation.score.noise_prediction.predicted_noise`."""

        def listed(a):
            return [None if not np.isfinite(v) else float(v) for v in a]

        return {
            "s2_sample": listed(self.s2_sample),
            "se_s2_sample": listed(self.se_s2_sample),
            "dt": self.dt.tolist(),
            "displacement_noise_m": [listed(row) for row in self.displacement_noise],
            "pair_noise_m2": [listed(row) for row in self.pair_noise],
            "particles": self.particles,
            "associated": self.associated,
            "se_c1_over_truth": None
            if self.se_c1_over_truth is None
            else listed(self.se_c1_over_truth),
        }


def paired_ratio_se(
    per_snapshot: Sequence[PairSums], weights: np.ndarray, s2_boot: np.ndarray
) -> np.ndarray:
    """Standard error of a measured S2 over the truth of the same snapshots, paired.

    Parameters
    ----------
    per_snapshot : sequence of M PairSums
        The truth's pair sums of the snapshots the weights' columns name, in order.
    weights : ndarray, shape (R, M)
        How often each snapshot was drawn in each bootstrap replicate of the measurement.
    s2_boot : ndarray, shape (R, B)
        The measurement's S2 in each replicate (NaN where not fitted), m²/s².

    Returns
    -------
    ndarray, shape (B,)
        The standard deviation over the replicates of S2 over the truth refitted on the
        same draws (NaN where fewer than two replicates are finite).
    """
    count = np.array([np.reshape(s.count, -1) for s in per_snapshot], dtype=float)
    sum_q = np.array([s.sum_q[:, 0] for s in per_snapshot])
    with np.errstate(invalid="ignore", divide="ignore"):
        truth_boot = (weights @ sum_q) / (weights @ count)
        ratio = s2_boot / truth_boot
    finite = np.isfinite(ratio)
    out = np.full(ratio.shape[1], np.nan)
    usable = finite.sum(axis=0) >= 2
    out[usable] = [np.std(ratio[finite[:, b], b], ddof=1) for b in np.flatnonzero(usable)]
    return out


def population_truth(
    population: S2Population,
    truth: TruthFile,
    chunks: Iterable[tuple[int, int]],
    settings: StatisticsSettings,
    *,
    radius: float,
    rotation: np.ndarray | None = None,
    translation: np.ndarray | None = None,
    replicates: tuple[SnapshotBootstrap, np.ndarray] | None = None,
) -> PopulationTruth:
    """The truth of the particles a measurement's S2 used: the sample-truth S2 of their
    pairs (docs/statistics.md §8: the exact velocities over the actual pairs isolate the
    method's error from the sampling), the paired error of the measurement over it, and
    their displacement noise.

    Parameters
    ----------
    population : S2Population
        The measured X(t) and ΔX of S2's particles, per snapshot (calibration frame).
    truth : TruthFile
        The dataset's truth (its runs share frame a).
    chunks : iterable of (int, int)
        Snapshot ranges covering the dataset, in order: the truth is read chunk by chunk.
    settings : StatisticsSettings
        The separation bins.
    radius : float
        A measured particle is the true particle nearest to it within this distance, m
        (one voxel).
    rotation, translation : ndarray, shapes (3, 3) and (3,), optional
        Calibration frame → world, X_world = R X + t (default: the identity).
    replicates : (SnapshotBootstrap, ndarray (R, B)), optional
        The measurement's bootstrap (whose single stratum holds the population's
        snapshots) and its S2 in each replicate: for the paired error of c1 over the
        truth (:func:`paired_ratio_se`).
    """
    rotation = np.eye(3) if rotation is None else np.asarray(rotation)
    translation = np.zeros(3) if translation is None else np.asarray(translation)
    measured = dict(
        zip(
            population.snapshot_ids.tolist(),
            zip(population.positions, population.displacements, strict=True),
            strict=True,
        )
    )
    per_snapshot, errors, associated = [], [], 0
    pairs = PairNoiseSums.empty(len(truth.dt), settings.bins)
    for m0, m1 in chunks:
        wanted = [m for m in range(m0, m1) if m in measured]
        if not wanted:
            continue
        runs = truth.runs(m0, m1)
        for m in wanted:
            i = m - m0
            positions, moved = measured[m]
            true_x, true_u = runs[0].positions[i, 0], runs[0].velocity[i]
            dist, nearest = cKDTree(true_x).query(
                positions @ rotation.T + translation, distance_upper_bound=radius
            )
            hit = np.isfinite(dist)
            partner = nearest[hit]
            associated += len(partner)
            found = np.unique(partner)
            per_snapshot.append(pair_sums(true_x[found], true_u[found], settings.bins))
            true_moves = np.stack([r.positions[i, 1, partner] - true_x[partner] for r in runs], 1)
            errors.append(moved[hit] @ rotation.T - true_moves)  # (N, K, 3)
            pairs = pairs.merged(
                PairNoiseSums.of_snapshot(true_x[partner], errors[-1], settings.bins, seed=m)
            )
    _, s2, se = _pooled(per_snapshot)
    k = len(truth.dt)
    error = np.concatenate(errors) if errors else np.empty((0, k, 3))
    noise = np.sqrt(np.mean(error**2, axis=0)) if len(error) else np.full((k, 3), np.nan)
    paired = None
    if replicates is not None:
        bootstrap, s2_boot = replicates
        if not bootstrap.pairs_with([population.snapshot_ids]):
            raise ValueError("the bootstrap's snapshots are not the population's")
        paired = paired_ratio_se(per_snapshot, bootstrap.weights, s2_boot)
    return PopulationTruth(
        s2_sample=s2,
        se_s2_sample=se,
        dt=truth.dt,
        displacement_noise=noise,
        pair_noise=pairs.mean(),
        particles=population.count,
        associated=associated,
        se_c1_over_truth=paired,
    )


def flow_truth(
    snapshots: Iterable[tuple[np.ndarray, np.ndarray]],
    parameters: TurbulenceParameters,
    exact: ExactStructure,
    settings: StatisticsSettings,
) -> FlowTruth:
    """Sample truth and exact D_LL in the bins of ``settings`` (module docstring).

    Parameters
    ----------
    snapshots : iterable of (ndarray (P, 3), ndarray (P, 3))
        Positions (m) and exact velocities (m/s) at t of every independent snapshot
        (:meth:`validation.truth.truth_file.TruthFile.snapshots_at_t`).
    parameters : TurbulenceParameters
        The flow.
    exact : ExactStructure
        Its exact D_LL (:mod:`validation.truth.exact`).
    settings : StatisticsSettings
        Analysis volume, bins, plateau.
    """
    lower, upper = (np.asarray(v) for v in settings.analysis_volume)
    region = Box(tuple(upper - lower), tuple((upper + lower) / 2))
    edges = check_edges(
        log_edges(settings.r_min, settings.r_max, settings.n_bins),
        REFERENCE_PARTICLES,
        REFERENCE_GROUPS,
    )
    rng = np.random.default_rng(REFERENCE_SEED)
    per_snapshot, inside, parts = [], [], []
    for x, u in snapshots:
        sums = sample_structure_function(x[None], u[None], settings.bins, region=region)
        per_snapshot.append(sums)
        mask = region.contains(x)
        inside.append(u[mask])
        parts.append(
            subsample_sums(
                x[mask],
                u[mask],
                edges,
                per_group=REFERENCE_PARTICLES,
                groups=REFERENCE_GROUPS,
                rng=rng,
            )
        )
    r, s2, se = _pooled(per_snapshot)
    ok = np.isfinite(r)
    s2_exact = np.full_like(r, np.nan)
    s2_exact[ok] = exact.dll(r[ok])
    velocities = np.concatenate(inside)
    reference = collect(edges, parts)
    correlation = autocorrelation_time(np.array([sums.mean[:, 0] for sums in per_snapshot]))
    return FlowTruth(
        r=r,
        s2_sample=s2,
        se_s2_sample=se,
        s2_exact=s2_exact,
        epsilon_input=parameters.epsilon,
        epsilon_exact=_plateau(r[ok], s2_exact[ok], settings),
        epsilon_sample=_plateau(r[ok], s2[ok], settings),
        u_rms_sample=float(np.sqrt(np.mean(velocities**2))),
        parameters=parameters.as_dict(),
        r_reference=reference.r,
        s2_reference=reference.s2,
        se_s2_reference=reference.se_s2(),
        sample_over_reference=reference.mean_ratio(s2),
        epsilon_reference=plateau_epsilon_reference(
            exact.reference,
            reference.r,
            r_range=settings.plateau,
            method=settings.plateau_method,
            kolmogorov_c2=settings.kolmogorov_c2,
        ),
        snapshot_correlation={**correlation.as_dict(), "block": block_length(correlation)},
    )
