"""Multi-Δt sweeps on KS particles without images: how many Δt, what noise, what seeding.

Each point simulates exact double-frame runs of the scenario's flow (one independent
run of M snapshots per Δt, :func:`simulator.particles.double_frame`, whatever the
scenario's ``shared_first_frame``: the conservative design, whose sampling noise does not
cancel between the Δt as it does when they share frame a), measures them
with white Gaussian position noise (:class:`validation.studies.multi_dt_experiment.Measurement`)
and fits c₁Δt² + c₂ per separation bin (docs/statistics.md §3), beside the sample truth of the
same pairs and the exact D_LL of the spectrum.

Sizes. P, the particles per snapshot in the analysis volume, is the scenario's tracer
count times the share of the illuminated sheet the analysis box covers (≈ 780 for the
default scenario); M is the scenario's frame pairs per Δt, at most
:data:`MAX_SNAPSHOTS` unless given (the paper-size scenarios' 1500 would take hours).

- ``dt``: k = 2, 3, 4, 5 Δt values spread over the preset's set (the smallest and the
  largest always in, e.g. indices 0, 2, 4 for k = 3) at a fixed budget of K·M frame
  pairs, split evenly over the k values (docs/statistics.md §3.5: two Δt give the smallest
  Var c₁ for a fixed budget but cannot show curvature).
- ``noise``: σ = 0, 5, 10, 15, 30 µm per component; every point measures the same
  simulated sample, so the differences are the noise's.
- ``seeding``: P = 250, 500, 1000, 2000 at fixed M: the scatter of c₁ at small r goes
  as 1/(P√M) (docs/statistics.md §10).
"""

from dataclasses import replace

import numpy as np

from ptv.stats.structure import StructureFunction
from simulator.particles import Box, DoubleFrameSample, KSFlow, double_frame
from simulator.presets import FlowPreset
from simulator.rigs import load_rig
from simulator.spectra import SPECTRA, Spectrum
from validation.run.scenario import Scenario, scenario_from_dict
from validation.studies.multi_dt_experiment import Measurement, analyse
from validation.studies.runner import Sweep, SweepPoint, seed_sequence

#: Snapshots per Δt when the scenario asks for more and none are given.
MAX_SNAPSHOTS = 100
#: Separations r/η at which the table reports c₁ against the sample truth.
R_OVER_ETA = (10, 40, 100)
#: Position noise of the dt and seeding studies, µm (paper-like, docs/statistics.md §10).
DEFAULT_NOISE_UM = 15.0
DT_COUNTS = (2, 3, 4, 5)
NOISE_UM = (0.0, 5.0, 10.0, 15.0, 30.0)
PARTICLES = (250, 500, 1000, 2000)


def study_sizes(scenario: Scenario, snapshots: int | None) -> tuple[int, int]:
    """(P, M): particles per snapshot in the analysis volume and snapshots per Δt.

    P is the scenario's count in the rig's illuminated sheet times the share of the
    sheet's volume inside the (centred) analysis box.
    """
    if snapshots is not None and snapshots < 2:
        raise ValueError(f"--snapshots must be >= 2 (the bootstrap needs two), got {snapshots}")
    sheet = load_rig(scenario.rig.name).sheet
    inside = np.prod(np.minimum(scenario.ptv.analysis_size, sheet.size))
    particles = max(2, round(scenario.particles.count * inside / sheet.volume))
    if snapshots is None:
        snapshots = min(scenario.particles.frames, MAX_SNAPSHOTS)
    return int(particles), int(snapshots)


def _check_noise(noise_um: float) -> float:
    if not noise_um >= 0:
        raise ValueError(f"--position-noise must be >= 0 µm, got {noise_um}")
    return float(noise_um)


def spread_indices(total: int, count: int) -> list[int]:
    """``count`` indices spread over ``range(total)``, first and last included."""
    return sorted(set(np.round(np.linspace(0, total - 1, count)).astype(int).tolist()))


def dt_sweep(scenario: Scenario, *, snapshots: int | None, noise_um: float) -> Sweep:
    """k Δt of the preset's set at a fixed budget of frame pairs (module docstring)."""
    particles, m = study_sizes(scenario, snapshots)
    total = len(scenario.flow.as_preset().dt_over_tau_eta)
    counts = sorted({k for k in DT_COUNTS if k <= total} | {total})
    points = tuple(
        SweepPoint(
            f"dt-{k}",
            {
                "dt_count": k,
                "dt_indices": spread_indices(total, k),
                "snapshots_per_dt": round(total * m / k),
            },
        )
        for k in counts
    )
    options = {"particles": particles, "noise_um": _check_noise(noise_um), "frame_pairs": total * m}
    return Sweep("dt", dt_task, scenario.as_dict(), options, points)


