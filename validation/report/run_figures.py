"""Figures of the ``synptv run`` report beyond the paper's: peak locking, the error budget
and the noise term c2 against the measured noise."""

from collections.abc import Mapping

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from ptv.detect.peaklocking import PeakLocking
from validation.report.ptv_figures import mark_off_axis, plain_log_axis
from validation.score.noise_prediction import NoisePrediction


def peak_locking_figure(locking: Mapping[str, PeakLocking], *, label: str = "") -> Figure:
    """Histograms of the fractional detected positions per camera and axis (flat: no bias).

    The legend gives the fitted bias amplitude a (what the report's check judges) and
    the χ² probability of a flat histogram; the footnote says why the two can disagree.
    ``label`` (e.g. the run and rung) follows the title.
    """
    figure, axes = plt.subplots(
        1, len(locking), figsize=(4.2 * len(locking), 3.6), squeeze=False, layout="constrained"
    )
    for ax, (name, pl) in zip(axes[0], locking.items(), strict=True):
        flat = pl.n / (len(pl.edges) - 1)
        band = 1 / np.sqrt(flat)
        ax.fill_between(
            [pl.edges[0], pl.edges[-1]],
            1 - 2 * band,
            1 + 2 * band,
            color="0.8",
            alpha=0.6,
            lw=0,
            zorder=0,
            label="±2σ counting noise",
        )
        for row, (axis, colour) in enumerate((("x", "C0"), ("y", "C1"))):
            ax.stairs(
                pl.counts[row] / flat,
                pl.edges,
                color=colour,
                lw=1.6,
                zorder=2,
                label=f"{axis}: a = {pl.amplitude[row]:+.4f} px, flat p = {pl.p_chi2[row]:.2g}",
            )
        ax.set_xlim(pl.edges[0], pl.edges[-1])
        ax.set_ylim(0.8, 1.2)
        ax.set_xlabel("fractional position (px; 0 = pixel centre)")
        ax.set_title(f"{name}: {pl.n} detections", fontsize=10)
        ax.legend(fontsize=7, loc="lower center")
    axes[0, 0].set_ylabel("count / flat count")
    figure.suptitle(
        "Peak-locking diagnostic of the detected centres" + (f"\n{label}" if label else ""),
        fontsize=10,
    )
    n = min(pl.n for pl in locking.values())
    figure.text(
        0.5,
        -0.02,
        f"p: χ² probability that the histogram is flat within counting noise. With {n:.2g} "
        "or more detections a bias far below a tenth of the error budget is already "
        "resolved (small p); the check judges the amplitude a.",
        ha="center",
        va="top",
        fontsize=7.5,
        wrap=True,
    )
    return figure


#: The c1 / truth axis of the error budget, the same for every run so that runs compare;
#: points beyond it are marked on its edge.
BUDGET_AXIS = (0.8, 1.2)


def budget_figure(
    r: np.ndarray,
    ratios: Mapping[str, np.ndarray],
    check_range: tuple[float, float],
    *,
    label: str = "",
) -> Figure:
    """c1 / sample-truth S2 against r for each rung of the error budget.

    Parameters
    ----------
    r : ndarray, shape (B,)
        Separations, m.
    ratios : mapping of str to ndarray, shape (B,)
        c1/S2 per variant (NaN where not fitted).
    check_range : (float, float)
        r range of the c1 check, m (shaded).
    label : str
        Which run (second title line).
    """
    low, high = BUDGET_AXIS
    figure, ax = plt.subplots(figsize=(7.0, 4.4), layout="constrained")
    ax.axvspan(*(v * 1e3 for v in check_range), color="0.93", label="check range")
    ax.axhspan(0.95, 1.05, color="C2", alpha=0.12, label="±5 %")
    ax.axhline(1.0, color="k", lw=0.8)
    clipped = False
    for i, (name, ratio) in enumerate(ratios.items()):
        ok = np.isfinite(ratio) & np.isfinite(r)
        ax.plot(r[ok] * 1e3, ratio[ok], "o-", ms=3.5, lw=1.0, color=f"C{i}", label=name)
        clipped |= mark_off_axis(ax, r * 1e3, ratio, BUDGET_AXIS, f"C{i}")
    if clipped:
        ax.plot([], [], "^", color="0.4", ms=7, label=f"off the axis ({low:g}–{high:g})")
    ax.set_xscale("log")
    plain_log_axis(ax.xaxis, ax.get_xlim())
    ax.set_ylim(low, high)
    ax.set_xlabel("r (mm)")
    ax.set_ylabel("c1 / sample-truth S2 of its pairs")
    ax.set_title(
        "Error budget: noise-free S2 of each measurement against the truth"
        + (f"\n{label}" if label else ""),
        fontsize=10,
    )
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, ncol=2)
    return figure


