"""Figures of tracks scored against a recording's truth.

- :func:`track_lengths_figure`: points per track beside observed frames per true
  trajectory, on the bins of :data:`validation.score.trajectories.LENGTH_EDGES`;
- :func:`fit_window_figure`: the fitted acceleration's rms error against the fit
  window, on the tracks, on the true positions plus the measured noise (the estimator's
  floor), and as predicted from the noise and the flow;
- :func:`lagrangian_figure`: S2ᴸ(τ) raw, noise-removed and exact, and the PDF of the
  fitted and true accelerations.
"""

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure


def track_lengths_figure(scores: dict, title: str) -> Figure:
    """Histograms of track and trajectory lengths from :func:`trajectory_scores`'s
    ``lengths``."""
    lengths = scores["lengths"]
    edges = lengths["tracks"]["edges"]
    uppers = [*edges[1:], None]  # the last bin is open
    labels = [
        f"≥ {a}" if b is None else (f"{a}" if b - a == 1 else f"{a}–{b - 1}")
        for a, b in zip(edges, uppers, strict=True)
    ]
    x = np.arange(len(edges))
    fig, ax = plt.subplots(figsize=(8, 4))
    for offset, key, name in (
        (-0.2, "trajectories", "true trajectories"),
        (0.2, "tracks", "tracks"),
    ):
        counts = lengths[key]["counts"]
        mean = lengths[key]["mean"]
        ax.bar(
            x + offset,
            counts,
            width=0.4,
            label=f"{name} (mean {mean:.1f})" if mean is not None else name,
        )
    ax.set_xticks(x, labels, rotation=45)
    ax.set_yscale("log")
    ax.set_xlabel("length, frames (trajectories: observed frames; tracks: points)")
    ax.set_ylabel("count")
    ax.set_title(title, fontsize=9)
    ax.legend()
    return fig


def fit_window_figure(fit: dict, title: str) -> Figure:
    """The fitted acceleration's rms error against the fit window (``fit`` of
    :func:`validation.run.recording_scores.score_sequences`): on the tracks, its floor
    (the true positions of the same points plus the measured noise), and as predicted
    from the noise and ⟨|x⁽⁴⁾|²⟩; the chosen window marked."""
    fig, ax = plt.subplots(figsize=(7, 4.5))
    measured, predicted = fit["measured"], fit["predicted"]
    ax.plot(measured["windows"], measured["error"], "o-", label="tracks against truth")
    ax.plot(measured["windows"], measured["floor"], "s--", label="floor: truth + measured noise")
    shown = np.asarray(predicted["windows"]) <= max(measured["windows"])
    for key, style, name in (
        ("noise_rms", ":", "predicted, centred fits: noise"),
        ("bias_rms", "-.", "predicted, centred fits: bias"),
        ("total_rms", "-", "predicted, centred fits: total"),
    ):
        values = np.array([np.nan if v is None else v for v in predicted[key]], dtype=float)
        if np.isfinite(values[shown]).any():
            windows = np.asarray(predicted["windows"])[shown]
            ax.plot(windows, values[shown], style, color="grey", alpha=0.8, label=name)
    ax.axvline(fit["window"], color="k", lw=0.8)
    ax.annotate(
        f"window {fit['window']}: {fit['acceleration_rms_error']:.3g} m/s² "
        f"({fit['floor_ratio']:.3f} × floor)",
        (fit["window"], fit["acceleration_rms_error"]),
        xytext=(8, 12),
        textcoords="offset points",
        fontsize=8,
    )
    ax.set_yscale("log")
    ax.set_xlabel("fit window W, points (cubic)")
    ax.set_ylabel("rms error of |a|, m/s²")
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=8)
    return fig


def _values(entries: list[dict], key: str) -> np.ndarray:
    return np.array([np.nan if e[key] is None else e[key] for e in entries], dtype=float)


def lagrangian_figure(lagrangian: dict, title: str) -> Figure:
    """S2ᴸ(τ) raw, noise-removed (with its standard error), noise-free and exact, the
    velocity autocorrelation, and the acceleration PDF, from ``lagrangian`` of
    :func:`validation.run.lagrangian_scores.lagrangian_scores`."""
    fig, (s2_ax, rho_ax, pdf_ax) = plt.subplots(1, 3, figsize=(15, 4.5))
    s2 = lagrangian["s2"]
    tau = _values(s2, "tau_over_tau_eta")
    s2_ax.plot(tau, _values(s2, "raw"), "x:", label="raw D(τ; 1 frame)")
    s2_ax.errorbar(tau, _values(s2, "measured"), _values(s2, "se"), fmt="o", label="noise removed")
    s2_ax.plot(tau, _values(s2, "noise_free"), "s", mfc="none", label="estimator, no noise")
    s2_ax.plot(tau, _values(s2, "exact"), "k-", label="exact")
    s2_ax.axvspan(tau.min() * 0.8, lagrangian["checked_from_tau_eta"], color="0.9", zorder=0)
    s2_ax.set_xscale("log")
    s2_ax.set_yscale("log")
    s2_ax.set_xlabel("τ / τ_η (shaded: reported, not checked)")
    s2_ax.set_ylabel("S2ᴸ(τ), m²/s²")
    s2_ax.legend(fontsize=8)
    a = lagrangian["acceleration_variance"]
    s2_ax.set_title(
        f"<|a|²>: {a['ratio_to_exact']:.3f} × exact, {a['ratio']:.3f} × the estimator "
        f"without noise (raw {a['raw'] / a['exact']:.3g} ×)",
        fontsize=8,
    )
    rho = lagrangian["autocorrelation"]
    rho_tau = np.asarray(rho["tau_s"]) / lagrangian["tau_eta_s"]
    measured = np.array([np.nan if v is None else v for v in rho["measured"]])
    error = np.array([np.nan if v is None else v for v in rho["se"]])
    rho_ax.errorbar(rho_tau, measured, error, fmt="o", label="noise removed")
    rho_ax.plot(rho_tau, rho["exact"], "k-", label="exact")
    rho_ax.set_xlabel("τ / τ_η")
    rho_ax.set_ylabel("velocity autocorrelation ρ(τ)")
    rho_ax.legend(fontsize=8)
    rho_ax.set_title(title, fontsize=9)
    pdf = lagrangian["acceleration_pdf"]
    centres = 0.5 * (np.asarray(pdf["edges"][1:]) + np.asarray(pdf["edges"][:-1]))
    pdf_ax.semilogy(centres, pdf["measured"], "o", ms=3, label="fitted, over its rms")
    pdf_ax.semilogy(centres, pdf["true"], "k-", label="true, same points, over its rms")
    pdf_ax.set_xlabel("a_c / rms")
    pdf_ax.set_ylabel("PDF")
    pdf_ax.legend(fontsize=8)
    return fig