def noise_sweep(scenario: Scenario, *, snapshots: int | None) -> Sweep:
    """Position noise σ from 0 to 30 µm on one simulated sample."""
    particles, m = study_sizes(scenario, snapshots)
    points = tuple(SweepPoint(f"noise-{s:g}um", {"noise_um": s}) for s in NOISE_UM)
    options = {"particles": particles, "snapshots": m}
    return Sweep("noise", noise_task, scenario.as_dict(), options, points)


def seeding_sweep(scenario: Scenario, *, snapshots: int | None, noise_um: float) -> Sweep:
    """Particles per snapshot P from 250 to 2000 at fixed M."""
    _, m = study_sizes(scenario, snapshots)
    points = tuple(SweepPoint(f"seeding-{p}", {"particles": p}) for p in PARTICLES)
    options = {"snapshots": m, "noise_um": _check_noise(noise_um)}
    return Sweep("seeding", seeding_task, scenario.as_dict(), options, points)


def _flow(scenario: Scenario) -> tuple[FlowPreset, Spectrum, Box]:
    """The scenario's flow, its spectrum and the analysis box."""
    preset = scenario.flow.as_preset()
    spectrum = SPECTRA[scenario.flow.spectrum](preset.parameters)
    return preset, spectrum, Box(scenario.ptv.analysis_size)


def _simulate(
    scenario: Scenario, preset: FlowPreset, *, particles: int, snapshots: int, study: str
) -> DoubleFrameSample:
    """Exact runs of the scenario's flow at the preset's Δt set (seeded per study)."""
    _, spectrum, region = _flow(scenario)
    return double_frame(
        KSFlow(spectrum, n_modes=scenario.flow.modes, unsteadiness=scenario.flow.unsteadiness),
        preset.dt,
        particles=particles,
        snapshots=snapshots,
        region=region,
        rng=seed_sequence(scenario.seed, study, "flow"),
    )


def _analyse(
    scenario: Scenario,
    sample: DoubleFrameSample,
    measurement: Measurement,
    rng: np.random.SeedSequence,
) -> dict:
    """:func:`validation.studies.multi_dt_experiment.analyse` with the scenario's PTV settings."""
    preset, spectrum, region = _flow(scenario)
    ptv = scenario.ptv
    result = analyse(
        sample,
        preset,
        measurement,
        region=region,
        bins=ptv.n_bins,
        inertial_range=tuple(ptv.plateau),
        kolmogorov_c2=ptv.kolmogorov_c2,
        spectrum=spectrum,
        n_boot=ptv.n_boot,
        rng=rng,
    )
    return _summary(
        result.fit,
        result.sample_truth,
        result.exact_dll,
        (result.epsilon_fit, result.epsilon_exact),
        preset.parameters.eta,
        measurement.noise[0],
    )


def _measure(
    settings: dict,
    study: str,
    point: dict,
    *,
    particles: int,
    snapshots: int,
    noise_um: float,
    dt_indices: list[int] | None = None,
) -> dict:
    """Simulate the study's sample, measure it with white noise and analyse it.

    The sample is seeded by the study (every point of a study sees the same flow), the
    noise by the point. ``dt_indices`` keeps only those of the preset's Δt set.
    """
    scenario = scenario_from_dict(settings)
    preset = scenario.flow.as_preset()
    if dt_indices is not None:
        ratios = tuple(preset.dt_over_tau_eta[i] for i in dt_indices)
        preset = replace(preset, dt_over_tau_eta=ratios)
    sample = _simulate(scenario, preset, particles=particles, snapshots=snapshots, study=study)
    rng = seed_sequence(scenario.seed, study, "measurement", point)
    return _analyse(scenario, sample, Measurement(noise=(noise_um * 1e-6,) * 3), rng)


def noise_task(settings: dict, options: dict, point: dict) -> dict:
    """One noise level σ = ``point["noise_um"]`` (µm) on the study's sample.

    Parameters
    ----------
    settings : dict
        The scenario (:meth:`Scenario.as_dict`).
    options : dict
        ``particles`` (P per snapshot in the analysis box) and ``snapshots`` (M per Δt).
    point : dict
        ``noise_um``: position noise per component, µm.

    Returns
    -------
    dict
        ``rows`` (one row: the point, c₁ vs sample truth at :data:`R_OVER_ETA`, ε, c₂)
        and ``curves`` (per separation bin, SI units).
    """
    out = _measure(
        settings,
        "noise",
        point,
        particles=options["particles"],
        snapshots=options["snapshots"],
        noise_um=point["noise_um"],
    )
    out["rows"] = [{**point, **options, **out["rows"][0]}]
    return out


