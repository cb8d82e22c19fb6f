"""Lagrangian statistics from noisy tracks, the noise removed with several steps (multi-Δt).

Positions are measured at frames f, τ₀ = 1/frame_rate apart, as X_f = x(fτ₀) + n_f with
n white: variance σ_c² in component c, independent between frames. Finite differences
over a step of s frames then carry noise of a known, exactly s-dependent variance, and a
smoothing bias that grows as s²; fitting both over a few steps leaves the noise-free
statistic (the multi-Δt idea of :mod:`ptv.stats.multidt`, here along tracks).

Acceleration variance (:func:`acceleration_variance`). A_s(f) = (X_{f+s} − 2X_f +
X_{f−s})/(sτ₀)². Its noise has variance (1 + 4 + 1)σ_c²/(sτ₀)⁴, uncorrelated with the
signal; the signal is a + (sτ₀)²x⁽⁴⁾/12 + O(s⁴), so per component

    ⟨A_s²⟩ = ⟨a²⟩ + b s² + 6σ²/(sτ₀)⁴,      b = τ₀²⟨a x⁽⁴⁾⟩/6 = −τ₀²⟨ȧ²⟩/6.

⟨a²⟩, b and σ² are fitted per component by weighted linear least squares over the steps,
weights 1/SE² of each ⟨A_s²⟩ from the bootstrap. The steps are 1, 2, 3 unless given:
three parameters need three steps; at s = 1 the noise term is largest, so σ² is pinned
there whenever noise matters at all; and the truncation of the s² expansion (the
O(s⁴) rest) is least at the smallest steps. Larger steps lower the variance where the
expansion holds further, but the data do not show reliably where it stops: on kinematic
simulation at τ₀ = τ_η/10 with σ = 15 µm, neither the generalised χ² of the fit over
1 … 4 (bootstrap covariance: the steps share tracks and noise) nor the shift of ⟨a²⟩
from the fit over 1 … 3 (in bootstrap standard errors of the difference) rejected
S = 4, which lowers ⟨a²⟩ by a further 10 % and, through σ², S2ᴸ(5τ₀) by 1.5 %.
``chi2_dof`` (more than three steps) and ``noise_fraction`` (the fitted noise term's
share of ⟨A_s²⟩: near 1 at the largest step, the signal is not resolved) are the
diagnostics. Where the acceleration decorrelates within a few frames no steps avoid the
bias: kinematic simulation's sweeping of small scales puts ⟨A_1²⟩ 7 % below ⟨a²⟩ at
τ₀ = τ_η/10, and the fit over 1, 2, 3 is 10 % low even without noise.

Structure function (:func:`lagrangian_structure_function`). u_s(f) = (X_{f+s} −
X_f)/(sτ₀) is the velocity at f + s/2 plus (sτ₀)²ü/24 + O(s⁴), and

    D(L; s) = ⟨|u_s(f+L) − u_s(f)|²⟩ = S2ᴸ(Lτ₀) + b_L s² + n(s, L)·Σ_c σ_c²/(sτ₀)²,

with n = 4 when the four frames f, f+s, f+L, f+L+s are distinct (L ≠ s) and 6 when L = s
(the middle frame counts twice). The noise is removed with the σ_c² of the acceleration
fit, each bootstrap replicate with its own, and S2ᴸ and b_L are fitted over the steps
(1, 2, 3 by default) by weighted least squares. The choice of σ² was measured on
kinematic simulation (τ₀ = τ_η/10, 2000 particles in the paper-stereo sheet, ten noise
realisations, unweighted fits, rms error against the exact S2ᴸ of the same pairs): with
σ = 15 µm, σ² from the acceleration fit gives 8, 4, 1.2, 0.6 % at L = 1, 2, 5, 10
frames, a joint fit of S2ᴸ, b_L and σ² per lag 8, 5.4, 0.7, 0.5 %; with σ = 5 µm,
6.9, 1.6, 0.1, 0.1 % against 3.8, 3.4, 0.3, 0.1 %. Neither is better everywhere; the
acceleration's σ² is used (one σ² for every statistic, its errors carried by the shared
replicates). At L ≤ 2 the error is mostly bias: the noise term is 40–200 times S2ᴸ at
s = 1 (σ = 15 µm), so a σ² off by 0.1 % (sampling, or curvature of ⟨A_s²⟩ taken for
noise) moves S2ᴸ by 4–20 %. D(L; 1), the raw estimate, is reported beside.

Velocity variance (:func:`velocity_variance`). ⟨|u_s|²⟩ = ⟨|u|²⟩ + b s² + 2Σ_cσ_c²/(sτ₀)²,
fitted alike. No mean velocity is subtracted: the flows this is written for (isotropic
turbulence, kinematic simulation) have none; a flow with a mean needs it removed first
(e.g. per bin, :mod:`ptv.stats.mean_displacement`).

Autocorrelation (:func:`velocity_autocorrelation`). ρ(τ) = 1 − S2ᴸ(τ)/(2⟨|u|²⟩), from the
two noise-free fits above.

Acceleration PDF (:func:`acceleration_pdf`): the components of fitted accelerations
(:class:`ptv.tracking.fitting.FittedTracks`) over their rms, as one normalised histogram.

Populations. A statistic fitted over several steps uses, for every step, the same
points: those whose every needed frame (f ± s for the acceleration, f + s, f + L,
f + L + s for the structure function, for all s) is a point of the same track, so that
the fit compares like with like (which particles stay long in the volume depends on their
velocity). Tracks may skip frames; only the frames present are used.

Errors. Tracks are independent; the points of one are not. Every mean is kept as
per-track sums, and :class:`TrackSample` draws ``resamples`` bootstrap replicates of the
tracks once (whole tracks, with replacement); every fit is linear in its means, so a
replicate is refitted with one contraction. Statistics computed from one
:class:`TrackSample` share their replicates, so an error propagated from one to another
(σ² into S2ᴸ, S2ᴸ and ⟨|u|²⟩ into ρ) keeps their correlation.
"""

