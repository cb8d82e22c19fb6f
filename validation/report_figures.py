"""Figures of the ``synptv run`` report beyond the paper's: peak locking and the error budget."""

from collections.abc import Mapping

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from ptv.detect.peaklocking import PeakLocking


def peak_locking_figure(locking: Mapping[str, PeakLocking]) -> Figure:
    """Histograms of the fractional detected positions per camera and axis (flat: no bias)."""
    figure, axes = plt.subplots(
        1, len(locking), figsize=(4.2 * len(locking), 3.4), squeeze=False, layout="constrained"
    )
    for ax, (name, pl) in zip(axes[0], locking.items(), strict=True):
        flat = pl.n / (len(pl.edges) - 1)
        for row, (axis, colour) in enumerate((("x", "C0"), ("y", "C1"))):
            ax.stairs(
                pl.counts[row] / flat,
                pl.edges,
                color=colour,
                label=f"{axis}: a = {pl.amplitude[row]:+.4f} px, p = {pl.p_chi2[row]:.2g}",
            )
        band = 1 / np.sqrt(flat)
        ax.fill_between(
            [pl.edges[0], pl.edges[-1]], 1 - 2 * band, 1 + 2 * band, color="0.85", label="±2σ"
        )
        ax.set_xlim(pl.edges[0], pl.edges[-1])
        ax.set_ylim(0.8, 1.2)
        ax.set_xlabel("fractional position (px; 0 = pixel centre)")
        ax.set_title(f"{name}: {pl.n} detections", fontsize=10)
        ax.legend(fontsize=7, loc="lower center")
    axes[0, 0].set_ylabel("count / flat count")
    figure.suptitle("Peak-locking diagnostic", fontsize=11)
    return figure


def budget_figure(
    r: np.ndarray, ratios: Mapping[str, np.ndarray], check_range: tuple[float, float]
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
    """
    figure, ax = plt.subplots(figsize=(7.0, 4.4), layout="constrained")
    ax.axvspan(*(v * 1e3 for v in check_range), color="0.93", label="check range")
    ax.axhspan(0.95, 1.05, color="C2", alpha=0.12, label="±5 %")
    ax.axhline(1.0, color="k", lw=0.8)
    for i, (name, ratio) in enumerate(ratios.items()):
        ok = np.isfinite(ratio) & np.isfinite(r)
        ax.plot(r[ok] * 1e3, ratio[ok], "o-", ms=3.5, lw=1.0, color=f"C{i}", label=name)
    ax.set_xscale("log")
    ax.set_ylim(0.8, 1.2)
    ax.set_xlabel("r (mm)")
    ax.set_ylabel("c1 / sample-truth S2")
    ax.set_title("Error budget: noise-free S2 of each measurement against the truth", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, ncol=2)
    return figure
