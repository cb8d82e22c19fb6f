"""The report of ``synptv score``: ``score.json``, ``report.html`` and ``score.png``."""

import html
import textwrap
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from validation.report.html_parts import number, table
from validation.report.png import save_figure
from validation.report.ptv_figures import mark_off_axis, plain_log_axis
from validation.report.run_figures import BUDGET_AXIS
from validation.score.tolerances import float_array
from validation.workflow.files import write_json_atomic, write_text_atomic

#: The files a report is made of.
REPORT_FILES = ("score.json", "report.html", "score.png")

_STYLE = (
    "<style>body{font-family:sans-serif;max-width:1100px;margin:2em auto;}"
    "table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #bbb;"
    "padding:3px 8px;text-align:right}th{background:#eee}img{max-width:100%}"
    ".fail{color:#b00;font-weight:bold}.pass{color:#070}</style>"
)


def _score_row(label: str, s: dict) -> list[str]:
    """A table row of :func:`validation.score.scores.summarize`."""
    return [
        label,
        number(s["frames"]),
        number(s["n_reference"]),
        number(s["n_found"]),
        number(s["yield"]),
        number(s["ghost_fraction"]),
        *(number(s["position_mean_um"][axis], 3) for axis in "xyz"),
        *(number(s["position_rms_um"][axis], 3) for axis in "xyz"),
        number(s["sheet"]["yield"]),
        number(s["sheet"]["ghost_fraction"]),
    ]


def _statistics_html(statistics: dict) -> list[str]:
    """The statistics section: c1 and ε against the truth, or why there are none."""
    parts = ["<h2>S2 and ε through synptv's multi-Δt statistics</h2>"]
    if not statistics["computed"]:
        return [*parts, f"<p>{html.escape(statistics['reason'])}.</p>"]
    c1, eps, used = statistics["c1"], statistics["epsilon"], statistics["links_used"]
    lo, hi = (1e3 * v for v in c1["r_range_m"])
    rows = [
        ["links by", statistics["linked_by"]],
        ["links used per Δt index", ", ".join(f"{k}: {n}" for k, n in used.items())],
        ["c1 reference", statistics["c1_reference"]],
        [f"max |c1/S2 − 1| over {lo:.3g}–{hi:.3g} mm", number(c1["max_abs_deviation"])],
        ["mean c1/S2 − 1", number(c1["mean_deviation"])],
        ["plateau ε (m²/s³)", number(eps["value"])],
        ["ε / estimator on exact D_LL − 1", number(eps["relative_to_exact_d_ll"])],
    ]
    return [*parts, table(["quantity", "value"], rows)]


def render_html(result: dict) -> str:
    """The report page of a score (``score.png`` beside it)."""
    settings, alignment = result["settings"], result["alignment"]
    box = " × ".join(f"{1e3 * v:g}" for v in settings["analysis_size_m"])
    parts = [
        "<!doctype html><html><head><meta charset='utf-8'>",
        f"<title>synptv score: {html.escape(settings['positions'])}</title>{_STYLE}</head><body>",
        f"<h1>Positions {html.escape(settings['positions'])} against the truth</h1>",
        f"<p>Dataset {html.escape(settings['dataset'])}. Reference: the particles imaged by at "
        f"least {settings['min_cameras']} cameras; a position is a true positive within "
        f"{1e6 * settings['voxel_m']:.4g} µm (one voxel) of a particle, one-to-one; yield, "
        f"ghosts and errors in the {box} mm analysis volume (the sheet: every position and "
        "reference particle). The positions were brought to the world frame by a rigid "
        f"transform fitted on their nearest particles: {alignment['rotation_deg']:.3g}° and "
        + ", ".join(f"{1e6 * v:.3g}" for v in alignment["translation_m"])
        + " µm.</p>",
        "<h2>Positions</h2>",
        table(
            [
                "Δt",
                "frames",
                "reference",
                "found",
                "yield",
                "ghosts",
                *(f"mean {a} (µm)" for a in "xyz"),
                *(f"RMS {a} (µm)" for a in "xyz"),
                "sheet yield",
                "sheet ghosts",
            ],
            [
                *(_score_row(f"{1e3 * s['dt_s']:.4g} ms", s) for s in result["per_dt"]),
                _score_row("total", result),
            ],
        ),
    ]
    tracks = result["tracks"]
    if tracks is not None:
        parts.append("<h2>Links of the tracks</h2>")
        parts.append(
            table(
                ["links", "correct", "wrong", "found in both frames", "broken"],
                [
                    [
                        tracks["links"],
                        f"{tracks['correct']} ({number(tracks['correct_fraction'])})",
                        f"{tracks['wrong']} ({number(tracks['wrong_fraction'])})",
                        tracks["found_in_both"],
                        f"{tracks['broken']} ({number(tracks['broken_fraction'])})",
                    ]
                ],
            )
        )
    parts += _statistics_html(result["statistics"])
    parts.append('<figure><img src="score.png" alt="the score"></figure>')
    parts.append("</body></html>")
    return "\n".join(parts)


def _short(path: str, limit: int = 50) -> str:
    """``path`` as a figure title can hold it: whole up to ``limit`` characters, else
    its last three components."""
    if len(path) <= limit:
        return path
    return str(Path("…", *Path(path).parts[-3:]))