from dataclasses import dataclass

import numpy as np

from ptv.stats.track_sample import TrackSample, track_sample
from ptv.tracking.fitting import FittedTracks

__all__ = [
    "LAGS",
    "AccelerationPdf",
    "AccelerationVariance",
    "LagrangianStatistics",
    "LagrangianStructureFunction",
    "TrackSample",
    "VelocityAutocorrelation",
    "VelocityVariance",
    "acceleration_pdf",
    "acceleration_variance",
    "lagrangian_statistics",
    "lagrangian_structure_function",
    "track_sample",
    "velocity_autocorrelation",
    "velocity_variance",
]

#: Default steps of every fit, frames.
STEPS = (1, 2, 3)
#: Lags of S2ᴸ, frames, of :func:`lagrangian_statistics` (those beyond a third of the
#: longest track are left out).
LAGS = (1, 2, 3, 5, 7, 10, 14, 20, 30, 50, 70, 100)


# ---------------------------------------------------------------------------- fits


def _wls(design: np.ndarray, y: np.ndarray, boot: np.ndarray):
    """Weighted least squares y ≈ design·c, weights from the replicates' spread.

    Parameters
    ----------
    design : ndarray, shape (K, P)
    y : ndarray, shape (K,)
    boot : ndarray, shape (R, K)
        Bootstrap replicates of y.

    Returns
    -------
    c : ndarray, shape (P,)
    c_boot : ndarray, shape (R, P)
        The same operator applied to each replicate.
    """
    se = boot.std(axis=0, ddof=1)
    if not np.any(se > 0):
        se = np.ones_like(se)
    weight = 1.0 / np.where(se > 0, se, se[se > 0].min())  # a step without spread
    scale = np.linalg.norm(design * weight[:, None], axis=0)
    operator = np.linalg.pinv(design * weight[:, None] / scale) * weight / scale[:, None]
    return operator @ y, boot @ operator.T