def seeding_task(settings: dict, options: dict, point: dict) -> dict:
    """One seeding density, P = ``point["particles"]`` per snapshot in the analysis box.

    Parameters
    ----------
    settings : dict
        The scenario (:meth:`Scenario.as_dict`).
    options : dict
        ``snapshots`` (M per Δt) and ``noise_um`` (position noise, µm).
    point : dict
        ``particles``: P.

    Returns
    -------
    dict
        As :func:`noise_task`.
    """
    out = _measure(
        settings,
        "seeding",
        point,
        particles=point["particles"],
        snapshots=options["snapshots"],
        noise_um=options["noise_um"],
    )
    out["rows"] = [{**point, **options, **out["rows"][0]}]
    return out


def dt_task(settings: dict, options: dict, point: dict) -> dict:
    """The multi-Δt fit on k Δt of the preset's set, ``snapshots_per_dt`` runs each.

    Parameters
    ----------
    settings : dict
        The scenario (:meth:`Scenario.as_dict`).
    options : dict
        ``particles`` (P), ``noise_um`` (position noise, µm), ``frame_pairs`` (budget).
    point : dict
        ``dt_count`` (k), ``dt_indices`` (into the preset's set), ``snapshots_per_dt``.

    Returns
    -------
    dict
        As :func:`noise_task`.
    """
    out = _measure(
        settings,
        "dt",
        point,
        particles=options["particles"],
        snapshots=point["snapshots_per_dt"],
        noise_um=options["noise_um"],
        dt_indices=point["dt_indices"],
    )
    ratios = scenario_from_dict(settings).flow.as_preset().dt_over_tau_eta
    dt_over_tau_eta = [ratios[i] for i in point["dt_indices"]]
    out["rows"] = [{**point, "dt_over_tau_eta": dt_over_tau_eta, **options, **out["rows"][0]}]
    return out


def _summary(
    fit: StructureFunction,
    truth: np.ndarray,
    exact: np.ndarray,
    epsilon: tuple[float, float],
    eta: float,
    sigma: float,
) -> dict:
    """The table row and the curves of one point.

    Parameters
    ----------
    fit : StructureFunction
        The multi-Δt fit, B bins.
    truth, exact : ndarray, shape (B,)
        Sample-truth S2 of the same pairs and the exact D_LL, m²/s².
    epsilon : (float, float)
        Plateau ε of the fit and of the exact D_LL (same estimator), m²/s³.
    eta : float
        Kolmogorov length, m.
    sigma : float
        Position noise per component, m (c₂ should be 4σ²).

    Returns
    -------
    dict
        ``rows``: one dict of scalars: in the fitted bin nearest each r/η = n of
        :data:`R_OVER_ETA`, ``r_mm_<n>eta`` (mm), ``c1_error_<n>eta`` and ``c1_se_<n>eta``
        (c₁ error and standard error relative to the sample truth) and
        ``raw_over_truth_<n>eta`` (raw S2 at the smallest Δt over the truth); ε of the
        fit and of the exact D_LL (m²/s³) and their relative difference; the median c₂
        (µm²) and its ratio to 4σ²; the median χ²/dof.
        ``curves``: per bin ``r_m``, ``c1``, ``se_c1``, ``c2_m2``, ``sample_truth``,
        ``exact_dll``, ``raw_s2_dt_min`` (SI units).
    """
    r = fit.r
    raw_min = fit.raw_s2[:, int(np.argmin(fit.dt))]
    usable = np.flatnonzero(fit.fitted & np.isfinite(r) & (truth > 0))
    row = {}
    for n in R_OVER_ETA:
        if usable.size:
            b = usable[np.argmin(np.abs(np.log(r[usable] / (n * eta))))]
            values = (r[b] * 1e3, fit.s2[b] / truth[b] - 1, fit.se_s2[b] / truth[b])
            values += (raw_min[b] / truth[b],)
        else:
            values = (np.nan,) * 4
        for name, value in zip(
            ("r_mm", "c1_error", "c1_se", "raw_over_truth"), values, strict=True
        ):
            row[f"{name}_{n}eta"] = float(value)
    c2 = float(np.median(fit.noise[fit.fitted])) if fit.fitted.any() else np.nan
    chi2 = fit.chi2_dof[np.isfinite(fit.chi2_dof)]
    row.update(
        epsilon_fit=epsilon[0],
        epsilon_exact_dll=epsilon[1],
        epsilon_error=epsilon[0] / epsilon[1] - 1,
        c2_median_um2=c2 * 1e12,
        c2_over_4sigma2=c2 / (4 * sigma**2) if sigma > 0 else np.nan,
        chi2_dof_median=float(np.median(chi2)) if chi2.size else np.nan,
    )
    curves = {
        "r_m": r,
        "c1": fit.s2,
        "se_c1": fit.se_s2,
        "c2_m2": fit.noise,
        "sample_truth": truth,
        "exact_dll": exact,
        "raw_s2_dt_min": raw_min,
    }
    return {
        "rows": [row],
        "curves": {k: np.asarray(v, dtype=float).tolist() for k, v in curves.items()},
    }
