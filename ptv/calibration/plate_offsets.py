"""Plate self-calibration: the printing errors of the plate, estimated with the calibration.

A printed or engraved plate is not its nominal grid: whole columns and rows of dots sit
off the pitch by tens to hundreds of µm, and each dot scatters about its place. Every
camera sees the same plate at every traverse position, so these errors repeat in every
view, while the plane maps T_j: pixel → (X, Y) of a camera and position are smooth
(cubic) functions. The offsets are estimated together with those maps by alternating
least squares:

1. fit each view's T_j (:func:`ptv.calibration.polynomial.fit_polynomial2d`, cubic) to
   the dots at their current corrected positions, nominal + offset;
2. move each offset by the mean residual T_j(pixel) − corrected position over the views
   of its column (δX), row (δY) or dot (δX, δY);
3. remove from the offsets what a smooth map absorbs anyway, the least-squares fit of a
   polynomial of the maps' degree in the grid indices (weighted by the views): those
   components are not identifiable, and leaving them would let the grid drift;

until no offset moves by more than :data:`TOLERANCE`. The corrected grid is then what
every calibration method is fitted on, and Table 1 can be taken against both grids.

Two modes: ``"rows-columns"`` (δX per column i, δY per row j: the pattern of a plate
printed or engraved line by line) and ``"dots"`` (δX, δY per dot, which needs each dot
in several views: cameras × positions ≥ 2).
"""

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np

from ptv.calibration.grid_errors import TraverseDots
from ptv.calibration.polynomial import fit_polynomial2d

#: The modes of :func:`estimate_plate_offsets`.
MODES = ("rows-columns", "dots")
#: Convergence: largest change of an offset in one iteration, m.
TOLERANCE = 1e-9
#: Iterations at most.
MAX_ITERATIONS = 200


@dataclass(frozen=True)
class PlateOffsets:
    """The estimated offsets of the plate's dots from their nominal grid.

    Attributes
    ----------
    mode : str
        ``"rows-columns"`` or ``"dots"``.
    indices : ndarray of int, shape (D, 2)
        Grid indices (i, j) of the dots seen in any view.
    offsets : ndarray, shape (D, 2)
        (δX, δY) of each dot, m: the corrected grid is indices × pitch + offsets.
    pitch : float
        Grid pitch, m.
    iterations : int
        Alternations until convergence.
    rms_before_m, rms_after_m : float
        RMS over all views of |T_j(pixel) − position| in the plate plane against the
        nominal and against the corrected grid, m: what the plane maps could not absorb.
    """

    mode: str
    indices: np.ndarray
    offsets: np.ndarray
    pitch: float
    iterations: int
    rms_before_m: float
    rms_after_m: float

    def of(self, indices: np.ndarray) -> np.ndarray:
        """Offsets (N, 2), m, of dots given by their indices (N, 2) (0 for a dot never
        seen)."""
        row = {tuple(ij): k for k, ij in enumerate(self.indices.tolist())}
        out = np.zeros((len(indices), 2))
        for n, ij in enumerate(np.asarray(indices).tolist()):
            k = row.get(tuple(ij))
            if k is not None:
                out[n] = self.offsets[k]
        return out

    def corrected(
        self, dots: Mapping[str, Sequence[TraverseDots]]
    ) -> dict[str, list[TraverseDots]]:
        """The same dots, their plate positions on the corrected grid."""
        return {
            name: [replace(d, offsets=self.of(d.indices)) for d in planes]
            for name, planes in dots.items()
        }

    def positions(self, indices: np.ndarray, z: Sequence[float]) -> np.ndarray:
        """The corrected grid's dot positions (N_Z, D, 3), m, for grid indices (D, 2)
        and traverse readings Z_j (as :func:`ptv.calibration.grid_errors.nominal_positions`)."""
        xy = np.asarray(indices) * self.pitch + self.of(indices)
        return np.stack([np.column_stack([xy, np.full(len(xy), zj)]) for zj in z])

    def summary(self) -> dict:
        """JSON-able figures: RMS and largest |δX|, |δY| (µm), the map residuals before
        and after (µm), and the offsets per column and row (rows-columns) or per dot."""
        out = {
            "mode": self.mode,
            "iterations": self.iterations,
            "rms_offset_um": (np.sqrt(np.mean(self.offsets**2, axis=0)) * 1e6).tolist(),
            "max_abs_offset_um": (np.abs(self.offsets).max(axis=0) * 1e6).tolist(),
            "map_residual_rms_um": {
                "nominal": self.rms_before_m * 1e6,
                "corrected": self.rms_after_m * 1e6,
            },
        }
        if self.mode == "rows-columns":
            columns, first = np.unique(self.indices[:, 0], return_index=True)
            rows, first_row = np.unique(self.indices[:, 1], return_index=True)
            out["columns"] = {
                "i": columns.tolist(),
                "dX_um": (self.offsets[first, 0] * 1e6).tolist(),
            }
            out["rows"] = {
                "j": rows.tolist(),
                "dY_um": (self.offsets[first_row, 1] * 1e6).tolist(),
            }
        else:
            out["dots"] = {
                "ij": self.indices.tolist(),
                "dXY_um": (self.offsets * 1e6).tolist(),
            }
        return out