def _gls_chi2(design: np.ndarray, y: np.ndarray, boot: np.ndarray) -> float:
    """Minimum of rᵀC⁻¹r over the fits y ≈ design·c, C the replicates' covariance."""
    inverse = np.linalg.pinv(np.cov(boot, rowvar=False))
    scale = np.linalg.norm(design, axis=0)
    d = design / scale
    fit = d @ np.linalg.pinv(d.T @ inverse @ d) @ d.T @ inverse
    r = y - fit @ y
    return float(r @ inverse @ r)


def _se(boot: np.ndarray) -> np.ndarray:
    return boot.std(axis=0, ddof=1)


# -------------------------------------------------------------------- acceleration


@dataclass(frozen=True, eq=False)
class AccelerationVariance:
    """⟨a²⟩ with the noise removed over several steps.

    Attributes
    ----------
    steps : ndarray of int, shape (K,)
        Steps s fitted, frames.
    mean_square, mean_square_se : ndarray, shape (K, 3)
        Raw ⟨A_s²⟩ per component and its standard error, m²/s⁴.
    per_component, per_component_se : ndarray, shape (3,)
        Noise-free ⟨a_c²⟩, m²/s⁴.
    total, total_se : float
        ⟨|a|²⟩, m²/s⁴.
    noise_variance, noise_variance_se : ndarray, shape (3,)
        σ_c², m².
    curvature : ndarray, shape (3,)
        b per component, m²/s⁴ per frame².
    noise_fraction : ndarray, shape (K,)
        The fitted noise term's share of ⟨|A_s|²⟩ at each step.
    chi2_dof : float
        Generalised χ² per degree of freedom of the fits (NaN for three steps).
    points : int
        Points in the population.
    per_component_boot, noise_variance_boot : ndarray, shape (R, 3)
        Bootstrap replicates, m²/s⁴ and m².
    """

    steps: np.ndarray
    mean_square: np.ndarray
    mean_square_se: np.ndarray
    per_component: np.ndarray
    per_component_se: np.ndarray
    total: float
    total_se: float
    noise_variance: np.ndarray
    noise_variance_se: np.ndarray
    curvature: np.ndarray
    noise_fraction: np.ndarray
    chi2_dof: float
    points: int
    per_component_boot: np.ndarray
    noise_variance_boot: np.ndarray

    @property
    def raw(self) -> float:
        """⟨|A_1|²⟩ or at the smallest step, m²/s⁴: the estimate without noise removal."""
        return float(self.mean_square[0].sum())

    def as_dict(self) -> dict:
        """JSON-able summary, SI units."""
        return {
            "steps": self.steps.tolist(),
            "mean_square": self.mean_square.tolist(),
            "mean_square_se": self.mean_square_se.tolist(),
            "per_component": self.per_component.tolist(),
            "per_component_se": self.per_component_se.tolist(),
            "total": self.total,
            "total_se": self.total_se,
            "raw": self.raw,
            "noise_variance": self.noise_variance.tolist(),
            "noise_variance_se": self.noise_variance_se.tolist(),
            "curvature": self.curvature.tolist(),
            "noise_fraction": self.noise_fraction.tolist(),
            "chi2_dof": None if np.isnan(self.chi2_dof) else self.chi2_dof,
            "points": self.points,
        }


def _acceleration_means(sample: TrackSample, steps: np.ndarray):
    """⟨A_s²⟩ per step and component over the common population, and replicates."""
    x, tau = sample.position, sample.tau
    rows = {s: (sample.rows(-s), sample.rows(s)) for s in steps}
    keep = np.all([(b >= 0) & (a >= 0) for b, a in rows.values()], axis=0)
    centre = np.flatnonzero(keep)
    if len(centre) == 0:
        raise ValueError(f"no point has frames f ± {steps.max()} in its track")
    values = [
        ((x[rows[s][1][centre]] - 2 * x[centre] + x[rows[s][0][centre]]) / (s * tau) ** 2) ** 2
        for s in steps
    ]
    mean, boot = sample.means(centre, np.concatenate(values, axis=1))
    k = len(steps)
    return mean.reshape(k, 3), boot.reshape(-1, k, 3), len(centre)


def _acceleration_design(steps: np.ndarray, tau: float) -> np.ndarray:
    s = steps.astype(float)
    return np.stack([np.ones_like(s), s**2, 6.0 / (s * tau) ** 4], axis=1)


