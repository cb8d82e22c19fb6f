"""What a run on a Navier–Stokes flow adds to the report: the DNS's own checks and the
Δt³ term of the multi-Δt method, measured (docs/dns.md §11, docs/statistics.md §4).

From the field's statistics (``statistics.h5`` of the flow stage, exact on the grid):

- **energy budget**: the mean dissipation over the stationary window against the
  injected ε (the forcing injects exactly ε; their difference is the energy's drift over
  the window);
- **Kármán–Howarth**: S3(r) against 6ν dS2/dr − (6/r⁴)∫₀^r y⁴F_LL dy (forced stationary
  turbulence), in standard errors of the mean over the snapshots, from three grid
  spacings to a quarter box;
- **the energy flux**: ⟨δu·δa⟩(r) and ⟨δu_L δa_L⟩(r), beside −2ε, the inertial-range
  value of the first.

From the true trajectories of the dataset (every Δt from the shared first frame, no
noise, the run's analysis volume and bins): the bias of c1 against the sample truth of
its pairs at 10η, 20η and 40η with its paired bootstrap error
(:mod:`validation.truth.dt3_bias`), binned by the separation at t (the standard fit) and
by the chord midpoint, beside the prediction γβ(r)/S2 of docs/statistics.md §4 with
β = ⟨δu_L δa_L⟩ of the field, γ of the Δt set unweighted and γ of the fit's weights. The
check: the standard fit's bias is the weighted prediction, Σz² ≤ :data:`DT3_CHI2_LIMIT`
over the three separations.

**The flux from the tracers** (docs/dns.md §13): the tracers' Lagrangian acceleration
fitted to their positions over the Δt set (:mod:`validation.truth.acceleration_fit`,
which never calls the DNS's acceleration code), their pairs' ⟨δu·δa⟩ at
:data:`FLUX_R_OVER_ETA` η (:mod:`validation.truth.pair_flux`) against the field's from
the solver's acceleration, snapshot by snapshot (the tracers of snapshot m are seeded in
field snapshot m: the difference is paired). The check: |tracers − field| within the
allowance (the fit's truncation and the spline's gradient in the path's acceleration,
each bounded by Cauchy–Schwarz, and the field's direction sampling) plus
:func:`~validation.score.tolerances.false_alarm_z` of the effective snapshots times the
moving-block bootstrap error of the mean difference.
"""

import h5py
import numpy as np

from ptv.bins import LogBins
from ptv.stats.resampling import autocorrelation_time, block_length, block_weights
from simulator.dns.field_statistics import forcing_flux, modal_dll_slope
from simulator.particles import Box
from validation.score.tolerances import FALSE_ALARM, false_alarm_z
from validation.truth.acceleration_fit import (
    DEFAULT_TERMS,
    acceleration_from_positions,
    truncation_bound,
)
from validation.truth.dt3_bias import at_separation, c1_bias, dt3_gamma
from validation.truth.pair_flux import pair_flux
from validation.truth.truth_file import TruthFile

#: Energy budget: the stationary window's mean dissipation within this of ε.
BUDGET_TOLERANCE = 0.02
#: Kármán–Howarth: the residual within this many standard errors, from
#: :data:`KH_MIN_STEPS` grid spacings to a quarter box (below the forcing scale).
KH_SE = 3.0
#: Below three grid spacings the 2/3-rule cut shapes the increments themselves: the
#: balance misses by 26 % at one spacing and 9 % at two on 64³ (docs/dns.md §11).
KH_MIN_STEPS = 3
#: Separations (in η) where the Δt³ bias is reported.
BIAS_R_OVER_ETA = (10.0, 20.0, 40.0)
#: The Δt³ bias against γβ/S2: Σz² over the three separations within the 99th
#: percentile of χ² with 3 degrees of freedom (z in paired standard errors).
DT3_CHI2_LIMIT = 11.34
#: The flux check's separation, in η: near the peak of ⟨δu·δa⟩/(−2ε) at these R_λ.
FLUX_R_OVER_ETA = 10.0
#: Its pair bins: geometric, √2 apart, centred on 5, 7.1, 10, 14 and 20 η; the paired
#: differences of all five give the snapshots' lag-one correlation, the middle one the check.
FLUX_BIN_STEP = np.sqrt(2.0)
FLUX_BINS = 5
#: Moving-block bootstrap replicates of the mean paired difference.
FLUX_REPLICATES = 2000
#: The spline's gradient error carried by the sweeping, in units of u′(ε/ν)^½
#: (:func:`interpolation_error`): measured 6.0·10⁻⁴ on dns-ci (rms over 5 × 3164 tracers of
#: the path's acceleration, with ∇ of the velocity's spline, less the solver's), taken
#: 2.5 times larger for other grids and Reynolds numbers.
FLUX_INTERPOLATION = 1.5e-3
#: Allowance for the field's direction sampling: its increments are averaged over 13
#: grid directions, the pairs' over all; from three grid spacings on the 13-direction S2
#: and S3 lie within 1–2 % of the isotropic values (docs/dns.md §11).
FLUX_DIRECTIONS = 0.02


