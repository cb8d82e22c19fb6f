"""Figures of a PTV run (``synptv ptv``): the paper's Fig. 5a, 5b, 6a and 6b.

Each function takes the :class:`ptv.pipeline.double_frame.PtvResult` and returns a matplotlib
Figure; :func:`save_ptv_figures` writes the four PNGs with
:func:`validation.report.png.save_figure`. Separations are shown in mm (η is not known on
real data), displacements in µm, Δt in ms; S2 in m²/s² and ε in m²/s³.

Every figure's suptitle says whose measurement it is (``label``: in ``synptv run`` the
scenario, its seed and the rung; by default the folder of the data measured), so that
the figures of different rungs or runs cannot be taken for one another outside their
folders.
"""

import os
from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.container import ErrorbarContainer
from matplotlib.figure import Figure
from matplotlib.ticker import FixedLocator, FuncFormatter, NullFormatter

from ptv.pipeline.double_frame import PtvResult
from validation.report.png import save_figure
from validation.report.value_error import value_error

__all__ = [
    "FIGURE_FILES",
    "epsilon_figure",
    "measurement_label",
    "q_versus_dt2_figure",
    "raw_structure_figure",
    "save_ptv_figures",
    "structure_figure",
]

#: File names written by :func:`save_ptv_figures`.
FIGURE_FILES = {
    "fig5a": "fig5a_raw_s2.png",
    "fig5b": "fig5b_q_vs_dt2.png",
    "fig6a": "fig6a_s2.png",
    "fig6b": "fig6b_epsilon.png",
}

Reference = tuple[np.ndarray, np.ndarray, str]


def measurement_label(result: PtvResult) -> str:
    """What a figure of ``result`` names when it is given no label: the folder of the
    data measured (a dataset, or a run's detection store)."""
    folder = getattr(result.source, "folder", None)
    return "measurement" if folder is None else f"measurement of {Path(folder).name}"


def _titled(figure: Figure, result: PtvResult, label: str | None) -> None:
    """The figure's suptitle: whose measurement it is."""
    figure.suptitle(measurement_label(result) if label is None else label, fontsize=10)


def _colours(n: int) -> list:
    return [plt.get_cmap("viridis")(v) for v in np.linspace(0.0, 0.85, n)]


def _plain(value: float, _position=None) -> str:
    return f"{value:g}"


def plain_log_axis(axis, limits) -> None:
    """Label a log axis with plain numbers: 1-2-3-4-5-6-8 steps within about a decade,
    1-2-5 up to three decades, decades beyond."""
    lo, hi = sorted(float(v) for v in limits)
    if not (np.isfinite(lo) and np.isfinite(hi) and 0 < lo < hi):
        return
    decades = np.log10(hi / lo)
    steps = (1, 2, 3, 4, 5, 6, 8) if decades <= 1.2 else (1, 2, 5) if decades <= 3 else (1,)
    exps = np.arange(np.floor(np.log10(lo)), np.ceil(np.log10(hi)) + 1)
    ticks = np.array([m * 10.0**e for e in exps for m in steps])
    ticks = ticks[(ticks >= lo) & (ticks <= hi)]
    if ticks.size < 2:
        return
    axis.set_major_locator(FixedLocator(ticks))
    axis.set_major_formatter(FuncFormatter(_plain))
    axis.set_minor_formatter(NullFormatter())


#: Axis limits of a log-log panel, ((x0, x1), (y0, y1)), the same for every measurement of
#: a run so that they compare; None: fitted to the data.
Limits = tuple[tuple[float, float], tuple[float, float]] | None


def _loglog(ax, limits: Limits = None) -> None:
    """Log axes, with ``limits`` if given; where nothing positive was plotted (a run too
    thin to measure), a note in the panel instead of matplotlib's error."""
    if limits is not None:
        ax.set_xlim(*limits[0])
        ax.set_ylim(*limits[1])
    lim = ax.dataLim
    if not (np.isfinite([lim.x1, lim.y1]).all() and lim.x1 > 0 and lim.y1 > 0):
        ax.text(
            0.5,
            0.5,
            "nothing to plot: no positive values\n(too few matched particles?)",
            transform=ax.transAxes,
            ha="center",
            va="center",
        )
        return
    ax.set_xscale("log")
    ax.set_yscale("log")
    plain_log_axis(ax.xaxis, ax.get_xlim())
    plain_log_axis(ax.yaxis, ax.get_ylim())


