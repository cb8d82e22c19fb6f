"""The multi-Δt method on KS particles with injected measurement errors, against truth.

Exact double-frame trajectories of a KS flow (one independent run per Δt) are
"measured" as X = (1 + s) X̃ + b: a uniform calibration scale error s (docs/statistics.md §9,
b(X) constant in time) and white Gaussian position noise b, independent at t and
t + Δt. The stack's statistics (``ptv.stats``) then fit c₁Δt² + c₂ per separation bin,
and every figure is compared with the sample truth of the same pairs (exact velocities
at t) and with the exact D_LL of the spectrum.
"""

from dataclasses import dataclass, replace

import numpy as np

from ptv.bins import LogBins
from ptv.settings import DEFAULT_C2
from ptv.stats.dissipation import dissipation_profile, plateau_epsilon
from ptv.stats.links import RunParticles
from ptv.stats.mean_displacement import MeanDisplacement, mean_displacement
from ptv.stats.multidt import dt_subsets
from ptv.stats.pairs import PairSums, pair_sums
from ptv.stats.snapshots import SnapshotSums
from ptv.stats.structure import StructureFunction, double_frame_sums, structure_function
from simulator.particles import ANALYSIS_VOLUME, Box, DoubleFrameSample, KSFlow, double_frame
from simulator.presets import FlowPreset
from simulator.spectra import C_KOLMOGOROV, KolmogorovBandSpectrum, PopeSpectrum, Spectrum
from simulator.truth import longitudinal_structure_function
from simulator.turbulence import TurbulenceParameters

#: Random Fourier modes of a correlated noise field (redrawn every frame, so its
#: covariance is exact on average; 64 cosines make each value close to Gaussian).
_NOISE_MODES = 64