def _acceleration_fit(mean, boot, steps, tau):
    """Per-component fits: coefficients (3 parameters, 3 components) and (R, 3, 3)."""
    design = _acceleration_design(steps, tau)
    fits = [_wls(design, mean[:, c], boot[:, :, c]) for c in range(3)]
    return np.stack([c for c, _ in fits], axis=1), np.stack([b for _, b in fits], axis=2)


def _acceleration_chi2(mean, boot, steps, tau) -> float:
    """Generalised χ² per degree of freedom, summed over components."""
    design = _acceleration_design(steps, tau)
    chi2 = sum(_gls_chi2(design, mean[:, c], boot[:, :, c]) for c in range(3))
    return chi2 / (3 * (len(steps) - 3))


def acceleration_variance(sample: TrackSample, *, steps=STEPS) -> AccelerationVariance:
    """Noise-free ⟨a²⟩, per component and total, with σ² and bootstrap errors.

    Parameters
    ----------
    sample : TrackSample
        The tracks.
    steps : sequence of int
        Steps s ≥ 1 to fit, at least 3 distinct (default 1, 2, 3: module docstring).

    Returns
    -------
    AccelerationVariance
    """
    steps = np.unique(np.asarray(steps, dtype=int))
    if len(steps) < 3 or steps[0] < 1:
        raise ValueError(f"steps must hold at least 3 distinct integers >= 1, got {steps!r}")
    mean, boot, points = _acceleration_means(sample, steps)
    coef, coef_boot = _acceleration_fit(mean, boot, steps, sample.tau)
    chi2 = _acceleration_chi2(mean, boot, steps, sample.tau) if len(steps) > 3 else np.nan
    return AccelerationVariance(
        steps=steps,
        mean_square=mean,
        mean_square_se=_se(boot),
        per_component=coef[0],
        per_component_se=_se(coef_boot[:, 0]),
        total=float(coef[0].sum()),
        total_se=float(_se(coef_boot[:, 0].sum(axis=1))),
        noise_variance=coef[2],
        noise_variance_se=_se(coef_boot[:, 2]),
        curvature=coef[1],
        noise_fraction=6.0 * coef[2].sum() / (steps * sample.tau) ** 4 / mean.sum(axis=1),
        chi2_dof=float(chi2),
        points=points,
        per_component_boot=coef_boot[:, 0],
        noise_variance_boot=coef_boot[:, 2],
    )


# ------------------------------------------------------------ structure function


@dataclass(frozen=True, eq=False)
class LagrangianStructureFunction:
    """S2ᴸ(τ) = ⟨|u(t + τ) − u(t)|²⟩ with the noise and the step bias removed.

    Attributes
    ----------
    lags : ndarray of int, shape (J,)
        L, frames.
    tau : ndarray, shape (J,)
        τ = L τ₀, s.
    value, se : ndarray, shape (J,)
        S2ᴸ(τ) and its standard error, m²/s².
    raw : ndarray, shape (J,)
        D(L; 1), m²/s².
    curvature : ndarray, shape (J,)
        b_L, m²/s² per frame².
    pairs : ndarray of int, shape (J,)
        Pairs in each lag's population.
    steps : ndarray of int, shape (K,)
        Steps s fitted.
    boot : ndarray, shape (R, J)
        Bootstrap replicates of the value.
    """

    lags: np.ndarray
    tau: np.ndarray
    value: np.ndarray
    se: np.ndarray
    raw: np.ndarray
    curvature: np.ndarray
    pairs: np.ndarray
    steps: np.ndarray
    boot: np.ndarray

    def as_dict(self) -> dict:
        """JSON-able summary, SI units."""
        return {
            "lags": self.lags.tolist(),
            "tau": self.tau.tolist(),
            "value": self.value.tolist(),
            "se": self.se.tolist(),
            "raw": self.raw.tolist(),
            "curvature": self.curvature.tolist(),
            "pairs": self.pairs.tolist(),
            "steps": self.steps.tolist(),
        }