def _field(folder) -> dict:
    with h5py.File(folder / "statistics.h5", "r") as f:
        out = {name: f[name][()] for name in ("r", "shell_k", "band_k")}
        for name in ("shell_energy", "band_energy", "s2", "s3", "du_da", "dul_dal"):
            out[name] = f[name][()]
        out["history"] = {name: f[f"history/{name}"][()] for name in f["history"]}
        out.update({name: float(f.attrs[name]) for name in ("epsilon", "nu", "box_side")})
    return out


def _budget(field: dict, eddy_time: float) -> dict:
    h = field["history"]
    weights = h["steps"]
    ratio = float(np.sum(h["dissipation"] * weights) / np.sum(weights) / field["epsilon"])
    return {
        "dissipation_over_injection": ratio,
        "window_eddy_times": float(np.sum(weights) / eddy_time),
        "tolerance": BUDGET_TOLERANCE,
        "passed": abs(ratio - 1) <= BUDGET_TOLERANCE,
    }


def _karman_howarth(field: dict) -> dict:
    r, nu, epsilon = field["r"], field["nu"], field["epsilon"]
    s3 = field["s3"]
    m = len(s3)
    mean, se = s3.mean(axis=0), s3.std(axis=0, ddof=1) / np.sqrt(m)
    slope = modal_dll_slope(field["shell_k"], field["shell_energy"].mean(axis=0), r)
    forcing = forcing_flux(field["band_k"], field["band_energy"].mean(axis=0), epsilon, r)
    predicted = 6 * nu * slope - forcing
    residual = (mean - predicted) / se
    below = (r >= KH_MIN_STEPS * r[0]) & (r <= field["box_side"] / 4)
    return {
        "r_m": r.tolist(),
        "s3": mean.tolist(),
        "se_s3": se.tolist(),
        "predicted": predicted.tolist(),
        "four_fifths": (-0.8 * epsilon * r).tolist(),
        "residual_in_se": residual.tolist(),
        "max_residual_in_se": float(np.abs(residual[below]).max()),
        "tolerance_se": KH_SE,
        "passed": bool(np.abs(residual[below]).max() <= KH_SE),
    }


def _flux(field: dict, eta: float) -> dict:
    epsilon = field["epsilon"]
    return {
        "r_over_eta": (field["r"] / eta).tolist(),
        "du_da_over_minus_2eps": (field["du_da"].mean(axis=0) / (-2 * epsilon)).tolist(),
        "dul_dal_over_minus_2eps": (field["dul_dal"].mean(axis=0) / (-2 * epsilon)).tolist(),
    }


def beta_over_s2(folder):
    """r (m) → β(r)/S2(r) of a DNS stage's field statistics, 1/s: β = ⟨δu_L δa_L⟩ and S2
    averaged over the snapshots, interpolated in log r (NaN for a NaN r)."""
    field = _field(folder)
    r = np.log(field["r"])
    ratio = field["dul_dal"].mean(axis=0) / field["s2"].mean(axis=0)
    return lambda x: float(np.interp(np.log(x), r, ratio)) if np.isfinite(x) else np.nan


