"""The table of a study, whatever its chain: ``study.json``, ``study.csv`` and a figure.

One row per point, seed and calibration method, with the swept parameter and

    table1_d_um, model_error_um      calibration: Table 1 d against the nominal dot
                                     positions, and the model error at random points, µm
    yield, ghosts                    stereo matching against the true particles (the
                                     density study's IPR rows: found and ghosts of the
                                     reconstruction; its columns in
                                     ``validation.studies.density``)
    c1_rel_err, c1_rel_se            {"10", "40", "100"}: c₁/sample truth − 1 and its
                                     standard error at those r/η
    epsilon_rel_err, epsilon_rel_se  plateau ε over the estimator on the exact D_LL − 1

(null where a chain does not measure a quantity: the ideal chain's calibration studies
see no particles, its multi-Δt studies no images). The figure shows each quantity
against the parameter: the mean over the seeds, with error bars of the scatter between
seeds where there are several, else of the bootstrap standard error; a note under the
panels says which.
"""

import csv
import io
from collections.abc import Mapping, Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import NullFormatter

#: The swept parameter of each study, its axis label, and whether it is categorical.
PARAMETERS = {
    "planes": ("planes", "calibration planes N_Z (spanning the traverse)", False),
    "dt": ("dt_subset", "Δt values used", True),
    "noise": ("read_noise_e", "read noise of the particle images (e⁻ rms)", False),
    "seeding": ("tracers", "tracers in the laser sheet", False),
    "obliquity": ("obliquity_deg", "window obliquity (°)", False),
    "density": ("ppp", "particles per pixel of the volume's image", False),
}
#: The first panel of a study's figure (the calibration's error, or for the density
#: study the position error of what the stacks located): label, scale, columns.
FIRST_PANEL = {
    "density": ("position error, 3-D rms (µm)", 1.0, ("position_rms_um",)),
}
CALIBRATION_PANEL = ("calibration error (µm)", 1.0, ("table1_d_um", "model_error_um"))
SECOND_PANEL = {"density": "found (IPR) or matching yield, and ghosts (%)"}
#: Studies whose c₁ and ε panels are drawn on a symmetric log axis, linear within this
#: many per cent of zero (the density study: IPR within per cents, detect-and-match at
#: high density off by thousands).
SYMLOG_STATISTICS = {"density": 10.0}
#: Studies whose parameter spans decades (the density study: 0.005-0.16 particles per
#: pixel), drawn on a logarithmic axis.
LOG_PARAMETER = {"density"}
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


def _series(rows: Sequence[Mapping], x_key: str, value, error):
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


def _groups(rows: Sequence[Mapping]) -> dict[str, list]:
    """The rows per calibration method (and window direction, or Δt population), in
    order of appearance."""
    groups: dict[str, list] = {}
    for row in rows:
        name = row.get("method") or "model-free"
        if row.get("dt_population"):
            name = f"{name}, {row['dt_population']}"
        if "direction_deg" in row:
            where = (
                f"{row['direction_deg']:g}° diagonal" if row["direction_deg"] else "camera plane"
            )
            name = f"{name}, {where}"
        groups.setdefault(name, []).append(row)
    return groups


#: Line styles of the quantities drawn in one panel.
_STYLES = ("-", "--", ":")
_MARKERS = ("o", "s", "^")


