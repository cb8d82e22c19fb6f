"""Where the whole sheet loses its particles: the matching's yield by region of the sheet.

The whole-sheet yield (:mod:`validation.truth.matching`) counts every particle lit and
on every camera's sensor. Its particles are cut here three ways, each a partition, from
what the simulator knows of each of them (docs/run.md §10):

- depth |Z − Z₀| across the sheet: the light sheet is Gaussian, its wings dim, and the
  seeding margin holds particles a little beyond the sheet's faces;
- the sheet's X, Y outline: more than a band inside its edges, within the band, or
  beyond the edges (particles of the seeding margin);
- inside or outside the calibrated volume, the plate's dots over the traverse: a
  calibration without a model has no rays where no dot was seen.

Rows apart from the sheet yield count the particles that fewer than all the cameras
image but at least two (what matching two of C cameras may still find). Each row holds
the region's particles, those found, its yield and its loss: the particles it loses as
a fraction of the whole sheet's, so that the losses of a partition add up to one minus
the sheet yield.
"""

from dataclasses import dataclass
from itertools import pairwise

import numpy as np

from ptv.box import Box, inside_box
from validation.truth.truth_file import TruthFile

#: Upper edges of the depth bins, as fractions of the sheet's half thickness (a last
#: bin holds the particles beyond it).
DEPTH_FRACTIONS = (0.4, 0.8, 0.9, 1.0)
#: Width of the band along the inside of the sheet's X, Y edges, m.
EDGE_BAND = 2e-3
#: The group of the rows outside the sheet yield.
FEWER_CAMERAS = "cameras imaging it"


@dataclass(frozen=True)
class SheetRegions:
    """The regions of a rig's sheet.

    Attributes
    ----------
    sheet : Box
        The lit sheet, (lower, upper) corners, m; its normal along Z.
    calibrated : Box
        The box the plate's dots span over the traverse, m.
    n_cameras : int
        Cameras of the rig, C ≥ 2.
    """

    sheet: Box
    calibrated: Box
    n_cameras: int

    @classmethod
    def of_dataset(cls, truth: TruthFile) -> "SheetRegions":
        """The regions of a rendered dataset: its rig's sheet and cameras, its plate's
        true dots over the traverse."""
        sheet = truth.rig.sheet
        half = 0.5 * np.asarray(sheet.size)
        dots = truth.plate_dots().reshape(-1, 3)
        return cls(
            sheet=(
                tuple(float(v) for v in np.asarray(sheet.centre) - half),
                tuple(float(v) for v in np.asarray(sheet.centre) + half),
            ),
            calibrated=(
                tuple(float(v) for v in dots.min(axis=0)),
                tuple(float(v) for v in dots.max(axis=0)),
            ),
            n_cameras=len(truth.rig.cameras),
        )

    def labels(self) -> list[tuple[str, str]]:
        """(group, region) of every row, in the order of :meth:`members`."""
        half = 0.5 * (self.sheet[1][2] - self.sheet[0][2])
        edges = [0.0, *(f * half for f in DEPTH_FRACTIONS)]
        depth = [
            ("depth |Z − Z₀|", f"{lo * 1e3:.3g} to {hi * 1e3:.3g} mm") for lo, hi in pairwise(edges)
        ]
        band = f"{EDGE_BAND * 1e3:.3g} mm"
        c = self.n_cameras
        return [
            ("sheet", "whole sheet"),
            *depth,
            ("depth |Z − Z₀|", f"beyond {half * 1e3:.3g} mm (outside the sheet)"),
            ("X, Y outline", f"more than {band} inside the edges"),
            ("X, Y outline", f"within {band} inside the edges"),
            ("X, Y outline", "beyond the edges"),
            ("calibrated volume", "inside the plate's dots × traverse"),
            ("calibrated volume", "outside"),
            *((FEWER_CAMERAS, f"{k} of {c} (not in the sheet yield)") for k in range(c - 1, 1, -1)),
        ]

    def members(self, positions: np.ndarray, imaging: np.ndarray) -> np.ndarray:
        """Which particles each row counts.

        Parameters
        ----------
        positions : ndarray, shape (P, 3)
            True particle positions, m.
        imaging : ndarray of int, shape (P,)
            How many cameras image each particle (lit and on the sensor).

        Returns
        -------
        ndarray of bool, shape (R, P)
            One row per :meth:`labels` row.
        """
        positions = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
        lower, upper = (np.asarray(v) for v in self.sheet)
        centre, half = 0.5 * (lower + upper), 0.5 * (upper - lower)
        reference = np.asarray(imaging) == self.n_cameras
        depth = np.abs(positions[:, 2] - centre[2])
        depth_bin = np.searchsorted(np.multiply(DEPTH_FRACTIONS, half[2]), depth, side="left")
        inside = np.min(half[:2] - np.abs(positions[:, :2] - centre[:2]), axis=1)
        calibrated = inside_box(positions, self.calibrated)
        rows = [np.ones(len(positions), dtype=bool)]
        rows += [depth_bin == b for b in range(len(DEPTH_FRACTIONS) + 1)]
        rows += [inside > EDGE_BAND, (inside >= 0) & (inside <= EDGE_BAND), inside < 0]
        rows += [calibrated, ~calibrated]
        rows = [row & reference for row in rows]
        rows += [np.asarray(imaging) == k for k in range(self.n_cameras - 1, 1, -1)]
        return np.array(rows, dtype=bool).reshape(len(rows), len(positions))


def region_counts(
    regions: SheetRegions, positions: np.ndarray, imaging: np.ndarray, found: np.ndarray
) -> np.ndarray:
    """One frame's particles and those found, per row of ``regions``.

    Parameters
    ----------
    regions : SheetRegions
        The cut.
    positions : ndarray, shape (P, 3)
        True particle positions, m.
    imaging : ndarray of int, shape (P,)
        How many cameras image each particle.
    found : ndarray of bool, shape (P,)
        Particles paired with a measured point.

    Returns
    -------
    ndarray of int, shape (R, 2)
        Particles and particles found; summed over frames for :func:`region_table`.
    """
    members = regions.members(positions, imaging)
    return np.column_stack([members.sum(axis=1), (members & found).sum(axis=1)]).astype(np.int64)


def region_table(regions: SheetRegions, counts: np.ndarray) -> list[dict]:
    """The table's rows from summed :func:`region_counts`.

    Returns
    -------
    list of dict
        Per row: ``group``, ``region``, ``particles``, ``found``, ``yield`` (None where
        the region holds no particle) and ``loss``, the particles lost there over the
        whole sheet's particles (None for the rows outside the sheet yield).
    """
    sheet = max(int(counts[0, 0]), 1)
    rows = []
    for (group, region), (particles, found) in zip(regions.labels(), counts, strict=True):
        particles, found = int(particles), int(found)
        rows.append(
            {
                "group": group,
                "region": region,
                "particles": particles,
                "found": found,
                "yield": found / particles if particles else None,
                "loss": None if group == FEWER_CAMERAS else (particles - found) / sheet,
            }
        )
    return rows
