"""Figures of the calibration comparison: the paper's Fig. 3 error maps and the studies.

Each function returns a matplotlib Figure (Agg backend), for
:func:`validation.report.png.save_figure`. Lengths are shown in mm and errors in
µm, as labelled.
"""

import textwrap
from collections.abc import Mapping, Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from ptv.calibration.grid_errors import PositionErrors
from ptv.calibration.plate_offsets import PlateOffsets


def _site_means(errors: PositionErrors) -> tuple[np.ndarray, np.ndarray]:
    """Per (X, Y) dot site: nominal position (S, 2) in mm, and the mean over the planes
    of |Δ|, Δ_X, Δ_Y, Δ_Z (S, 4) in µm."""
    sites = np.round(errors.truth[:, :2], 3)  # dots of different planes share (X, Y) to 1 mm
    keys, inverse = np.unique(sites, axis=0, return_inverse=True)
    values = np.column_stack([np.linalg.norm(errors.delta, axis=1), errors.delta])
    seen = np.isfinite(values[:, 0])
    count = np.bincount(inverse.ravel(), weights=seen, minlength=len(keys))
    means = np.empty((len(keys), 4))
    for k in range(4):
        total = np.bincount(
            inverse.ravel(), weights=np.where(seen, values[:, k], 0.0), minlength=len(keys)
        )
        with np.errstate(invalid="ignore"):
            means[:, k] = total / count * 1e6
    return keys * 1e3, means


#: Rows of :func:`error_maps`: title, colour map, and whether the scale is signed.
_MAP_ROWS = (
    ("mean |Δ| (µm)", "viridis", False),
    ("mean Δ_X (µm)", "RdBu_r", True),
    ("mean Δ_Y (µm)", "RdBu_r", True),
    ("mean Δ_Z (µm)", "RdBu_r", True),
)


#: Methods that fit polynomial maps to the dots with no optical model: with the same
#: dots they come out alike (docs/calibration.md §3 and §6).
POLYNOMIAL_METHODS = ("model-free", "soloff")
#: Relative difference of Table 1 d under which :func:`error_maps` says two polynomial
#: methods agree.
AGREEMENT = 0.02


def agreement_note(errors_by_method: Mapping[str, PositionErrors]) -> str:
    """Why the model-free and Soloff columns of Fig. 3 look alike, when they do
    (their Table 1 d within :data:`AGREEMENT`); "" otherwise."""
    if not all(m in errors_by_method for m in POLYNOMIAL_METHODS):
        return ""
    d = [errors_by_method[m].d * 1e6 for m in POLYNOMIAL_METHODS]
    if not (np.isfinite(d).all() and abs(d[0] - d[1]) <= AGREEMENT * max(d)):
        return ""
    return (
        f"Model-free and Soloff agree (d = {d[0]:.4g} and {d[1]:.4g} µm): both fit "
        "polynomial maps (cubic in X and Y) to the same detected dots, with no optical "
        "model, and Table 1 triangulates those very dots, so both errors are the same "
        "dot-centre noise (docs/calibration.md §3, §6, §7). The columns are computed "
        "separately, not copied."
    )


def error_maps(errors_by_method: Mapping[str, PositionErrors], *, title: str = "") -> Figure:
    """The paper's Fig. 3: error of each dot site, mean over the planes, per method.

    One column per method, whose title gives the Table 1 components; the first row is
    the 3-D error |Δ|, the others the signed components Δ_X, Δ_Y, Δ_Z. Every panel has
    a colour scale of its own (up to its 99th percentile; symmetric about zero for the
    components), so that a method's structure shows however large its errors are:
    compare methods by the numbers, not by the colours. Below the panels, a note says
    so, and why model-free and Soloff agree when they do (:func:`agreement_note`).
    """
    methods = list(errors_by_method)
    figure, axes = plt.subplots(
        len(_MAP_ROWS),
        len(methods),
        figsize=(3.9 * len(methods), 3.3 * len(_MAP_ROWS)),
        squeeze=False,
        layout="constrained",
    )
    for column, method in enumerate(methods):
        errors = errors_by_method[method]
        xy, means = _site_means(errors)
        for row, (label, cmap, signed) in enumerate(_MAP_ROWS):
            ax, value = axes[row, column], means[:, row]
            top = float(np.nanpercentile(np.abs(value), 99)) if np.isfinite(value).any() else 1.0
            top = top if top > 0 else 1.0
            image = ax.scatter(
                xy[:, 0],
                xy[:, 1],
                c=value,
                s=14,
                marker="s",
                vmin=-top if signed else 0.0,
                vmax=top,
                cmap=cmap,
            )
            figure.colorbar(image, ax=ax, label=label, shrink=0.85)
            ax.set_aspect("equal")
            if row == len(_MAP_ROWS) - 1:
                ax.set_xlabel("X (mm)")
            if column == 0:
                ax.set_ylabel("Y (mm)")
        dx, dy, dz = errors.components * 1e6
        axes[0, column].set_title(
            f"{method}\nd_X {dx:.1f}, d_Y {dy:.1f}, d_Z {dz:.1f}, d {errors.d * 1e6:.1f} µm",
            fontsize=9,
        )
    if title:
        figure.suptitle(title)
    note = "Each panel has a colour scale of its own: compare the methods by the numbers."
    agree = agreement_note(errors_by_method)
    figure.text(
        0.5,
        0.0,
        "\n".join(textwrap.wrap(f"{note} {agree}".strip(), 40 * len(methods) + 40)),
        ha="center",
        va="top",
        fontsize=8.5,
    )
    return figure