def _check_steps(steps) -> np.ndarray:
    steps = np.unique(np.asarray(steps, dtype=int))
    if len(steps) < 2 or steps[0] < 1:
        raise ValueError(f"steps must hold at least 2 distinct integers >= 1, got {steps!r}")
    return steps


def lagrangian_structure_function(
    sample: TrackSample, lags, acceleration: AccelerationVariance, *, steps=STEPS
) -> LagrangianStructureFunction:
    """Noise-free Lagrangian S2ᴸ(Lτ₀) of the velocity at the given lags.

    Parameters
    ----------
    sample : TrackSample
        The tracks (the same as ``acceleration``'s, so the replicates match).
    lags : sequence of int
        L ≥ 1, frames.
    acceleration : AccelerationVariance
        Its σ_c² removes the noise.
    steps : sequence of int
        Steps s of the finite-difference velocities, at least 2.

    Returns
    -------
    LagrangianStructureFunction
    """
    lags = np.asarray(lags, dtype=int)
    if lags.ndim != 1 or len(lags) == 0 or np.any(lags < 1):
        raise ValueError(f"lags must be integers >= 1, got {lags!r}")
    steps = _check_steps(steps)
    _check_replicates(sample, acceleration.noise_variance_boot)
    x, tau = sample.position, sample.tau
    used = np.union1d(steps, [1])
    noise = acceleration.noise_variance.sum()
    noise_boot = acceleration.noise_variance_boot.sum(axis=1)
    out = {name: np.empty(len(lags)) for name in ("value", "se", "raw", "curvature", "pairs")}
    boots = []
    for j, lag in enumerate(lags):
        offsets = np.union1d(np.union1d(used, used + lag), [lag])
        rows = {o: sample.rows(int(o)) for o in offsets}
        start = np.flatnonzero(np.all([r >= 0 for r in rows.values()], axis=0))
        if len(start) == 0:
            raise ValueError(f"no track holds the frames f … f + {offsets.max()} for L = {lag}")
        at = {o: r[start] for o, r in rows.items()}
        at[0] = start
        values = np.stack(
            [
                np.sum(((x[at[lag + s]] - x[at[lag]]) - (x[at[s]] - x[at[0]])) ** 2, axis=1)
                / (s * tau) ** 2
                for s in used
            ],
            axis=1,
        )
        mean, boot = sample.means(start, values)
        fitted = np.isin(used, steps)
        factor = np.where(steps == lag, 6.0, 4.0) / (steps * tau) ** 2
        y = mean[fitted] - factor * noise
        y_boot = boot[:, fitted] - noise_boot[:, None] * factor
        design = np.stack([np.ones(len(steps)), steps.astype(float) ** 2], axis=1)
        coef, coef_boot = _wls(design, y, y_boot)
        out["value"][j], out["curvature"][j] = coef
        out["se"][j] = _se(coef_boot[:, 0])
        out["raw"][j] = mean[used == 1][0]
        out["pairs"][j] = len(start)
        boots.append(coef_boot[:, 0])
    return LagrangianStructureFunction(
        lags=lags,
        tau=lags * tau,
        value=out["value"],
        se=out["se"],
        raw=out["raw"],
        curvature=out["curvature"],
        pairs=out["pairs"].astype(int),
        steps=steps,
        boot=np.stack(boots, axis=1),
    )


def _check_replicates(sample: TrackSample, boot: np.ndarray) -> None:
    if boot.shape[0] != sample.draws.shape[0]:
        raise ValueError(
            f"the statistics come from other bootstrap draws ({boot.shape[0]} replicates, "
            f"the sample has {sample.draws.shape[0]}): compute both from one TrackSample"
        )


# --------------------------------------------------------------- velocity variance