def score_figure(result: dict, errors: np.ndarray) -> Figure:
    """Yield and ghosts per Δt, the position errors, c1 over the sample truth.

    The suptitle names the positions scored and the dataset. The histograms of the
    position errors stop at the 99.5th percentile of |error| (so that the core shows);
    the legend says how many errors of each component lie beyond. Points of c1/S2
    beyond its axis are marked by triangles on the edge, explained in the legend.

    Parameters
    ----------
    result : dict
        The score (``per_dt``, ``statistics``, ``settings``).
    errors : ndarray, shape (N, 3)
        Position errors of the true positives, m.
    """
    figure, (ax_yield, ax_error, ax_c1) = plt.subplots(
        1, 3, figsize=(14.0, 4.3), layout="constrained"
    )
    settings = result.get("settings", {})
    if "positions" in settings:
        figure.suptitle(
            f"synptv score: positions {_short(settings['positions'])} against the truth "
            f"of {_short(settings.get('dataset', '?'))}",
            fontsize=10,
        )
    labels = [f"{1e3 * s['dt_s']:.3g}" for s in result["per_dt"]]
    at = np.arange(len(labels))
    ax_yield.bar(at - 0.2, [s["yield"] for s in result["per_dt"]], 0.4, label="yield")
    ax_yield.bar(at + 0.2, [s["ghost_fraction"] for s in result["per_dt"]], 0.4, label="ghosts")
    for container in ax_yield.containers:
        ax_yield.bar_label(container, fmt="%.3f", fontsize=7)
    ax_yield.set_xticks(at, labels)
    ax_yield.set_ylim(0, 1.1)
    ax_yield.set_xlabel("Δt (ms)")
    ax_yield.set_ylabel("fraction")
    ax_yield.set_title(
        f"Analysis volume: yield {result['yield']:.3f}, ghosts {result['ghost_fraction']:.3f}",
        fontsize=10,
    )
    ax_yield.legend(fontsize=8, loc="center right")
    title = "Position errors of the true positives"
    if len(errors):
        reach = max(float(np.percentile(np.abs(errors), 99.5)) * 1e6, 1.0)
        edges = np.linspace(-reach, reach, 61)
        rms = result["position_rms_um"]
        for axis, column in zip("xyz", errors.T * 1e6, strict=True):
            beyond = int(np.count_nonzero(np.abs(column) > reach))
            label = f"{axis}: RMS {rms[axis]:.3g} µm; {beyond} beyond ±{reach:.3g} µm not shown"
            ax_error.stairs(np.histogram(column, edges)[0], edges, label=label)
        ax_error.set_xlim(-reach, reach)
        ax_error.set_ylim(0, 1.35 * ax_error.get_ylim()[1])  # room for the legend
        ax_error.legend(fontsize=8, loc="upper center")
        title += f"\n(of {len(errors)}; the axis stops at the 99.5th percentile of |error|)"
    ax_error.set_xlabel("position − true particle (µm)")
    ax_error.set_ylabel("true positives")
    ax_error.set_title(title, fontsize=10)
    statistics = result["statistics"]
    if statistics["computed"]:
        r = float_array(statistics["sample_truth"]["r"])
        ratio = float_array(statistics["c1_over_truth"])
        lo, hi = statistics["c1"]["r_range_m"]
        ax_c1.axvspan(lo * 1e3, hi * 1e3, color="0.93", label="check range")
        ax_c1.axhspan(0.95, 1.05, color="C2", alpha=0.12, label="±5 %")
        ok = np.isfinite(ratio) & np.isfinite(r)
        ax_c1.plot(r[ok] * 1e3, ratio[ok], "o-", ms=3.5, lw=1.0, label="c1 / sample-truth S2")
        if mark_off_axis(ax_c1, r * 1e3, ratio, BUDGET_AXIS, "C0"):
            low, high = BUDGET_AXIS
            ax_c1.plot([], [], "^", color="C0", ms=7, label=f"off the axis ({low:g}–{high:g})")
        ax_c1.set_xscale("log")
        plain_log_axis(ax_c1.xaxis, ax_c1.get_xlim())
        ax_c1.set_ylim(*BUDGET_AXIS)
        ax_c1.set_ylabel("c1 / sample-truth S2")
        ax_c1.legend(fontsize=8)
    else:
        reason = textwrap.fill(statistics["reason"], 40)
        ax_c1.text(0.5, 0.5, reason, ha="center", va="center", fontsize=9)
        ax_c1.set_xticks([])
        ax_c1.set_yticks([])
    ax_c1.set_xlabel("r (mm)")
    ax_c1.set_title("Noise-free S2 (multi-Δt fit) against the truth", fontsize=10)
    return figure


def write_report(folder: Path, result: dict, errors: np.ndarray) -> list[Path]:
    """Write :data:`REPORT_FILES` into ``folder``.

    Parameters
    ----------
    folder : Path
        Where (it exists).
    result : dict
        The score.
    errors : ndarray, shape (N, 3)
        Position errors of the true positives, m.

    Returns
    -------
    list of Path
    """
    folder = Path(folder)
    return [
        write_json_atomic(folder / "score.json", result),
        write_text_atomic(folder / "report.html", render_html(result)),
        save_figure(score_figure(result, errors), folder / "score.png"),
    ]
