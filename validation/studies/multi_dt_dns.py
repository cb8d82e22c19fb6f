"""The Δt study on a Navier–Stokes flow: the Δt³ bias of c₁ as the Δt set is stretched.

On a DNS (``[flow] kind = "dns"``) the multi-Δt fit c₁Δt² + c₂ has a real Δt³ term,
⟨q⟩ = N + S2Δt² + βΔt³ + …, β = ⟨δu_L δa_L⟩ (docs/statistics.md §4). The study takes
the scenario's Δt set scaled by each of :data:`RANGE_SCALES` and measures, per scale and
for the standard binning (separation at t) and the chord-midpoint binning, the bias of
c₁ against the sample truth of the same pairs at 10η, 20η and 40η, with a paired
bootstrap error, beside the prediction γβ(r)/S2(r) from the field's own β: with the
unweighted γ of the Δt set, and with the γ of the weights the fit used (the bootstrap
σ of each ⟨q⟩_k, which favour the small Δt and so shrink γ).

One sample per seed serves every scale: tracers seeded in snapshot m of the field are
followed once over the union of the scaled Δt sets (the particles of a time-resolved
recording, every Δt from the same start), then measured with white Gaussian position
noise (σ = ``noise_um``; a shared start frame, so the noise at t is the same for every
Δt) and without. The field is the scenario's flow stage: the seeds redraw the tracers
and the noise in the same field snapshots, not the field.

The bias and its paired error: :mod:`validation.truth.dt3_bias`.
"""

from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from ptv.bins import LogBins
from simulator.dns.fieldfile import read_field_file_parameters
from simulator.dns.stationary_flow import FIELD_FILE, DnsTracerFlow
from simulator.particles import Box, follow_snapshots
from simulator.turbulence import TurbulenceParameters
from validation.run.dns_checks import beta_over_s2
from validation.run.flow_stage import dns_spec
from validation.run.scenario import Scenario, scenario_from_dict
from validation.studies.runner import Sweep, SweepPoint, seed_sequence
from validation.truth.dt3_bias import at_separation, c1_bias, dt3_gamma

#: Factors applied to the scenario's Δt set.
RANGE_SCALES = (0.5, 1.0, 2.0, 4.0)
#: Separations r/η at which the bias is reported.
BIAS_R_OVER_ETA = (10, 20, 40)
#: The binnings compared (:func:`ptv.stats.pairs.pair_sums`).
BINNINGS = ("start", "midpoint")


def dt_range_sweep(
    scenario: Scenario, *, particles: int, snapshots: int, noise_um: float, field: Path
) -> Sweep:
    """The Δt-range study of a DNS scenario: one point, every scale (module docstring).

    Parameters
    ----------
    scenario : Scenario
        A ``kind = "dns"`` scenario.
    particles, snapshots : int
        P in the analysis volume per snapshot; M snapshots (at most the field's).
    noise_um : float
        Position noise per component, µm.
    field : Path
        The scenario's flow stage (``field.h5``, ``statistics.h5``).

    Raises
    ------
    ValueError
        More snapshots than the field holds.
    """
    frames = scenario.particles.frames
    if snapshots > frames:
        raise ValueError(
            f"--snapshots {snapshots}: the DNS field holds {frames} snapshots "
            "([particles] frames of the scenario)"
        )
    options = {
        "particles": particles,
        "snapshots": snapshots,
        "noise_um": noise_um,
        "field": str(field),
    }
    point = SweepPoint("dt-ranges", {"scales": list(RANGE_SCALES)})
    return Sweep("dt", dt_range_task, scenario.as_dict(), options, (point,))


def dt_range_task(settings: dict, options: dict, point: dict) -> dict:
    """Follow one sample over every scaled Δt set and measure the bias of c₁.

    Parameters
    ----------
    settings : dict
        The scenario (:meth:`Scenario.as_dict`).
    options : dict
        ``particles``, ``snapshots``, ``noise_um`` and ``field`` (the flow stage's folder).
    point : dict
        ``scales``: the factors of the Δt set.

    Returns
    -------
    dict
        ``rows``: per scale, binning and noise (0 and σ), ``dt_max_over_tau_eta``,
        ``gamma_s`` and per r/η = n of :data:`BIAS_R_OVER_ETA` ``r_mm_<n>eta``,
        ``bias_<n>eta``, ``bias_se_<n>eta`` (relative to the sample truth), and the
        predictions γβ/S2 with the unweighted γ of the set (``predicted_<n>eta``,
        docs/statistics.md §4) and with the γ of the fit's own weights in that bin
        (``predicted_weighted_<n>eta``); ``curves``: nothing per bin (an empty dict).
    """
    scenario = scenario_from_dict(settings)
    folder = Path(options["field"])
    spec = dns_spec(scenario)
    field_scales = read_field_file_parameters(folder / FIELD_FILE)
    parameters = TurbulenceParameters(u_rms=field_scales.u_rms, epsilon=spec.epsilon, nu=spec.nu)
    preset = scenario.flow.as_preset(parameters)
    base = np.asarray(preset.dt, dtype=float)
    sets = [scale * base for scale in point["scales"]]
    times = np.unique(np.concatenate([[0.0], *sets]))
    region = Box(scenario.ptv.analysis_size)
    sample = follow_snapshots(
        DnsTracerFlow(spec, folder / FIELD_FILE, field_scales.u_rms),
        times,
        particles=options["particles"],
        snapshots=options["snapshots"],
        region=region,
        rng=seed_sequence(scenario.seed, "dt-range", "flow"),
    )
    bins = LogBins(scenario.ptv.r_min, scenario.ptv.r_max, scenario.ptv.n_bins)
    beta_of_r = beta_over_s2(folder)
    rows = []
    for noise_um in sorted({0.0, float(options["noise_um"])}):
        noise = seed_sequence(scenario.seed, "dt-range", "noise", noise_um)
        measured = sample.positions + np.random.default_rng(noise).normal(
            0.0, noise_um * 1e-6, sample.positions.shape
        )
        for scale, dt in zip(point["scales"], sets, strict=True):
            columns = np.searchsorted(times, dt)
            for binning in BINNINGS:
                bias = c1_bias(
                    times,
                    measured,
                    sample.positions[:, 0],
                    sample.velocity[:, 0],
                    columns,
                    region=region,
                    bins=bins,
                    binning=binning,
                    n_boot=scenario.ptv.n_boot,
                    rng=seed_sequence(scenario.seed, "dt-range", "bootstrap"),
                )
                row = {
                    "scale": scale,
                    "dt_max_over_tau_eta": float(dt[-1] / parameters.tau_eta),
                    "binning": binning,
                    "noise_um": noise_um,
                    "gamma_s": dt3_gamma(dt),
                }
                for n in BIAS_R_OVER_ETA:
                    r, value, se, gamma_weighted = at_separation(bias, n * parameters.eta)
                    row[f"r_mm_{n}eta"] = r * 1e3
                    row[f"bias_{n}eta"] = value
                    row[f"bias_se_{n}eta"] = se
                    row[f"predicted_{n}eta"] = dt3_gamma(dt) * beta_of_r(r)
                    row[f"predicted_weighted_{n}eta"] = gamma_weighted * beta_of_r(r)
                rows.append(row)
    return {"rows": rows, "curves": {}}


