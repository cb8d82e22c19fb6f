"""The table of a study, whatever its chain: ``study.json``, ``study.csv`` and a figure.

One row per point, seed and calibration method, with the swept parameter and

    table1_d_um, model_error_um      calibration: Table 1 d against the nominal dot
                                     positions, and the model error at random points, µm
    yield, ghosts                    stereo matching against the true particles
    c1_rel_err, c1_rel_se            {"10", "40", "100"}: c₁/sample truth − 1 and its
                                     standard error at those r/η
    epsilon_rel_err, epsilon_rel_se  plateau ε over the estimator on the exact D_LL − 1

(null where a chain does not measure a quantity: the ideal chain's calibration studies
see no particles, its multi-Δt studies no images). The figure shows each quantity
against the parameter: the mean over the seeds, with error bars of the scatter between
seeds where there are several, else of the bootstrap standard error.
"""

import csv
import io
from collections.abc import Mapping, Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

#: The swept parameter of each study, its axis label, and whether it is categorical.
PARAMETERS = {
    "planes": ("planes", "calibration planes N_Z (spanning the traverse)", False),
    "dt": ("dt_subset", "Δt values used", True),
    "noise": ("read_noise_e", "read noise of the particle images (e⁻ rms)", False),
    "seeding": ("tracers", "tracers in the laser sheet", False),
    "obliquity": ("obliquity_deg", "window obliquity (°)", False),
}
R_KEYS = ("10", "40", "100")


def flat_row(row: Mapping) -> dict:
    """A row with its nested dicts spread into columns (``c1_rel_err_10eta``, …)."""
    out = {}
    for key, value in row.items():
        if isinstance(value, Mapping):
            for sub, v in value.items():
                out[f"{key}_{sub}eta"] = v
        elif isinstance(value, list | tuple):
            out[key] = " ".join(str(v) for v in value)
        else:
            out[key] = value
    return out


def csv_text(rows: Sequence[Mapping]) -> str:
    """The rows as CSV (columns in order of first appearance)."""
    flat = [flat_row(r) for r in rows]
    columns = list(dict.fromkeys(key for row in flat for key in row))
    stream = io.StringIO()
    writer = csv.DictWriter(stream, fieldnames=columns, lineterminator="\n")
    writer.writeheader()
    writer.writerows(flat)
    return stream.getvalue()


def _series(rows: Sequence[Mapping], key: str, x_key: str, value, error):
    """Per parameter value: mean of ``value(row)`` over the rows (seeds) and its error."""
    xs = list(dict.fromkeys(r[x_key] for r in rows))
    mean, err = [], []
    for x in xs:
        vals = [value(r) for r in rows if r[x_key] == x]
        errs = [error(r) for r in rows if r[x_key] == x]
        vals = np.array([np.nan if v is None else v for v in vals], dtype=float)
        errs = np.array([np.nan if e is None else e for e in errs], dtype=float)
        mean.append(np.nanmean(vals) if np.isfinite(vals).any() else np.nan)
        if np.isfinite(vals).sum() >= 2:
            err.append(np.nanstd(vals, ddof=1) / np.sqrt(np.isfinite(vals).sum()))
        else:
            err.append(np.nanmean(errs) if np.isfinite(errs).any() else np.nan)
    return xs, np.array(mean), np.array(err)


def study_figure(study: str, rows: Sequence[Mapping], *, title: str = "") -> Figure:
    """Calibration error, matching, c₁ and ε against the study's parameter.

    Parameters
    ----------
    study : str
        One of :data:`PARAMETERS`.
    rows : sequence of dict
        The table (module docstring).
    title : str
        Figure title.
    """
    x_key, label, categorical = PARAMETERS[study]
    groups = {}
    for row in rows:
        name = row.get("method", "model-free")
        if "direction_deg" in row:
            name = (
                f"{name}, {row['direction_deg']:g}° diagonal"
                if row["direction_deg"]
                else (f"{name}, camera plane")
            )
        groups.setdefault(name, []).append(row)
    figure, axes = plt.subplots(2, 2, figsize=(11.0, 8.0), layout="constrained")
    panels = (
        (
            axes[0, 0],
            "calibration error (µm)",
            (("table1_d_um", "Table 1 d"), ("model_error_um", "model error")),
            1.0,
        ),
        (axes[0, 1], "matching (%)", (("yield", "yield"), ("ghosts", "ghosts")), 100.0),
    )
    for ax, ylabel, quantities, scale in panels:
        for name, group in groups.items():
            for key, what in quantities:
                xs, mean, err = _series(
                    group, key, x_key, lambda r, k=key: r.get(k), lambda r: None
                )
                if np.isfinite(mean).any():
                    _plot(ax, xs, mean * scale, err * scale, f"{what} ({name})", categorical)
        ax.set_ylabel(ylabel)
    ax = axes[1, 0]
    for name, group in groups.items():
        for n in R_KEYS:
            xs, mean, err = _series(
                group,
                "c1",
                x_key,
                lambda r, n=n: (r.get("c1_rel_err") or {}).get(n),
                lambda r, n=n: (r.get("c1_rel_se") or {}).get(n),
            )
            if np.isfinite(mean).any():
                _plot(ax, xs, mean * 100, err * 100, f"{n}η ({name})", categorical)
    ax.axhline(0.0, color="0.5", lw=0.8)
    ax.set_ylabel("c₁ / sample truth of its pairs − 1 (%)")
    ax = axes[1, 1]
    for name, group in groups.items():
        xs, mean, err = _series(
            group,
            "eps",
            x_key,
            lambda r: r.get("epsilon_rel_err"),
            lambda r: r.get("epsilon_rel_se"),
        )
        if np.isfinite(mean).any():
            _plot(ax, xs, mean * 100, err * 100, name, categorical)
    ax.axhline(0.0, color="0.5", lw=0.8)
    ax.set_ylabel("plateau ε / estimator on the exact D_LL − 1 (%)")
    for ax in axes.ravel():
        ax.set_xlabel(label)
        ax.grid(True, alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=7)
        else:
            ax.text(0.5, 0.5, "not measured by this chain", ha="center", transform=ax.transAxes)
    if title:
        figure.suptitle(title, fontsize=9)
    return figure


def _plot(ax, xs, mean, err, label, categorical) -> None:
    positions = np.arange(len(xs)) if categorical else np.asarray(xs, dtype=float)
    ax.errorbar(
        positions,
        mean,
        yerr=np.where(np.isfinite(err), err, 0.0),
        marker="o",
        capsize=3,
        label=label,
    )
    if categorical:
        ax.set_xticks(positions, [str(x) for x in xs], rotation=20, fontsize=8)