def obliquity_curves(rows: Sequence[Mapping[str, float]]) -> Figure:
    """Table 1 error ratio to the model-free method against window obliquity, per method."""
    directions = sorted({r["direction_deg"] for r in rows})
    methods = list(dict.fromkeys(r["method"] for r in rows))
    figure, axes = plt.subplots(
        1,
        len(directions),
        figsize=(5.0 * len(directions), 4.0),
        squeeze=False,
        layout="constrained",
        sharey=True,
    )
    for ax, direction in zip(axes[0], directions, strict=True):
        for method in methods:
            sel = sorted(
                (r for r in rows if r["direction_deg"] == direction and r["method"] == method),
                key=lambda r: r["obliquity_deg"],
            )
            ax.plot(
                [r["obliquity_deg"] for r in sel],
                [r["ratio_to_model_free"] for r in sel],
                marker="o",
                label=method,
            )
        where = "in the camera plane" if direction == 0 else f"about a {direction:g}° diagonal"
        ax.set_title(f"window tilted {where}", fontsize=10)
        ax.set_xlabel("window obliquity (°)")
        ax.set_yscale("log")
        ax.axhline(1.0, color="0.6", lw=0.8)
        ax.grid(True, which="both", alpha=0.3)
    axes[0, 0].set_ylabel("Table 1 d / d(model-free)")
    axes[0, -1].legend(fontsize=8)
    return figure


def plane_count_curves(rows: Sequence[Mapping[str, float]]) -> Figure:
    """Error with N_Z planes relative to all planes, on both metrics."""
    rows = sorted(rows, key=lambda r: r["planes"])
    figure, ax = plt.subplots(figsize=(5.0, 3.8), layout="constrained")
    n = [r["planes"] for r in rows]
    ax.plot(n, [r["table1_ratio"] for r in rows], marker="o", label="Table 1 metric (dots)")
    ax.plot(n, [r["model_ratio"] for r in rows], marker="s", label="model error (random points)")
    ax.axhline(1.0, color="0.6", lw=0.8)
    ax.set_xlabel("calibration planes N_Z (spanning the depth)")
    ax.set_ylabel(f"error / error with {n[-1]} planes")
    ax.legend(fontsize=8)
    ax.grid(True, alpha=0.3)
    return figure


def plate_offsets_figure(offsets: PlateOffsets) -> Figure:
    """The self-calibrated plate's offsets from its nominal grid.

    Rows-columns mode: δX per column and δY per row, µm, against the grid index. Dots
    mode: the offsets as arrows at the dots' nominal places (grid units), with a scale.
    """
    if offsets.mode == "rows-columns":
        fig, axes = plt.subplots(1, 2, figsize=(10, 3.6))
        for ax, c, name in ((axes[0], 0, "column i"), (axes[1], 1, "row j")):
            index, first = np.unique(offsets.indices[:, c], return_index=True)
            ax.bar(index, offsets.offsets[first, c] * 1e6, color=f"C{c}")
            ax.axhline(0, color="k", lw=0.6)
            ax.set_xlabel(name)
            ax.set_ylabel(f"δ{'XY'[c]}, µm")
            ax.set_title(f"offset of each {name.split()[0]} from the nominal grid")
    else:
        fig, ax = plt.subplots(figsize=(6.5, 5.5))
        largest = float(np.abs(offsets.offsets).max()) or 1.0
        ax.quiver(
            offsets.indices[:, 0],
            offsets.indices[:, 1],
            offsets.offsets[:, 0] * 1e6,
            offsets.offsets[:, 1] * 1e6,
            angles="xy",
            scale_units="xy",
            scale=largest * 1e6 / 0.8,
        )
        ax.set_aspect("equal")
        ax.set_xlabel("column i")
        ax.set_ylabel("row j")
        ax.set_title(
            "offset of each dot from the nominal grid\n"
            f"(0.8 grid spacing = {largest * 1e6:.1f} µm)",
            fontsize=10,
        )
    fig.suptitle(
        f"plate self-calibration ({offsets.mode}): plane-map residual "
        f"{offsets.rms_before_m * 1e6:.1f} → {offsets.rms_after_m * 1e6:.1f} µm rms",
        fontsize=10,
    )
    fig.tight_layout()
    return fig