def dt_range_figure(rows: Sequence[dict], title: str) -> Figure:
    """The bias of c₁ against the largest Δt of the set, per r/η (columns) and noise
    (rows): standard and midpoint binning, each seed its own marker (the seeds share
    the field), ±1 paired standard error; the prediction γβ/S2 dashed.

    Parameters
    ----------
    rows : sequence of dict
        :func:`dt_range_task` rows, with ``seed``.
    title : str
        The figure's title.
    """
    noises = sorted({row["noise_um"] for row in rows})
    seeds = sorted({row["seed"] for row in rows})
    fig, axes = plt.subplots(
        len(noises),
        len(BIAS_R_OVER_ETA),
        figsize=(4.2 * len(BIAS_R_OVER_ETA), 3.4 * len(noises)),
        squeeze=False,
        sharex=True,
    )
    styles = {"start": ("C0", "standard (binned at t)"), "midpoint": ("C1", "chord midpoint")}
    for i, noise in enumerate(noises):
        for j, n in enumerate(BIAS_R_OVER_ETA):
            ax = axes[i, j]
            ax.axhline(0.0, color="0.6", lw=0.8)
            for binning, (colour, label) in styles.items():
                for s, seed in enumerate(seeds):
                    mine = [
                        r
                        for r in rows
                        if (r["noise_um"], r["binning"], r["seed"]) == (noise, binning, seed)
                    ]
                    x = np.array([r["dt_max_over_tau_eta"] for r in mine])
                    shift = (
                        1
                        + 0.03 * (s - (len(seeds) - 1) / 2)
                        + (0.01 if binning == "midpoint" else -0.01)
                    )
                    y = 100 * np.array([r[f"bias_{n}eta"] for r in mine], dtype=float)
                    e = 100 * np.array([r[f"bias_se_{n}eta"] for r in mine], dtype=float)
                    ax.errorbar(
                        x * shift,
                        y,
                        e,
                        color=colour,
                        marker="os^v"[s % 4],
                        ms=4,
                        capsize=2,
                        lw=1,
                        label=f"{label}, seed {seed}" if (i, j) == (0, 0) else None,
                    )
            first = sorted(
                (
                    r
                    for r in rows
                    if r["noise_um"] == noise and r["binning"] == "start" and r["seed"] == seeds[0]
                ),
                key=lambda r: r["dt_max_over_tau_eta"],
            )
            x = [r["dt_max_over_tau_eta"] for r in first]
            ax.plot(
                x,
                [100 * r[f"predicted_{n}eta"] for r in first],
                "k--",
                lw=1,
                label="predicted γβ/S2, γ unweighted" if (i, j) == (0, 0) else None,
            )
            ax.plot(
                x,
                [100 * r[f"predicted_weighted_{n}eta"] for r in first],
                "k:",
                lw=1.2,
                label="predicted, γ of the fit's weights" if (i, j) == (0, 0) else None,
            )
            r_mm = np.nanmean([r[f"r_mm_{n}eta"] for r in first])
            ax.set_title(f"{n}η (bin at {r_mm:.2f} mm), σ = {noise:g} µm", fontsize=9)
            ax.set_xscale("log")
            ax.set_xticks(x, [f"{v:.2g}" for v in x])
            ax.minorticks_off()
            if j == 0:
                ax.set_ylabel("c₁ / sample truth − 1 (%)")
            if i == len(noises) - 1:
                ax.set_xlabel("largest Δt of the set / τ_η")
    fig.suptitle(title, fontsize=9)
    fig.legend(loc="lower center", ncol=3, fontsize=8, bbox_to_anchor=(0.5, -0.06))
    fig.text(
        0.5,
        -0.09,
        "Error bars: ±1 standard error of c₁/truth − 1, bootstrap over snapshots with the "
        "truth resampled alike (paired). The seeds redraw tracers and noise in the same "
        "field snapshots.",
        ha="center",
        fontsize=8,
    )
    fig.tight_layout(rect=(0, 0, 1, 0.97))
    return fig