@dataclass(frozen=True, eq=False)
class VelocityVariance:
    """⟨|u|²⟩ (no mean subtracted) with the noise and the step bias removed.

    Attributes
    ----------
    steps : ndarray of int, shape (K,)
        Steps s fitted.
    per_component : ndarray, shape (3,)
        ⟨u_c²⟩, m²/s².
    total, total_se : float
        ⟨|u|²⟩, m²/s².
    raw : float
        ⟨|u_1|²⟩ (or at the smallest step), m²/s².
    points : int
        Points in the population.
    boot : ndarray, shape (R,)
        Bootstrap replicates of the total.
    """

    steps: np.ndarray
    per_component: np.ndarray
    total: float
    total_se: float
    raw: float
    points: int
    boot: np.ndarray

    def as_dict(self) -> dict:
        """JSON-able summary, SI units."""
        return {
            "steps": self.steps.tolist(),
            "per_component": self.per_component.tolist(),
            "total": self.total,
            "total_se": self.total_se,
            "raw": self.raw,
            "points": self.points,
        }


def velocity_variance(
    sample: TrackSample, acceleration: AccelerationVariance, *, steps=STEPS
) -> VelocityVariance:
    """Noise-free ⟨|u|²⟩ from finite-difference velocities over several steps.

    Parameters
    ----------
    sample : TrackSample
        The tracks (the same as ``acceleration``'s).
    acceleration : AccelerationVariance
        Its σ_c² removes the noise.
    steps : sequence of int
        Steps s, at least 2.

    Returns
    -------
    VelocityVariance
    """
    steps = _check_steps(steps)
    _check_replicates(sample, acceleration.noise_variance_boot)
    x, tau = sample.position, sample.tau
    rows = {s: sample.rows(int(s)) for s in steps}
    start = np.flatnonzero(np.all([r >= 0 for r in rows.values()], axis=0))
    if len(start) == 0:
        raise ValueError(f"no track holds the frames f … f + {steps.max()}")
    values = np.concatenate(
        [((x[rows[s][start]] - x[start]) / (s * tau)) ** 2 for s in steps], axis=1
    )
    mean, boot = sample.means(start, values)
    k = len(steps)
    mean, boot = mean.reshape(k, 3), boot.reshape(-1, k, 3)
    factor = 2.0 / (steps * tau) ** 2
    y = mean - factor[:, None] * acceleration.noise_variance
    y_boot = boot - factor[None, :, None] * acceleration.noise_variance_boot[:, None, :]
    design = np.stack([np.ones(k), steps.astype(float) ** 2], axis=1)
    fits = [_wls(design, y[:, c], y_boot[:, :, c]) for c in range(3)]
    per_component = np.array([c[0] for c, _ in fits])
    total_boot = np.sum([b[:, 0] for _, b in fits], axis=0)
    return VelocityVariance(
        steps=steps,
        per_component=per_component,
        total=float(per_component.sum()),
        total_se=float(total_boot.std(ddof=1)),
        raw=float(mean[0].sum()),
        points=len(start),
        boot=total_boot,
    )


# ------------------------------------------------------------------ autocorrelation


@dataclass(frozen=True, eq=False)
class VelocityAutocorrelation:
    """ρ(τ) = 1 − S2ᴸ(τ)/(2⟨|u|²⟩).

    Attributes
    ----------
    lags : ndarray of int, shape (J,)
        L, frames.
    tau : ndarray, shape (J,)
        s.
    value, se : ndarray, shape (J,)
        ρ and its standard error.
    """

    lags: np.ndarray
    tau: np.ndarray
    value: np.ndarray
    se: np.ndarray

    def as_dict(self) -> dict:
        """JSON-able summary."""
        return {
            "lags": self.lags.tolist(),
            "tau": self.tau.tolist(),
            "value": self.value.tolist(),
            "se": self.se.tolist(),
        }


def velocity_autocorrelation(
    structure: LagrangianStructureFunction, variance: VelocityVariance
) -> VelocityAutocorrelation:
    """ρ(τ) from the noise-free S2ᴸ and ⟨|u|²⟩ of one :class:`TrackSample`.

    Parameters
    ----------
    structure : LagrangianStructureFunction
    variance : VelocityVariance

    Returns
    -------
    VelocityAutocorrelation
    """
    if structure.boot.shape[0] != variance.boot.shape[0]:
        raise ValueError("the two statistics come from different bootstrap draws")
    boot = 1.0 - structure.boot / (2.0 * variance.boot[:, None])
    return VelocityAutocorrelation(
        lags=structure.lags,
        tau=structure.tau,
        value=1.0 - structure.value / (2.0 * variance.total),
        se=_se(boot),
    )


