"""Summary figures of the multi-Δt studies (dt, noise, seeding).

One figure per study, panels against the swept parameter: c₁ against the sample truth
over r (one curve per point, ±1 standard error shaded), the accuracy of c₁ at a few
r/η, the plateau ε against the same estimator on the exact D_LL, c₂ against 4σ², and
(noise study) the raw single-Δt S2 over the truth. Errors are shown in %, separations
in units of η, noise in µm. Returns matplotlib Figures (Agg backend); write them with
:func:`validation.report.calibration_figures.save_figure`.
"""

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.ticker import NullFormatter

from validation.studies.multi_dt import R_OVER_ETA


@dataclass(frozen=True)
class _Axis:
    """How a study's swept parameter is shown."""

    key: str
    label: str
    legend: str
    log: bool = False


_AXES = {
    "dt": _Axis("dt_count", "Δt values used, k (spread over the set; fixed frame pairs)", "k = {}"),
    "noise": _Axis("noise_um", "position noise σ per component (µm)", "σ = {:g} µm"),
    "seeding": _Axis(
        "particles", "particles per snapshot P in the analysis volume", "P = {}", log=True
    ),
}


def _column(rows: Sequence[Mapping], key: str) -> np.ndarray:
    return np.array([row[key] for row in rows], dtype=float)  # None (not finite) → NaN


def _c1_over_r(
    ax: Axes, rows: Sequence[Mapping], curves: Sequence[Mapping], axis: _Axis, eta: float
) -> None:
    """c₁ / sample truth − 1 against r/η, ±1 standard error shaded."""
    spread = [5.0]
    for row, curve in zip(rows, curves, strict=True):
        r, c1, se, truth = (
            np.array(curve[k], dtype=float) for k in ("r_m", "c1", "se_c1", "sample_truth")
        )
        ok = np.isfinite(c1) & (truth > 0)
        x, err, band = r[ok] / eta, 100 * (c1[ok] / truth[ok] - 1), 100 * se[ok] / truth[ok]
        (line,) = ax.plot(x, err, marker=".", label=axis.legend.format(row[axis.key]))
        ax.fill_between(x, err - band, err + band, color=line.get_color(), alpha=0.15, lw=0)
        spread += list(np.abs(err[x >= 30]) + band[x >= 30])
    limit = min(60.0, 1.3 * max(spread))
    ax.set_ylim(-limit, limit)
    ax.set_xscale("log")
    ax.axhline(0.0, color="0.5", lw=0.8)
    ax.set_xlabel("separation r/η")
    ax.set_ylabel("c₁ / sample-truth S2 − 1 (%)")
    ax.set_title("c₁ against the truth of the same pairs (±1 s.e.)", fontsize=9)
    ax.legend(fontsize=7)


def _c1_accuracy(ax: Axes, rows: Sequence[Mapping], axis: _Axis) -> None:
    """Standard error and |error| of c₁ relative to the truth at each r/η."""
    x = _column(rows, axis.key)
    for n in R_OVER_ETA:
        se = 100 * _column(rows, f"c1_se_{n}eta")
        err = 100 * np.abs(_column(rows, f"c1_error_{n}eta"))
        (line,) = ax.plot(x, se, marker="o", label=f"s.e., r ≈ {n}η")
        ax.plot(
            x, err, marker="o", ls="--", mfc="none", color=line.get_color(), label=f"|error|, {n}η"
        )
    if axis.key == "particles":
        se = 100 * _column(rows, f"c1_se_{R_OVER_ETA[1]}eta")
        ax.plot(x, se[0] * x[0] / x, color="0.4", lw=0.8, ls=":", label="∝ 1/P")
    ax.set_yscale("log")
    ax.set_ylabel("c₁ relative to sample truth (%)")
    ax.set_title("c₁ standard error (solid) and |error| (dashed)", fontsize=9)
    ax.legend(fontsize=7, ncol=2)


def _epsilon(ax: Axes, rows: Sequence[Mapping], axis: _Axis) -> None:
    """Plateau ε of the fit relative to the estimator on the exact D_LL."""
    ax.plot(_column(rows, axis.key), 100 * _column(rows, "epsilon_error"), marker="o")
    ax.axhline(0.0, color="0.5", lw=0.8)
    ax.set_ylabel("ε plateau: fit / exact D_LL − 1 (%)")
    ax.set_title("plateau ε = max over r of (c₁/C₂)^1.5 / r vs the exact D_LL's", fontsize=9)


def _noise_term(ax: Axes, rows: Sequence[Mapping], axis: _Axis) -> None:
    """Median fitted c₂ over 4σ² (1 for white noise)."""
    ax.plot(
        _column(rows, axis.key),
        _column(rows, "c2_over_4sigma2"),
        marker="o",
        label="median c₂ / 4σ²",
    )
    ax.axhline(1.0, color="0.5", lw=0.8, label="white noise: 4σ²")
    ax.set_ylabel("c₂ / 4σ²")
    ax.set_title("noise term c₂ against 4σ² (median over bins)", fontsize=9)
    ax.legend(fontsize=7)


def _raw_bias(ax: Axes, rows: Sequence[Mapping], axis: _Axis) -> None:
    """Raw S2 at the smallest Δt over the sample truth at each r/η."""
    x = _column(rows, axis.key)
    for n in R_OVER_ETA:
        ax.plot(x, _column(rows, f"raw_over_truth_{n}eta"), marker="o", label=f"r ≈ {n}η")
    ax.axhline(1.0, color="0.5", lw=0.8)
    ax.set_yscale("log")
    ax.set_ylabel("raw S2(Δt_min) / sample truth")
    ax.set_title("single-Δt S2 at the smallest Δt (no noise removal)", fontsize=9)
    ax.legend(fontsize=7)


def multi_dt_figure(
    study: str, rows: Sequence[Mapping], curves: Sequence[Mapping], *, eta: float
) -> Figure:
    """The summary figure of a ``dt``, ``noise`` or ``seeding`` study.

    Parameters
    ----------
    study : {"dt", "noise", "seeding"}
        Which study (sets the swept parameter).
    rows : sequence of dict
        The table rows, one per point (:func:`validation.studies.multi_dt.noise_task`).
    curves : sequence of dict
        The points' per-bin curves, in the order of ``rows``.
    eta : float
        Kolmogorov length, m (separations are shown as r/η).
    """
    axis = _AXES[study]
    panels = [_c1_accuracy, _epsilon, _noise_term] + ([_raw_bias] if study == "noise" else [])
    columns = 3 if len(panels) > 3 else 2
    figure, axes = plt.subplots(2, columns, figsize=(5.2 * columns, 8.0), layout="constrained")
    flat = axes.ravel()
    _c1_over_r(flat[0], rows, curves, axis, eta)
    for ax, panel in zip(flat[1:], panels, strict=False):
        panel(ax, rows, axis)
        ax.set_xlabel(axis.label)
        if axis.log:
            ax.set_xscale("log")
        values = _column(rows, axis.key)
        ax.set_xticks(values, [f"{v:g}" for v in values])
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.grid(True, which="both", alpha=0.3)
    for ax in flat[1 + len(panels) :]:
        ax.set_visible(False)
    flat[0].grid(True, which="both", alpha=0.3)
    return figure
