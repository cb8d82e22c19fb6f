"""Prescribed and realized statistics of a KS flow (the ``synptv flow`` command)."""

from dataclasses import dataclass

import numpy as np

from ptv.bins import LogBins
from simulator.ks_field import DEFAULT_UNSTEADINESS
from simulator.particles import ANALYSIS_VOLUME, Box, KSFlow, Progress, follow_snapshots
from simulator.spectra import SPECTRA, Spectrum, discretise
from simulator.truth import longitudinal_structure_function
from simulator.turbulence import TurbulenceParameters
from validation.truth.sample import sample_structure_function

#: Snapshot batches used to estimate the standard error of the sample S2.
BATCHES = 10


@dataclass(frozen=True)
class FlowSettings:
    """What ``synptv flow`` samples.

    Attributes
    ----------
    parameters : TurbulenceParameters
        Prescribed u', ε, ν.
    spectrum : str
        A key of :data:`simulator.spectra.SPECTRA` (``pope`` or ``k41-band``).
    particles : int
        Particles per snapshot inside ``region``.
    snapshots : int
        Independent realizations M.
    n_modes : int
        KS modes N.
    unsteadiness : float
        λ in ω_n = λ √(k³E).
    bins : int
        Logarithmic separation bins over [10 η, L_int/2].
    region : Box
        Volume holding the particles (the paper's analysis volume by default).
    seed : int
        Seed of the random generator.
    """

    parameters: TurbulenceParameters
    spectrum: str = "pope"
    particles: int = 2000
    snapshots: int = 1000
    n_modes: int = 200
    unsteadiness: float = DEFAULT_UNSTEADINESS
    bins: int = 24
    region: Box = ANALYSIS_VOLUME
    seed: int = 0

    def build_spectrum(self) -> Spectrum:
        """The continuous spectrum named by ``spectrum``."""
        try:
            kind = SPECTRA[self.spectrum]
        except KeyError:
            raise ValueError(
                f"unknown spectrum {self.spectrum!r}; known: {', '.join(SPECTRA)}"
            ) from None
        return kind(self.parameters)


def summarize_flow(settings: FlowSettings, *, progress: Progress | None = None) -> dict:
    """Sample a KS flow and compare its realized statistics with the prescribed ones.

    Parameters
    ----------
    settings : FlowSettings
        What to sample.
    progress : callable(done, total), optional
        Called after each snapshot and each batch of pair binning.

    Returns
    -------
    dict
        ``prescribed`` (u_rms, epsilon, nu, eta, tau_eta, R_lambda, L_int, …),
        ``spectrum`` (mode range and the energy and dissipation of the modes),
        ``realized`` (u_rms and its standard error, s2_max_rel_err over
        10 η ≤ r ≤ L_int/2 and the largest standard error of the sample S2 there) and
        ``s2`` (per bin: r, sample-truth S2, exact D_LL, pair count), SI units.
    """
    p = settings.parameters
    spectrum = settings.build_spectrum()
    modes = discretise(spectrum, settings.n_modes)
    n_batches = min(BATCHES, settings.snapshots)
    total_steps = settings.snapshots + n_batches

    def report(done: int) -> None:
        if progress is not None:
            progress(done, total_steps)

    sample = follow_snapshots(
        KSFlow(spectrum, n_modes=settings.n_modes, unsteadiness=settings.unsteadiness),
        np.array([0.0]),
        particles=settings.particles,
        snapshots=settings.snapshots,
        region=settings.region,
        rng=settings.seed,
        progress=lambda done, _total: report(done),
    )
    x, u = sample.positions[:, 0], sample.velocity[:, 0]
    inside = settings.region.contains(x)
    u_inside = u[inside]
    per_snapshot = np.array([np.mean(v[m] ** 2) for v, m in zip(u, inside, strict=True)])
    u_rms = float(np.sqrt(np.mean(u_inside**2)))
    u_rms_stderr = float(np.std(per_snapshot, ddof=1) / np.sqrt(len(per_snapshot)) / (2 * u_rms))

    bins = LogBins(10 * p.eta, p.L_int / 2, settings.bins)
    batches = []
    for n, idx in enumerate(np.array_split(np.arange(settings.snapshots), n_batches)):
        batches.append(sample_structure_function(x[idx], u[idx], bins, region=settings.region))
        report(settings.snapshots + n + 1)
    total = batches[0]
    for b in batches[1:]:
        total = total + b
    s2 = total.mean[:, 0]
    r = total.mean_separation
    exact = longitudinal_structure_function(spectrum, np.where(np.isfinite(r), r, bins.centres))
    rel = s2 / exact - 1.0
    batch_means = np.array([b.mean[:, 0] for b in batches])
    with np.errstate(invalid="ignore"):
        stderr = np.nanstd(batch_means, axis=0, ddof=1) / np.sqrt(len(batches)) / exact
    filled = total.count > 0
    return {
        "prescribed": p.as_dict(),
        "spectrum": {
            "kind": settings.spectrum,
            "n_modes": settings.n_modes,
            "unsteadiness": settings.unsteadiness,
            "k_min": float(modes.k[0]),
            "k_max": float(modes.k[-1]),
            "modes_energy_over_k_t": float(modes.energy.sum() / p.k_t),
            "modes_dissipation_over_epsilon": float(
                2 * p.nu * np.sum(modes.k**2 * modes.energy) / p.epsilon
            ),
        },
        "sample": {
            "particles": settings.particles,
            "snapshots": settings.snapshots,
            "region_size": list(settings.region.size),
            "seed": settings.seed,
        },
        "realized": {
            "u_rms": u_rms,
            "u_rms_stderr": u_rms_stderr,
            "s2_max_rel_err": float(np.max(np.abs(rel[filled]))),
            "s2_max_rel_stderr": float(np.nanmax(stderr[filled])),
            "s2_r_range": [bins.r_min, bins.r_max],
        },
        "s2": {
            "r": _json_list(r),
            "sample_truth": _json_list(s2),
            "exact_dll": _json_list(exact),
            "pairs": total.count.tolist(),
        },
    }


def _json_list(values: np.ndarray) -> list[float | None]:
    """Floats for JSON, with None where a bin is empty (JSON has no NaN)."""
    return [float(v) if np.isfinite(v) else None for v in values]