#: The noise figure's axis ends at this many times the prediction's largest value.
OFF_SCALE = 2.5


def noise_figure(
    r: np.ndarray,
    c2: Mapping[str, tuple[np.ndarray, np.ndarray]],
    prediction: NoisePrediction,
    check_range: tuple[float, float],
    *,
    noise_free: np.ndarray | None = None,
    label: str = "",
    predicted_for: str = "",
) -> Figure:
    """The fitted noise term c2(r) of each measurement against the measured noise.

    Parameters
    ----------
    r : ndarray, shape (B,)
        Separations, m.
    c2 : mapping of str to (ndarray (B,), ndarray (B,))
        c2 and its standard error per variant, m² (NaN where not fitted).
    prediction : NoisePrediction
        c2 predicted from the displacement noise measured against the truth.
    check_range : (float, float)
        r range of the checks, m (shaded).
    noise_free : ndarray, shape (B,), optional
        c2 of the same fit on the exact positions, m² (the flow's terms beyond Δt²):
        drawn, and added to the prediction.
    label : str
        Which run (second title line).
    predicted_for : str
        The measurement whose noise ``prediction`` is (named in the legend).
    """
    figure, ax = plt.subplots(figsize=(7.0, 4.4), layout="constrained")
    um2 = 1e12
    ax.axvspan(*(v * 1e3 for v in check_range), color="0.93", label="check range")
    ok = np.isfinite(r)
    offset = np.zeros_like(r) if noise_free is None else np.nan_to_num(noise_free)
    ax.fill_between(
        r[ok] * 1e3,
        (prediction.c2_low[ok] + offset[ok]) * um2,
        (prediction.c2[ok] + offset[ok]) * um2,
        color="k",
        alpha=0.15,
        label="from the measured noise"
        + (f" ({predicted_for}'s particles)" if predicted_for else "")
        + (" + exact positions' c2" if noise_free is not None else ""),
    )
    if noise_free is not None:
        fit = ok & np.isfinite(noise_free)
        ax.plot(
            r[fit] * 1e3, noise_free[fit] * um2, "k--", lw=1, label="exact positions (no noise)"
        )
    # The axis shows the prediction; a measurement far above it (a poor calibration's
    # ghosts and mislinks) is named in the legend with its median instead of flattening
    # the rest.
    band = (prediction.c2 + offset)[ok]
    top = OFF_SCALE * float(np.nanmax(band)) if np.isfinite(band).any() else None
    for i, (name, (value, se)) in enumerate(c2.items()):
        fit = ok & np.isfinite(value)
        median = float(np.median(value[fit])) if fit.any() else np.nan
        off = top is not None and median > top
        ax.errorbar(
            r[fit] * 1e3 * (1 + 0.015 * i),
            value[fit] * um2,
            yerr=se[fit] * um2,
            fmt="o",
            ms=3.5,
            capsize=2,
            color=f"C{i}",
            label=f"{name} (off scale: median {median * um2:.3g} µm²)" if off else name,
        )
    ax.set_xscale("log")
    plain_log_axis(ax.xaxis, ax.get_xlim())
    ax.set_ylim(bottom=0, top=None if top is None else top * um2)
    ax.set_xlabel("r (mm)")
    ax.set_ylabel("c2 (µm²)")
    ax.set_title(
        "Noise term c2 of the multi-Δt fit against the measured noise"
        + (f"\n{label}" if label else ""),
        fontsize=10,
    )
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, ncol=2)
    return figure