@dataclass(frozen=True)
class Measurement:
    """How positions are measured.

    Attributes
    ----------
    noise : tuple of 3 floats
        Standard deviation of the position noise per component, m.
    scale_error : float
        Uniform calibration scale error s (X → (1 + s) X).
    correlation_length : float or None
        ℓ of spatially correlated noise (None: independent per particle), m.
    """

    noise: tuple[float, float, float] = (15e-6, 15e-6, 15e-6)
    scale_error: float = 0.0
    correlation_length: float | None = None

    def draw(self, positions: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Position noise at positions (P, 3), m: white, or a Gaussian random field.

        With a correlation length ℓ the noise of each component is a random Fourier field
        with covariance σ² exp(−r²/(2ℓ²)) in space (docs/statistics.md §1: N(r) = 4σ²(1 − ρ(r))),
        drawn afresh for every frame (white in time).
        """
        sigma = np.asarray(self.noise, dtype=float)
        if self.correlation_length is None:
            return rng.normal(0.0, 1.0, positions.shape) * sigma
        modes = _NOISE_MODES
        k = rng.normal(0.0, 1.0 / self.correlation_length, (3, 3 * modes))  # per component
        phase = rng.uniform(0.0, 2 * np.pi, 3 * modes)
        field = np.cos(positions @ k + phase).reshape(len(positions), 3, modes).sum(axis=-1)
        return field * np.sqrt(2.0 / modes) * sigma


@dataclass(frozen=True)
class MultiDtResult:
    """Fitted statistics beside the truth, per separation bin.

    Attributes
    ----------
    fit : StructureFunction
        The stack's multi-Δt fit (c₁ = ``fit.s2``, c₂ = ``fit.noise``).
    sample_truth : ndarray, shape (B,), or None
        S2 of the exact velocities over the same pairs, m²/s² (None when not asked for).
    exact_dll : ndarray, shape (B,)
        D_LL of the spectrum at the bins' mean separations, m²/s².
    epsilon_fit, epsilon_exact : float
        Plateau (maximum) of (S2/C₂)^{3/2}/r over the inertial range for the fit and for
        the exact D_LL, m²/s³.
    epsilon_subsets : dict
        Plateau ε of each Δt subset of :func:`ptv.stats.multidt.dt_subsets`.
    mean_displacement : MeanDisplacement
        The stack's line ⟨ΔX⟩ = αΔt + β₀ per component
        (:func:`ptv.stats.mean_displacement.mean_displacement`, errors from the scatter
        of snapshot means).
    links : tuple of RunParticles
        The measured X(t) and ΔX of each Δt run, as the stack's statistics take them.
    inertial : ndarray of bool, shape (B,)
        Bins inside the inertial range used for the plateau.
    sums : SnapshotSums
        Per-snapshot pair sums of the measured displacements (q in m²), for refits.
    """

    fit: StructureFunction
    sample_truth: np.ndarray | None
    exact_dll: np.ndarray
    epsilon_fit: float
    epsilon_exact: float
    epsilon_subsets: dict
    mean_displacement: MeanDisplacement
    links: tuple[RunParticles, ...]
    inertial: np.ndarray
    sums: SnapshotSums


def band_limited_spectrum(
    parameters: TurbulenceParameters, *, cutoff: float = 2 * np.pi
) -> KolmogorovBandSpectrum:
    """Band-limited K41 spectrum E = C_K ε^{2/3} k^{-5/3} cut off at k_N ≈ cutoff/η.

    A sharp cut-off dissipates ε = 2ν∫k²E dk only at k_Nη = (2/(3C_K))^{3/4} ≈ 0.544
    (``SPECTRA["k41-band"]``), which leaves no K41 range: the local slope of D_LL over
    20η–0.2L_int is 0.70–0.96. Cut at k_N = 2π/η (docs/flow.md §2.2: ε is the
    inertial-range flux, η the label 2π/k_N, and 2ν∫k²E dk = 26ε) the band spans
    k_N/k₁ ≈ 2200–3400, D_LL/(εr)^{2/3} peaks at 1.91 and the local slope is 0.65–0.71
    over that range (docs/flow.md §2.4). The result is the ``KolmogorovBandSpectrum`` of a fluid
    of viscosity ν' = ν (2/(3C_K)) cutoff^{-4/3}, whose dissipation-matched cut-off falls
    at cutoff/η (up to the small k₁ term of its dissipation integral). Its own
    ``parameters`` carry ν', hence η and τ_η of ν': take η, τ_η and the Δt set from the
    ``parameters`` passed in.

    Parameters
    ----------
    parameters : TurbulenceParameters
        u' (m/s), ε (m²/s³) and the ν (m²/s) that defines η.
    cutoff : float
        k_Nη, > 0.

    Returns
    -------
    KolmogorovBandSpectrum
    """
    if not (np.isfinite(cutoff) and cutoff > 0):
        raise ValueError(f"cutoff k_N·eta must be finite and > 0, got {cutoff!r}")
    nu = parameters.nu * 2.0 / (3.0 * C_KOLMOGOROV) * cutoff ** (-4.0 / 3.0)
    return KolmogorovBandSpectrum(replace(parameters, nu=nu))


def simulate(
    preset: FlowPreset,
    *,
    particles: int,
    snapshots: int,
    region: Box = ANALYSIS_VOLUME,
    spectrum: Spectrum | None = None,
    rng: np.random.Generator | int | None = None,
) -> DoubleFrameSample:
    """Exact double-frame runs of the preset's flow at its Δt set.

    ``spectrum`` is the flow's spectrum (default: the Pope spectrum of the preset's
    parameters); pass the same one to :func:`analyse`.
    """
    return double_frame(
        KSFlow(PopeSpectrum(preset.parameters) if spectrum is None else spectrum),
        preset.dt,
        particles=particles,
        snapshots=snapshots,
        region=region,
        rng=rng,
    )


def analyse(
    sample: DoubleFrameSample,
    preset: FlowPreset,
    measurement: Measurement,
    *,
    region: Box = ANALYSIS_VOLUME,
    bins: int = 16,
    inertial_range: tuple[float, float] = (2e-3, 20e-3),
    kolmogorov_c2: float = DEFAULT_C2,
    spectrum: Spectrum | None = None,
    n_boot: int = 200,
    sample_truth: bool = True,
    rng: np.random.Generator | int | None = None,
) -> MultiDtResult:
    """Measure the sample, fit the multi-Δt statistics and put them beside the truth.

    Parameters
    ----------
    sample : DoubleFrameSample
        Exact runs (see :func:`simulate`).
    preset : FlowPreset
        The flow (its parameters set the bins: 10 η to L_int/2).
    measurement : Measurement
        Noise and calibration scale error.
    region : Box
        Analysis volume: pairs are formed from particles measured inside it at t.
    bins : int
        Logarithmic separation bins.
    inertial_range : (float, float)
        Separations (m) over which the ε plateau is taken.
    kolmogorov_c2 : float
        C₂ of the estimator ε = (S2/C₂)^{3/2}/r (default: the stack's).
    spectrum : PopeSpectrum, KolmogorovBandSpectrum or None
        The spectrum the sample was simulated with, for the exact D_LL (None: the Pope
        spectrum of ``preset``).
    n_boot : int
        Bootstrap replicates over snapshots.
    sample_truth : bool
        Compute the sample truth with the stack's pair sums (False: ``sample_truth``
        is None, for callers that compare with independent references instead).
    rng : numpy.random.Generator, int or None
        Noise draws and bootstrap.

    Returns
    -------
    MultiDtResult
    """
    rng = np.random.default_rng(rng)
    p = preset.parameters
    log_bins = LogBins(10 * p.eta, p.L_int / 2, bins)
    gain = 1.0 + measurement.scale_error
    runs, truth = [], None
    for run in sample.runs:
        pairs = []
        for x, u in zip(run.positions, run.velocity[:, 0], strict=True):
            measured = gain * x + np.stack([measurement.draw(frame, rng) for frame in x])
            inside = region.contains(measured[0])
            start, delta = measured[0][inside], (measured[1] - measured[0])[inside]
            pairs.append((start, delta))
            if sample_truth:
                sums = pair_sums(x[0][inside], u[inside], log_bins)
                truth = sums if truth is None else truth + sums
        runs.append(pairs)
    links = tuple(
        RunParticles.from_links(k, d, pairs)
        for k, (d, pairs) in enumerate(zip(sample.dt, runs, strict=True))
    )
    snapshot_sums = double_frame_sums(runs, log_bins)
    fit = structure_function(snapshot_sums, sample.dt, n_boot=n_boot, rng=rng)
    r = np.where(np.isfinite(fit.r), fit.r, log_bins.centres)
    exact = longitudinal_structure_function(PopeSpectrum(p) if spectrum is None else spectrum, r)
    inertial = (r >= inertial_range[0]) & (r <= inertial_range[1]) & fit.fitted

    def plateau(s2: np.ndarray) -> float:
        profile = dissipation_profile(r[inertial], s2[inertial], kolmogorov_c2=kolmogorov_c2)
        return plateau_epsilon(
            profile, r_min=inertial_range[0], r_max=inertial_range[1], method="max"
        ).epsilon

    subsets = {}
    for name, use in dt_subsets(sample.dt).items():
        sub = structure_function(snapshot_sums, sample.dt, use=use, n_boot=n_boot, rng=rng)
        subsets[name] = plateau(sub.s2)
    return MultiDtResult(
        fit=fit,
        sample_truth=None if truth is None else _mean(truth),
        exact_dll=exact,
        epsilon_fit=plateau(fit.s2),
        epsilon_exact=plateau(exact),
        epsilon_subsets=subsets,
        mean_displacement=mean_displacement(links),
        links=links,
        inertial=inertial,
        sums=snapshot_sums,
    )


def add_dt3_term(sums: SnapshotSums, dt: np.ndarray, beta: float) -> SnapshotSums:
    """Add β Δt_k³ to the q of every pair at Δt_k: a Δt³ term injected analytically.

    The expansion ⟨q⟩ = N + S2Δt² + ⟨δv_∥δa_∥⟩Δt³ + … (docs/statistics.md §1, §4) has a Δt³ term
    that KS lacks (no energy flux, docs/flow.md §7). Each q → q + βΔt_k³, so Σq gains βΔt_k³·n and
    Σq² gains 2βΔt_k³Σq + (βΔt_k³)²n: every per-snapshot mean, hence ⟨q⟩_k and each
    bootstrap replicate, shifts by exactly βΔt_k³ and its scatter is unchanged.

    Parameters
    ----------
    sums : SnapshotSums
        Pair sums of the displacements, q in m².
    dt : ndarray, shape (K,)
        Δt of the sums' columns, s.
    beta : float
        β, m²/s³.

    Returns
    -------
    SnapshotSums
    """
    shift = beta * np.asarray(dt, dtype=float) ** 3
    return replace(
        sums,
        sum_q=sums.sum_q + shift * sums.count,
        sum_q2=sums.sum_q2 + 2 * shift * sums.sum_q + shift**2 * sums.count,
    )


def _mean(sums: PairSums) -> np.ndarray:
    return sums.mean[:, 0]