# ---------------------------------------------------------------- acceleration PDF


@dataclass(frozen=True, eq=False)
class AccelerationPdf:
    """PDF of the acceleration components over their rms.

    Attributes
    ----------
    edges : ndarray, shape (B + 1,)
        Bin edges of a_c / a_c,rms.
    density : ndarray, shape (B,)
        Probability density (its integral over the bins is the fraction inside them).
    rms : ndarray, shape (3,)
        a_c,rms, m/s².
    samples : int
        Components counted (3 per fitted point).
    """

    edges: np.ndarray
    density: np.ndarray
    rms: np.ndarray
    samples: int

    def as_dict(self) -> dict:
        """JSON-able summary."""
        return {
            "edges": self.edges.tolist(),
            "density": self.density.tolist(),
            "rms": self.rms.tolist(),
            "samples": self.samples,
        }


def acceleration_pdf(fitted: FittedTracks, *, edges: np.ndarray | None = None) -> AccelerationPdf:
    """Normalised histogram of the fitted acceleration components over their rms.

    Parameters
    ----------
    fitted : FittedTracks
        Points without a fit (NaN) are left out.
    edges : ndarray, shape (B + 1,), optional
        Increasing bin edges (default 81 bins over ±10).

    Returns
    -------
    AccelerationPdf
    """
    edges = np.linspace(-10.0, 10.0, 82) if edges is None else np.asarray(edges, dtype=float)
    if edges.ndim != 1 or len(edges) < 2 or np.any(np.diff(edges) <= 0):
        raise ValueError("edges must be increasing, at least 2")
    a = fitted.acceleration[np.all(np.isfinite(fitted.acceleration), axis=1)]
    if len(a) == 0:
        raise ValueError("no fitted acceleration")
    rms = np.sqrt(np.mean(a**2, axis=0))
    counts, _ = np.histogram((a / rms).ravel(), bins=edges)
    return AccelerationPdf(
        edges=edges, density=counts / (a.size * np.diff(edges)), rms=rms, samples=a.size
    )


@dataclass(frozen=True, eq=False)
class LagrangianStatistics:
    """⟨a²⟩, S2ᴸ, ⟨|u|²⟩ and ρ of one set of tracks, from one :class:`TrackSample`."""

    acceleration: AccelerationVariance
    structure: LagrangianStructureFunction
    velocity: VelocityVariance
    autocorrelation: VelocityAutocorrelation

    def as_dict(self) -> dict:
        """JSON-able summary, SI units."""
        return {
            "acceleration_variance": self.acceleration.as_dict(),
            "structure_function": self.structure.as_dict(),
            "velocity_variance": self.velocity.as_dict(),
            "autocorrelation": self.autocorrelation.as_dict(),
        }


def lagrangian_statistics(
    track: np.ndarray,
    frame: np.ndarray,
    position: np.ndarray,
    frame_rate: float,
    *,
    lags=None,
    resamples: int = 200,
    rng: np.random.Generator | int | None = 0,
) -> LagrangianStatistics:
    """Every statistic of this module on one set of tracks, sharing their replicates.

    Parameters
    ----------
    track, frame, position, frame_rate, resamples, rng :
        As :func:`ptv.stats.track_sample.track_sample`.
    lags : sequence of int, optional
        Lags of S2ᴸ, frames (default :data:`LAGS` up to a third of the longest track).

    Returns
    -------
    LagrangianStatistics
    """
    sample = track_sample(track, frame, position, frame_rate, resamples=resamples, rng=rng)
    if lags is None:
        longest = int(np.bincount(sample.track).max())
        lags = [lag for lag in LAGS if lag <= longest // 3] or [1]
    acceleration = acceleration_variance(sample)
    structure = lagrangian_structure_function(sample, lags, acceleration)
    velocity = velocity_variance(sample, acceleration)
    return LagrangianStatistics(
        acceleration, structure, velocity, velocity_autocorrelation(structure, velocity)
    )