def study_figure(study: str, rows: Sequence[Mapping], *, title: str = "") -> Figure:
    """Calibration error, matching, c₁ and ε against the study's parameter.

    One colour per calibration method (and window direction), one line style per
    quantity of a panel.

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
    groups = _groups(rows)
    # Categories (Δt subsets) keep one position each, whatever group they appear in.
    categories = list(dict.fromkeys(r[x_key] for r in rows)) if categorical else None
    figure, axes = plt.subplots(2, 2, figsize=(11.0, 8.0), layout="constrained")
    if study in LOG_PARAMETER:  # before the ticks: a scale set later would replace them
        for ax in axes.ravel():
            ax.set_xscale("log")
            ax.xaxis.set_minor_formatter(NullFormatter())
    scalar = {
        axes[0, 0]: FIRST_PANEL.get(study, CALIBRATION_PANEL),
        axes[0, 1]: (
            SECOND_PANEL.get(study, "matching yield and ghosts (%)"),
            100.0,
            ("yield", "ghosts"),
        ),
    }
    names = {
        "table1_d_um": "Table 1 d",
        "model_error_um": "model error",
        "position_rms_um": "position error",
    }
    for ax, (ylabel, scale, keys) in scalar.items():
        for colour, (name, group) in enumerate(groups.items()):
            for style, key in zip(_STYLES, keys, strict=False):
                xs, mean, err = _series(group, x_key, lambda r, k=key: r.get(k), lambda r: None)
                what = f"{names.get(key, key)} ({name})"
                _plot(ax, xs, mean * scale, err * scale, what, categories, colour, style)
        ax.set_ylabel(ylabel)
    for colour, (name, group) in enumerate(groups.items()):
        for i, n in enumerate(R_KEYS):
            xs, mean, err = _series(
                group,
                x_key,
                lambda r, n=n: (r.get("c1_rel_err") or {}).get(n),
                lambda r, n=n: (r.get("c1_rel_se") or {}).get(n),
            )
            label_n = f"{n}η ({name})"
            _plot(
                axes[1, 0],
                xs,
                mean * 100,
                err * 100,
                label_n,
                categories,
                colour,
                _STYLES[i],
                _MARKERS[i],
            )
        xs, mean, err = _series(
            group, x_key, lambda r: r.get("epsilon_rel_err"), lambda r: r.get("epsilon_rel_se")
        )
        _plot(axes[1, 1], xs, mean * 100, err * 100, name, categories, colour, "-")
    axes[1, 0].set_ylabel("c₁ / sample truth of its pairs − 1 (%)")
    axes[1, 1].set_ylabel("plateau ε / estimator on the exact D_LL − 1 (%)")
    for ax in axes[1]:
        ax.axhline(0.0, color="0.5", lw=0.8)
        if study in SYMLOG_STATISTICS:  # stacks whose errors differ by orders of magnitude
            ax.set_yscale("symlog", linthresh=SYMLOG_STATISTICS[study])
    for ax in axes.ravel():
        ax.set_xlabel(label)
        ax.grid(True, alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=7)
        else:
            ax.text(0.5, 0.5, "not measured on this chain", ha="center", transform=ax.transAxes)
    if title:
        figure.suptitle(title, fontsize=9)
    figure.text(0.5, 0.0, error_bar_note(rows), ha="center", va="top", fontsize=8)
    return figure


def error_bar_note(rows: Sequence[Mapping]) -> str:
    """What the error bars of :func:`study_figure` are, for these rows."""
    seeds = len({r.get("seed") for r in rows})
    if seeds >= 2:
        return (
            f"Points: mean over {seeds} seeds; error bars: ±1 standard error of that mean "
            f"(the seeds' scatter / √{seeds})."
        )
    return (
        "One seed: error bars are ±1 bootstrap standard error of c₁ and ε "
        "(c1_rel_se, epsilon_rel_se); the calibration errors and the matching have none."
    )


def _plot(ax, xs, mean, err, label, categories, colour, style, marker="o") -> None:
    """One series with its error bars (nothing when every value is missing); x values
    are numbers, or (with ``categories``) placed at their category's position."""
    if not np.isfinite(mean).any():
        return
    if categories is None:
        positions = np.asarray(xs, dtype=float)
        ticks, labels = positions, [f"{x:g}" for x in xs]
    else:
        positions = np.array([categories.index(x) for x in xs], dtype=float)
        ticks, labels = np.arange(len(categories)), [str(c) for c in categories]
    ax.errorbar(
        positions,
        mean,
        yerr=np.where(np.isfinite(err), err, 0.0),
        color=f"C{colour}",
        ls=style,
        marker=marker,
        ms=4,
        capsize=3,
        label=label,
    )
    ax.set_xticks(ticks, labels, fontsize=8)