def estimate_plate_offsets(
    dots: Mapping[str, Sequence[TraverseDots]], *, mode: str = "rows-columns", degree: int = 3
) -> PlateOffsets:
    """Estimate the plate's offsets from its nominal grid with the plane maps.

    Parameters
    ----------
    dots : dict of str to sequence of TraverseDots
        Identified dots per camera and traverse position (one pitch).
    mode : str
        ``"rows-columns"`` or ``"dots"`` (see the module docstring).
    degree : int
        Degree of the plane maps T_j (that of the model-free calibration, 3).

    Returns
    -------
    PlateOffsets

    Raises
    ------
    ValueError
        An unknown mode; fewer columns or rows (rows-columns), or dots seen in two
        views or more (dots), than the smooth part that is removed needs.
    """
    if mode not in MODES:
        raise ValueError(f"plate offsets mode must be one of {', '.join(MODES)}; got {mode!r}")
    views = [d for planes in dots.values() for d in planes if len(d.indices)]
    pitch = float(views[0].pitch)
    indices, label = np.unique(
        np.concatenate([d.indices for d in views]), axis=0, return_inverse=True
    )
    label = label.ravel()
    bounds = np.cumsum([0] + [len(d.indices) for d in views])
    nominal = indices[label] * pitch
    groups = _groups(indices, label, mode)
    offsets = np.zeros((len(indices), 2))
    before = _residuals(views, nominal, bounds, degree)
    residual, iterations, moved = before, 0, np.inf
    while moved >= TOLERANCE and iterations < MAX_ITERATIONS:
        step = np.stack([_group_mean(residual[:, c], g) for c, g in enumerate(groups)], 1)
        step = _remove_smooth(step, indices, label, mode, degree)
        offsets += step
        residual = _residuals(views, nominal + offsets[label], bounds, degree)
        iterations, moved = iterations + 1, np.abs(step).max()
    return PlateOffsets(
        mode=mode,
        indices=indices,
        offsets=offsets,
        pitch=pitch,
        iterations=iterations,
        rms_before_m=_rms(before),
        rms_after_m=_rms(residual),
    )


def _groups(indices: np.ndarray, label: np.ndarray, mode: str) -> list[np.ndarray]:
    """Per component (X, Y), the group of each observation: its column and its row, or
    its dot for both."""
    if mode == "dots":
        return [label, label]
    return [
        np.unique(indices[:, 0], return_inverse=True)[1].ravel()[label],
        np.unique(indices[:, 1], return_inverse=True)[1].ravel()[label],
    ]


def _group_mean(values: np.ndarray, group: np.ndarray) -> np.ndarray:
    """The mean of ``values`` over each group, per observation."""
    sums = np.bincount(group, values)
    counts = np.bincount(group)
    return (sums / counts)[group]


def _residuals(
    views: list[TraverseDots], positions: np.ndarray, bounds: np.ndarray, degree: int
) -> np.ndarray:
    """T_j(pixel) − position per observation (N, 2), m, each view's map fitted anew."""
    out = np.empty_like(positions)
    for d, lo, hi in zip(views, bounds[:-1], bounds[1:], strict=True):
        fitted = fit_polynomial2d(d.pixels, positions[lo:hi], degree=degree)
        out[lo:hi] = fitted(d.pixels) - positions[lo:hi]
    return out


def _remove_smooth(
    step: np.ndarray, indices: np.ndarray, label: np.ndarray, mode: str, degree: int
) -> np.ndarray:
    """A per-observation offset step (N, 2) reduced to one value per dot (D, 2), less its
    weighted least-squares polynomial of ``degree`` in the grid indices (in i for δX and
    j for δY in rows-columns mode, in (i, j) for dots): what the maps absorb."""
    weights = np.bincount(label, minlength=len(indices)).astype(float)
    per_dot = np.zeros((len(indices), 2))
    per_dot[label] = step
    seen = weights >= (2 if mode == "dots" else 1)  # a dot in one view alone: no estimate
    scale = max(np.abs(indices).max(), 1)
    for c in range(2):
        if mode == "dots":
            i, j = indices[:, 0] / scale, indices[:, 1] / scale
            design = np.stack(
                [i**a * j**b for a in range(degree + 1) for b in range(degree + 1 - a)], 1
            )
        else:
            x = indices[:, c] / scale
            design = np.stack([x**a for a in range(degree + 1)], 1)
        unique = len(np.unique(design[seen], axis=0))
        if unique <= design.shape[1]:
            raise ValueError(
                f"plate offsets ({mode}): {unique} distinct "
                f"{'dots' if mode == 'dots' else ('columns', 'rows')[c]} seen; more than "
                f"{design.shape[1]} are needed to estimate anything beyond what the "
                f"degree-{degree} plane maps absorb"
            )
        root_w = np.sqrt(weights[seen])
        coef, *_ = np.linalg.lstsq(
            design[seen] * root_w[:, None], per_dot[seen, c] * root_w, rcond=None
        )
        per_dot[:, c] -= design @ coef
    per_dot[~seen] = 0.0
    return per_dot


def _rms(residual: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum(residual**2, axis=1))))
