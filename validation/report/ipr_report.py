"""The report's section on iterative particle reconstruction (IPR): every IPR rung's
scores as the LPT Challenge keeps them, and where in the volume and at what overlap of
the images they change (``reconstruction.json``, :mod:`validation.truth.reconstruction`).
"""

import html
from collections.abc import Mapping

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from validation.report.html_parts import number, percent, table

__all__ = ["FIGURE", "ipr_html", "judged_rungs", "reconstruction_figure"]

#: The figure's path under the run folder.
FIGURE = "figures/ipr_breakdown.png"


def judged_rungs(results: dict) -> list[str]:
    """The IPR rungs of a run's results that are judged (through a fitted calibration;
    the first is the method under test), in their order."""
    return [v for v in results.get("reconstruction", {}) if v != "ipr-true-cameras"]


def _column(rows: list[dict], key: str) -> np.ndarray:
    return np.array([np.nan if row.get(key) is None else row[key] for row in rows], float)


def reconstruction_figure(scores: Mapping[str, dict], *, label: str = "") -> Figure:
    """Found fraction, ghosts and projected error against depth, and found fraction
    against the distance to the nearest other particle image, for every IPR rung.

    Parameters
    ----------
    scores : mapping of str to dict
        Rung → its ``reconstruction.json`` (``by_depth``, ``by_neighbour``).
    label : str
        Which run (second title line).
    """
    figure, axes = plt.subplots(1, 3, figsize=(12.0, 3.8), layout="constrained")
    found_ax, error_ax, overlap_ax = axes
    for i, (rung, score) in enumerate(scores.items()):
        depth = score.get("by_depth") or []
        if depth:
            z = np.array([np.mean(row["z_mm"]) for row in depth])
            found_ax.plot(z, _column(depth, "found"), "o-", color=f"C{i}", label=f"{rung}: found")
            kept = 1 - _column(depth, "ghosts")
            found_ax.plot(z, kept, "s--", color=f"C{i}", mfc="none", label=f"{rung}: 1 − ghosts")
            error_ax.plot(z, _column(depth, "rms_px"), "o-", color=f"C{i}", label=rung)
        near = [row for row in score.get("by_neighbour") or [] if row["particles"]]
        if near:
            x = np.arange(len(near))
            overlap_ax.plot(x, _column(near, "found"), "o-", color=f"C{i}", label=rung)
            overlap_ax.set_xticks(x, [_distance_label(row["distance_px"]) for row in near])
    found_ax.set(xlabel="depth Z (mm)", ylabel="fraction", title="found, and 1 − ghosts")
    error_ax.axhline(0.1, color="0.5", lw=0.8, ls=":", label="0.1 px")
    error_ax.set(xlabel="depth Z (mm)", ylabel="projected rms error (px)", ylim=(0, None))
    error_ax.set_title("position error")
    overlap_ax.set(
        xlabel="nearest other particle image (px, least over the cameras)",
        ylabel="found fraction",
        title="found against image overlap",
    )
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    figure.suptitle(f"Iterative particle reconstruction against the truth\n{label}", fontsize=10)
    return figure


def _distance_label(edges) -> str:
    lo, hi = edges
    return f"≥ {lo:g}" if hi is None or not np.isfinite(hi) else f"{lo:g}–{hi:g}"


def ipr_html(scores: Mapping[str, dict]) -> list[str]:
    """The report's IPR section: a table of every rung's scores and the figure."""
    if not scores:
        return []
    rows = [
        (
            html.escape(rung),
            number(s["ppp"], 3),
            percent(s["found"]),
            percent(s["ghosts"]),
            number(s["rms_um"], 3),
            number(s["rms_px"], 3),
            number(s.get("displacement_rms_um"), 3),
            number(s["seconds_per_exposure"], 3),
            number(s["outer_iterations_median"], 3),
        )
        for rung, s in scores.items()
    ]
    header = [
        "IPR rung",
        "particles per pixel",
        "found",
        "ghosts",
        "error (µm)",
        "projected (px)",
        "displacement error (µm)",
        "s per exposure",
        "outer iterations",
    ]
    return [
        "<h2>Iterative particle reconstruction</h2>",
        table(header, rows),
        "<p>Every exposure of the run, scored as the LPT Challenge scores reconstructions: "
        "a particle lit and imaged by every camera is found when a point lies within one "
        "voxel of it (one to one); ghosts are the points with no particle; the error is "
        "the rms 3-D distance and its projection through the true cameras; the "
        "displacement error compares (b − a) of the particles found in both frames of a "
        "pair with their true displacement. The figure shows where these change: with "
        "the depth in the volume, and with the distance from a particle's image to the "
        "nearest other one (overlap).</p>",
        f'<figure><img src="{FIGURE}" alt="IPR scores by depth and overlap">'
        "<figcaption>IPR scores by depth and by image overlap</figcaption></figure>",
    ]