def _trajectories(truth: TruthFile) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(times (K + 1,), positions (M, K + 1, N, 3), start (M, N, 3), velocity (M, N, 3)):
    the true trajectories of a shared-first-frame dataset, every Δt from the same start."""
    runs = truth.runs()
    positions = np.stack([runs[0].positions[:, 0], *(run.positions[:, 1] for run in runs)], 1)
    times = np.concatenate([[0.0], [run.dt for run in runs]])
    return times, positions, runs[0].positions[:, 0], runs[0].velocity


def _dt3_bias(folder, truth: TruthFile, ptv, seed: int, eta: float) -> dict | None:
    """The paired bias of c1 on the true trajectories, both binnings, at
    :data:`BIAS_R_OVER_ETA`, beside γβ/S2 of the field (module docstring)."""
    if not truth.shared_first_frame:
        return None
    ratio = beta_over_s2(folder)
    times, positions, start, velocity = _trajectories(truth)
    columns = np.arange(1, len(times))
    gamma = dt3_gamma(times[columns])
    measured = {}
    for binning in ("start", "midpoint"):
        measured[binning] = c1_bias(
            times,
            positions,
            start,
            velocity,
            columns,
            region=Box(ptv.analysis_size),
            bins=LogBins(ptv.r_min, ptv.r_max, ptv.n_bins),
            binning=binning,
            n_boot=ptv.n_boot,
            rng=np.random.SeedSequence([seed, 3]),
        )
    rows = []
    for n in BIAS_R_OVER_ETA:
        row = {"r_over_eta": n}
        for binning, name in (("start", "standard"), ("midpoint", "midpoint")):
            r, bias, se, gamma_weighted = at_separation(measured[binning], n * eta)
            row[name] = {"r_m": r, "bias": bias, "se": se}
            if binning == "start":
                row["predicted"] = gamma * ratio(r)
                row["predicted_weighted"] = gamma_weighted * ratio(r)
                row["z"] = (bias - gamma_weighted * ratio(r)) / se
        rows.append(row)
    z = np.array([row["z"] for row in rows])
    chi2 = float(np.sum(z[np.isfinite(z)] ** 2))
    return {
        "gain_s": gamma,
        "rows": rows,
        "chi2": chi2,
        "chi2_limit": DT3_CHI2_LIMIT,
        "passed": bool(np.all(np.isfinite(z)) and chi2 <= DT3_CHI2_LIMIT),
    }


def flux_edges(eta: float) -> np.ndarray:
    """The flux check's pair bins: :data:`FLUX_BINS` bins :data:`FLUX_BIN_STEP` apart in
    r, the middle one centred (geometrically) on :data:`FLUX_R_OVER_ETA` η, shape
    (FLUX_BINS + 1,), m."""
    steps = np.arange(FLUX_BINS + 1) - FLUX_BINS / 2
    return FLUX_R_OVER_ETA * eta * FLUX_BIN_STEP**steps


def interpolation_error(u_rms: float, epsilon: float, nu: float) -> float:
    """How far a tracer path's acceleration may lie from the field's at the same point,
    rms per component, m/s²: :data:`FLUX_INTERPOLATION` u′(ε/ν)^½.

    A tracer moves with the spline S[u] of the field, so its path accelerates at
    S[∂u/∂t] + (S[u]·∇)S[u]; the field's acceleration (and the solver's at the tracers)
    has the spline of the spectral gradient, S[∇u], in its place. The two gradients
    differ by the spline's error, a small fraction of the gradient's rms (ε/ν)^½, and the
    difference is carried by the sweeping velocity, of rms u′.
    """
    return FLUX_INTERPOLATION * u_rms * float(np.sqrt(epsilon / nu))


def flux_comparison(
    tracers: np.ndarray,
    field: np.ndarray,
    *,
    du2: np.ndarray,
    truncation_rms: float,
    interpolation_rms: float,
    epsilon: float,
    seed: int,
) -> dict:
    """The flux check on per-snapshot pair means (module docstring, docs/dns.md §13).

    Parameters
    ----------
    tracers : ndarray, shape (M, B)
        ⟨δu·δa⟩ of the tracers' pairs per snapshot (in time order) and bin, m²/s³; the
        middle bin is checked, all B give the snapshots' correlation.
    field : ndarray, shape (M, B)
        The field's ⟨δu·δa⟩ over the same pairs, m²/s³.
    du2 : ndarray, shape (M, B)
        ⟨|δu|²⟩ of the pairs, m²/s².
    truncation_rms : float
        rms per component of the fitted acceleration's truncation error, m/s².
    interpolation_rms : float
        rms per component of the difference between a tracer path's acceleration and
        the field's interpolated at it (:func:`interpolation_error`), m/s².
    epsilon : float
        The injected ε (the scale of the values shown), m²/s³.
    seed : int
        Seeds the bootstrap.

    Returns
    -------
    dict
        ``tracers``, ``field`` (over −2ε), ``difference`` (tracers − field, m²/s³) and
        ``difference_over_2eps``; ``se`` its bootstrap error (m²/s³), ``correlation``
        (lag-one correlation, τ, effective snapshots), ``block``, ``dof``, ``z``,
        ``allowance`` (``truncation``, ``interpolation``, ``directions``, m²/s³),
        ``tolerance`` (m²/s³) and ``tolerance_over_2eps``, and ``passed``.
    """
    tracers, field, du2 = (np.asarray(v, dtype=float) for v in (tracers, field, du2))
    m, n_bins = tracers.shape
    centre = n_bins // 2
    difference = tracers - field
    correlation = autocorrelation_time(difference)
    block = block_length(correlation)
    weights = block_weights(FLUX_REPLICATES, m, block, np.random.default_rng([seed, 13]))
    replicates = weights @ difference[:, centre] / m
    se = float(np.std(replicates, ddof=1))
    dof = correlation.effective_snapshots - 1.0
    z = false_alarm_z(dof)
    mean = float(np.mean(difference[:, centre]))
    field_mean = float(np.mean(field[:, centre]))
    # An error e of each tracer's a moves the flux by ⟨δu·δe⟩, and by Cauchy–Schwarz
    # |⟨δu·δe⟩| ≤ ⟨|δu|²⟩^½ ⟨|δe|²⟩^½ with ⟨|δe|²⟩ ≤ 4⟨|e|²⟩ = 12 e_rms² (e_rms per
    # component); the same bound holds for δu_L δe_L.
    per_error = 2.0 * np.sqrt(3.0) * float(np.sqrt(np.mean(du2[:, centre])))
    truncation = per_error * truncation_rms
    interpolation = per_error * interpolation_rms
    directions = FLUX_DIRECTIONS * abs(field_mean)
    tolerance = truncation + interpolation + directions + z * se
    finite = bool(np.isfinite([mean, se, tolerance]).all())
    return {
        "tracers": float(np.mean(tracers[:, centre])) / (-2 * epsilon),
        "field": field_mean / (-2 * epsilon),
        "difference": mean,
        "difference_over_2eps": mean / (2 * epsilon),
        "se": se,
        "correlation": correlation.as_dict(),
        "block": block,
        "dof": dof,
        "false_alarm": FALSE_ALARM,
        "z": z,
        "allowance": {
            "truncation": truncation,
            "interpolation": interpolation,
            "directions": directions,
        },
        "tolerance": tolerance,
        "tolerance_over_2eps": tolerance / (2 * epsilon),
        "passed": bool(finite and abs(mean) <= tolerance),
    }


def tracer_flux(
    field: dict,
    times: np.ndarray,
    positions: np.ndarray,
    velocity: np.ndarray,
    *,
    eta: float,
    seed: int,
) -> dict:
    """⟨δu·δa⟩ at :data:`FLUX_R_OVER_ETA` η from the tracers' fitted acceleration against
    the field's from the solver's (module docstring, docs/dns.md §13).

    Parameters
    ----------
    field : dict
        The flow stage's statistics (:func:`field_statistics`: ``r`` (R,), ``du_da``
        and ``dul_dal`` (M, R), ``epsilon``).
    times : ndarray, shape (T,)
        0 and the Δt set, s.
    positions : ndarray, shape (M, T, P, 3)
        The tracers of snapshot m (seeded in field snapshot m) at those times, m.
    velocity : ndarray, shape (M, P, 3)
        Their exact velocity at the start, m/s.
    eta : float
        η, m.
    seed : int
        Seeds the bootstrap.

    Returns
    -------
    dict
        :func:`flux_comparison`'s, with the pairs' mean ``r_m`` and ``r_over_eta``, the
        bin's ``edges_m``, ``pairs_per_snapshot``, the ``longitudinal`` terms (over −2ε)
        and the ``acceleration_fit``'s truncation (:class:`TruncationBound`).
    """
    if len(positions) != len(field["du_da"]):
        raise ValueError(
            f"{len(positions)} snapshots of tracers, the field's statistics hold "
            f"{len(field['du_da'])}"
        )
    acceleration = acceleration_from_positions(times, positions, velocity)
    bound = truncation_bound(times, positions, velocity)
    edges = flux_edges(eta)
    rows = [
        pair_flux(
            positions[m, 0],
            velocity[m],
            acceleration[m],
            edges,
            field_r=field["r"],
            field_du_da=field["du_da"][m],
            field_dul_dal=field["dul_dal"][m],
        )
        for m in range(len(positions))
    ]
    u_rms = float(np.sqrt(np.mean(np.asarray(velocity, dtype=float) ** 2)))
    errors = {
        "du2": np.array([row.du2 for row in rows]),
        "truncation_rms": bound.error_rms,
        "interpolation_rms": interpolation_error(u_rms, field["epsilon"], field["nu"]),
        "epsilon": field["epsilon"],
        "seed": seed,
    }
    out = flux_comparison(
        np.array([row.du_da for row in rows]),
        np.array([row.field_du_da for row in rows]),
        **errors,
    )
    longitudinal = flux_comparison(
        np.array([row.dul_dal for row in rows]),
        np.array([row.field_dul_dal for row in rows]),
        **errors,
    )
    centre = FLUX_BINS // 2
    r = float(np.mean([row.r[centre] for row in rows]))
    out.update(
        {
            "r_m": r,
            "r_over_eta": r / eta,
            "edges_m": edges[centre : centre + 2].tolist(),
            "pairs_per_snapshot": float(np.mean([row.count[centre] for row in rows])),
            "longitudinal": {
                key: longitudinal[key]
                for key in ("tracers", "field", "difference_over_2eps", "se", "tolerance_over_2eps")
            },
            "acceleration_fit": bound.as_dict(),
            "u_rms": u_rms,
        }
    )
    return out


def tracer_flux_check(field: dict, truth: TruthFile, *, eta: float, seed: int) -> dict | None:
    """:func:`tracer_flux` of a dataset's true trajectories; None without a shared first
    frame or with fewer Δt than the truncation bound needs (DEFAULT_TERMS + 1)."""
    if not truth.shared_first_frame or len(truth.dt) < DEFAULT_TERMS + 1:
        return None
    times, positions, _, velocity = _trajectories(truth)
    return tracer_flux(field, times, positions, velocity, eta=eta, seed=seed)


def field_statistics(folder) -> dict:
    """The flow stage's ``statistics.h5`` (``r``, the per-snapshot moments ``s2``, ``s3``,
    ``du_da``, ``dul_dal`` (M, R), the shell energies, the window's ``history``, and
    ``epsilon``, ``nu``, ``box_side``), SI."""
    return _field(folder)


def field_checks(field: dict, eddy_time: float) -> dict:
    """The checks of the field alone: ``energy_budget`` and ``karman_howarth``
    (module docstring), from :func:`field_statistics` and the window's T_L (s)."""
    return {"energy_budget": _budget(field, eddy_time), "karman_howarth": _karman_howarth(field)}


def dns_section(folder, *, flow: dict, truth: TruthFile, ptv, seed: int) -> dict:
    """The report's ``dns`` section (module docstring).

    Parameters
    ----------
    folder : Path
        The flow stage (its ``statistics.h5``).
    flow : dict
        results.json's ``flow`` (eta, eddy_time).
    truth : TruthFile
        The dataset's truth (the true trajectories).
    ptv : PtvSection
        The scenario's analysis volume, separation bins and bootstrap size.
    seed : int
        The scenario's seed (the bootstrap's).
    """
    field = _field(folder)
    return {
        **field_checks(field, flow["eddy_time"]),
        "flux": _flux(field, flow["eta"]),
        "dt3_bias": _dt3_bias(folder, truth, ptv, seed, flow["eta"]),
        "tracer_flux": tracer_flux_check(field, truth, eta=flow["eta"], seed=seed),
    }