def mark_off_axis(
    ax,
    x: np.ndarray,
    y: np.ndarray,
    y_limits: tuple[float, float],
    colour: str,
    x_limits: tuple[float, float] | None = None,
) -> bool:
    """Arrowheads on the edge of a fixed y axis for the points (x, y) beyond it (within
    ``x_limits`` when given); whether there were any."""
    low, high = y_limits
    shown = np.isfinite(x) & np.isfinite(y)
    if x_limits is not None:
        shown &= (x >= x_limits[0]) & (x <= x_limits[1])
    marked = False
    for beyond, edge, marker in ((y > high, high, "^"), (y < low, low, "v")):
        beyond &= shown
        if beyond.any():
            ax.plot(
                x[beyond],
                np.full(beyond.sum(), edge),
                marker,
                ms=7,
                color=colour,
                clip_on=False,
                zorder=5,
            )
            marked = True
    return marked


def _fitted(result: PtvResult) -> np.ndarray:
    sf = result.statistics.structure
    return sf.fitted & np.isfinite(sf.s2) & (sf.s2 > 0)


def _r_mm(result: PtvResult) -> np.ndarray:
    st = result.statistics
    r = st.structure.r
    return np.where(np.isfinite(r), r, st.bins.centres) * 1e3


def raw_structure_figure(
    result: PtvResult, *, limits: Limits = None, label: str | None = None
) -> Figure:
    """Fig. 5a: raw ⟨(δΔX·e)²⟩/Δt² for every Δt against r, with the multi-Δt S2.

    Small separations show the noise: the raw estimate at the smallest Δt lies highest.
    ``limits`` (mm, m²/s²) fixes the axes, points beyond them marked on the edge;
    ``label`` is the suptitle (default: :func:`measurement_label`).
    """
    st = result.statistics
    sf = st.structure
    r = _r_mm(result)
    figure, ax = plt.subplots(figsize=(6.0, 4.6), layout="constrained")
    for k, (dt, colour) in enumerate(zip(st.dt, _colours(st.dt.size), strict=True)):
        y = sf.raw_s2[:, k]
        ok = np.isfinite(y) & (y > 0) & (sf.n_pairs[:, k] >= 20)
        ax.plot(
            r[ok], y[ok], "o-", ms=3.5, lw=1.0, color=colour, label=f"raw, Δt = {dt * 1e3:.3f} ms"
        )
        if limits is not None:
            mark_off_axis(ax, r[ok], y[ok], limits[1], colour, x_limits=limits[0])
    fit = _fitted(result)
    ax.errorbar(
        r[fit],
        sf.s2[fit],
        yerr=sf.se_s2[fit],
        fmt="s-",
        ms=4,
        lw=1.6,
        color="black",
        capsize=2,
        label="multi-Δt fit S2 = c1",
    )
    if limits is not None:
        mark_off_axis(ax, r[fit], sf.s2[fit], limits[1], "black", x_limits=limits[0])
    _loglog(ax, limits)
    ax.set_xlabel("r (mm)")
    ax.set_ylabel("⟨(δΔX·e)²⟩ / Δt²  (m²/s²)")
    ax.set_title("Raw S2 of the displacements per Δt (Fig. 5a)", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    _titled(figure, result, label)
    return figure


def _pick_bins(result: PtvResult, n: int, candidates: np.ndarray | None) -> np.ndarray:
    """About ``n`` bins spread evenly in log r over ``candidates`` (all bins by default),
    keeping those the rung fitted."""
    r = _r_mm(result)
    pool = np.flatnonzero(np.ones(r.size, bool) if candidates is None else candidates)
    if pool.size > n:
        targets = np.geomspace(r[pool].min(), r[pool].max(), n)
        pool = np.unique([pool[int(np.argmin(np.abs(np.log(r[pool] / t))))] for t in targets])
    return pool[_fitted(result)[pool]]


def q_versus_dt2_figure(
    result: PtvResult,
    *,
    n_separations: int = 6,
    separations: np.ndarray | None = None,
    q_limit: float | None = None,
    label: str | None = None,
) -> Figure:
    """Fig. 5b: ⟨q⟩ against Δt² at a few separations, with the fitted lines c1Δt² + c2.

    Left, the paper's view: ⟨q⟩ and the lines (slope: the noise-free S2), the legend
    giving each intercept c2 ± its standard error. Right, a zoom on Δt → 0, where the
    intercepts c2 (the noise term, ◆ with ±1 s.e.) can be seen even when the noise is
    small: its y axis follows this rung's own intercepts (they fill its lower half),
    the points of the smallest Δt above it marked ▲ on its edge.

    ``separations`` (bool per bin) are the bins to choose the separations from, so that
    every rung of a run shows the same ones; ``q_limit`` (µm²) fixes the top of the left
    panel, points above it marked on the edge; ``label`` is the suptitle (default:
    :func:`measurement_label`).
    """
    st = result.statistics
    sf = st.structure
    r = _r_mm(result)
    dt2 = st.dt**2
    x_ms2 = dt2 * 1e6
    line = np.linspace(0.0, x_ms2.max() * 1.05, 50)
    figure, (ax, ax_res) = plt.subplots(
        1, 2, figsize=(11.0, 4.6), layout="constrained", gridspec_kw={"width_ratios": [1.2, 1.0]}
    )
    bins = _pick_bins(result, n_separations, separations)
    for b, colour in zip(bins, _colours(len(bins)), strict=True):
        q = sf.raw_s2[b] * dt2 * 1e12  # µm²
        se = sf.se_raw_s2[b] * dt2 * 1e12
        c2, se_c2 = sf.noise[b] * 1e12, sf.se_noise[b] * 1e12
        ax.errorbar(x_ms2, q, yerr=se, fmt="o", ms=4, color=colour, capsize=2)
        ax.plot(
            line,
            sf.s2[b] * line * 1e6 + c2,
            "-",
            color=colour,
            lw=1.2,
            label=f"r = {r[b]:.2f} mm: c2 = {value_error(c2, se_c2, 'µm²')}",
        )
        ax_res.errorbar(x_ms2, q, yerr=se, fmt="o", ms=4, color=colour, capsize=2)
        ax_res.plot(line, sf.s2[b] * line * 1e6 + c2, "-", color=colour, lw=1.2)
        # The intercept on top of the lines and the axis, outlined so that it shows
        # where the lines meet.
        ax_res.errorbar(
            0.0,
            c2,
            yerr=se_c2 if np.isfinite(se_c2) else None,
            fmt="D",
            ms=7,
            color=colour,
            mec="black",
            mew=0.8,
            capsize=3,
            clip_on=False,
            zorder=10,
        )
        if q_limit is not None:
            mark_off_axis(ax, x_ms2, q, (-np.inf, q_limit), colour)
    for a in (ax, ax_res):
        a.axhline(0.0, color="0.5", lw=0.8)
        a.set_xlabel("Δt² (ms²)")
        a.grid(True, alpha=0.3)
    ax.set_xlim(0.0, line[-1])
    if q_limit is not None:
        ax.set_ylim(top=q_limit)
    ax.set_ylabel("⟨(δΔX·e)²⟩  (µm²)")
    ax.set_title(f"⟨q⟩ = c1 Δt² + c2 at {len(bins)} separations (Fig. 5b)", fontsize=10)
    if len(bins):  # no bin, no labelled artist: a legend would only warn
        ax.legend(
            fontsize=7.5, loc="upper left", title="intercept c2 ± 1 s.e.", title_fontsize=7.5
        )
    # Zoom on the intercepts: they fill the lower half of the y axis, whatever the size
    # of the noise; the points of the smallest Δt above it are marked on its edge.
    x_zoom = 1.25 * np.min(x_ms2)
    if len(bins):
        c2_all = sf.noise[bins] * 1e12
        se_all = np.nan_to_num(sf.se_noise[bins] * 1e12)
        bottom = min(0.0, np.nanmin(c2_all - 1.5 * se_all))
        high = np.nanmax(c2_all + 1.5 * se_all)
        top = high + max(high - bottom, 1e-3)
        if np.isfinite(top) and np.isfinite(bottom):
            ax_res.set_ylim(bottom, top)
            for b, colour in zip(bins, _colours(len(bins)), strict=True):
                q = sf.raw_s2[b] * dt2 * 1e12
                mark_off_axis(ax_res, x_ms2, q, (bottom, top), colour, x_limits=(0, x_zoom))
    ax_res.set_xlim(0.0, x_zoom)
    ax_res.set_ylabel("⟨(δΔX·e)²⟩  (µm²)")
    ax_res.set_title(
        "zoom on Δt → 0: the intercepts c2 (noise term, ◆ ± 1 s.e.); ▲ points above",
        fontsize=9.5,
    )
    _titled(figure, result, label)
    return figure


def structure_figure(
    result: PtvResult,
    *,
    reference: Reference | None = None,
    limits: Limits = None,
    label: str | None = None,
) -> Figure:
    """Fig. 6a: the noise-free S2(r) with bootstrap errors and a r^{2/3} guide.

    ``reference`` = (r in m, S2 in m²/s², label) adds a curve (e.g. a ground truth);
    ``limits`` (mm, m²/s²) fixes the axes, points beyond them marked on the edge;
    ``label`` is the suptitle (default: :func:`measurement_label`).
    """
    sf = result.statistics.structure
    r = _r_mm(result)
    fit = _fitted(result)
    figure, ax = plt.subplots(figsize=(6.0, 4.6), layout="constrained")
    ax.errorbar(
        r[fit],
        sf.s2[fit],
        yerr=sf.se_s2[fit],
        fmt="o",
        ms=4,
        color="C0",
        capsize=2,
        label="S2 = c1 (multi-Δt fit), ±1 s.e.",
    )
    if reference is not None:
        rr, s2, name = reference
        ok = np.isfinite(s2) & (s2 > 0)
        ax.plot(np.asarray(rr)[ok] * 1e3, np.asarray(s2)[ok], "-", color="C3", lw=1.2, label=name)
    if fit.any():
        # Guide through the geometric middle of the fitted points.
        r0 = np.exp(np.mean(np.log(r[fit])))
        s0 = np.exp(np.mean(np.log(sf.s2[fit])))
        guide = np.geomspace(r[fit].min(), r[fit].max(), 20)
        ax.plot(guide, 0.7 * s0 * (guide / r0) ** (2 / 3), "k--", lw=1.0, label="slope 2/3 (guide)")
    if limits is not None:
        mark_off_axis(ax, r[fit], sf.s2[fit], limits[1], "C0", x_limits=limits[0])
    _loglog(ax, limits)
    ax.set_xlabel("r (mm)")
    ax.set_ylabel("S2 (m²/s²)")
    ax.set_title("Noise-free longitudinal structure function (Fig. 6a)", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    _titled(figure, result, label)
    return figure


def epsilon_figure(
    result: PtvResult,
    *,
    reference: Reference | None = None,
    levels: Sequence[tuple[float, str]] = (),
    limits: Limits = None,
    label: str | None = None,
) -> Figure:
    """Fig. 6b: ε(r) = (S2/C2)^{3/2}/r and the paper's S2^{3/2}/r, with the plateau.

    The plateau range is shaded grey; the plateau ε is a line across it, its ±1 s.e.
    band shaded in its colour (often thinner than the line: the legend gives the
    value and its error). ``reference`` = (r in m, S2 in m²/s², label) adds the ε(r)
    of that S2 through the same C2 (e.g. of the exact D_LL); each of ``levels`` = (ε in
    m²/s³, label) a horizontal line (e.g. the input ε); ``limits`` (mm, m²/s³) fixes the
    axes, points beyond them marked; ``label`` is the suptitle (default:
    :func:`measurement_label`). The legend lies below the axes, in a panel of its own,
    so that the axes are as large as those of Figs. 5a and 6a.
    """
    st = result.statistics
    prof = st.profile
    r = _r_mm(result)
    ok = np.isfinite(prof.epsilon)
    c2 = prof.kolmogorov_c2
    figure, (ax, ax_legend) = plt.subplots(
        2,
        1,
        figsize=(6.0, 6.0),
        layout="constrained",
        gridspec_kw={"height_ratios": [3.7, 1.35]},
    )
    ax.errorbar(
        r[ok],
        prof.epsilon[ok],
        yerr=prof.se_epsilon[ok],
        fmt="o-",
        ms=4,
        lw=1.0,
        color="C0",
        capsize=2,
        label=f"(S2/C2)^(3/2)/r, C2 = {c2:g}, ±1 s.e.",
    )
    ax.plot(
        r[ok],
        prof.epsilon_paper_caption[ok],
        "s--",
        ms=3.5,
        lw=1.0,
        color="C1",
        label=f"S2^(3/2)/r (paper's caption, no C2: ×{c2**1.5:.2f})",
    )
    lo, hi = (v * 1e3 for v in result.settings.statistics.plateau)
    ax.axvspan(lo, hi, color="0.93", zorder=0, label=f"plateau range {lo:.3g}–{hi:.3g} mm")
    p = st.plateau
    if p is not None and np.isfinite(p.epsilon):
        if np.isfinite(p.se_epsilon):
            ax.fill_between(
                [lo, hi],
                p.epsilon - p.se_epsilon,
                p.epsilon + p.se_epsilon,
                color="C0",
                alpha=0.25,
                lw=0,
            )
        ax.plot(
            [lo, hi],
            [p.epsilon, p.epsilon],
            color="C0",
            lw=2.0,
            alpha=0.6,
            label=f"plateau ε ({p.method} over the range) = "
            f"{value_error(p.epsilon, p.se_epsilon, 'm²/s³')}",
        )
    if reference is not None:
        rr, s2, name = np.asarray(reference[0]), np.asarray(reference[1]), reference[2]
        shown = np.isfinite(s2) & (s2 > 0) & np.isfinite(rr) & (rr > 0)
        ax.plot(
            rr[shown] * 1e3,
            (s2[shown] / c2) ** 1.5 / rr[shown],
            "-",
            color="C3",
            lw=1.2,
            label=name,
        )
    for (value, name), style in zip(levels, (":", "-."), strict=False):
        ax.axhline(value, color="0.3", lw=1.1, ls=style, label=f"{name}: {value:.3g} m²/s³")
    if limits is not None:
        mark_off_axis(ax, r[ok], prof.epsilon[ok], limits[1], "C0", x_limits=limits[0])
    _loglog(ax, limits)
    ax.set_xlabel("r (mm)")
    ax.set_ylabel("ε(r) (m²/s³)")
    ax.set_title("Dissipation rate from the noise-free S2 (Fig. 6b)", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax_legend.axis("off")
    # The measurement first (matplotlib lists error bars last).
    entries = sorted(
        zip(*ax.get_legend_handles_labels(), strict=True),
        key=lambda entry: not isinstance(entry[0], ErrorbarContainer),
    )
    ax_legend.legend(*zip(*entries, strict=True), fontsize=8, loc="upper center", frameon=False)
    _titled(figure, result, label)
    return figure


def save_ptv_figures(
    result: PtvResult,
    folder: str | os.PathLike,
    *,
    reference_s2: Reference | None = None,
    epsilon_reference: Reference | None = None,
    epsilon_levels: Sequence[tuple[float, str]] = (),
    s2_limits: Limits = None,
    epsilon_limits: Limits = None,
    separations: np.ndarray | None = None,
    q_limit: float | None = None,
    label: str | None = None,
) -> dict[str, Path]:
    """Write the four PNGs of :data:`FIGURE_FILES` into ``folder``; returns their paths.

    ``s2_limits`` go to Figs. 5a and 6a, ``separations`` and ``q_limit`` to Fig. 5b,
    ``reference_s2`` to Fig. 6a, ``epsilon_reference``, ``epsilon_levels`` and
    ``epsilon_limits`` to Fig. 6b (see :func:`raw_structure_figure`,
    :func:`q_versus_dt2_figure`, :func:`structure_figure` and :func:`epsilon_figure`);
    ``label``, the suptitle of every figure, says whose measurement it is (default:
    :func:`measurement_label`, the folder of the data measured).
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    figures = {
        "fig5a": raw_structure_figure(result, limits=s2_limits, label=label),
        "fig5b": q_versus_dt2_figure(result, separations=separations, q_limit=q_limit, label=label),
        "fig6a": structure_figure(result, reference=reference_s2, limits=s2_limits, label=label),
        "fig6b": epsilon_figure(
            result,
            reference=epsilon_reference,
            levels=epsilon_levels,
            limits=epsilon_limits,
            label=label,
        ),
    }
    return {key: save_figure(fig, folder / FIGURE_FILES[key]) for key, fig in figures.items()}
