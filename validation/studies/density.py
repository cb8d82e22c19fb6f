"""The density study: a dense scenario's particles swept over the LPT Challenge's
densities, each point through images, iterative particle reconstruction (IPR) beside
the detect-and-match stack, and the multi-Δt statistics (docs/study.md).

A density is counted as the LPT Challenge counts it, in particles per pixel (ppp) of
the image the volume projects onto (:func:`volume_image_area`, the mean over the
cameras): the tracers of a point are ppp × that area, all lit (a dense rig lights its
volume and nothing else, docs/rigs.md §2). Each point renders anew and runs every rung
of ``synptv run`` on it; its rows (one per rung under study: the detect-and-match stack
through the first ``[ptv]`` method, IPR through the true cameras and through every
``[ipr]`` method) give, besides the columns every study has (``validation.studies.table``),
the reconstruction's scores over every exposure (``validation.truth.reconstruction``):
``found`` and ``ghosts`` (as ``yield`` and ``ghosts`` for the IPR rows: the figure's
matching panel then compares the two stacks), ``position_rms_um`` and
``position_rms_px``, ``displacement_rms_um``, the density measured on the sensors,
the seconds per exposure, and how far down in r the statistics reach (the smallest
fitted separation and the particles S2 used at the smallest Δt).
"""

import json
from functools import cache
from pathlib import Path

import numpy as np

from simulator.rigs import Rig, load_rig

__all__ = [
    "DENSITIES_PPP",
    "density_scores",
    "image_area",
    "particles_at",
    "statistics_reach",
    "volume_image_area",
]

#: The LPT Challenge's densities, particles per pixel of the volume's image.
DENSITIES_PPP = (0.005, 0.025, 0.05, 0.08, 0.12, 0.16)
#: Densities allowed in ``--ppp``.
PPP_RANGE = (1e-4, 0.3)
#: Random points of :func:`volume_image_area` (about 70 per cell of a 512 × 512 px
#: image of the volume: an inner cell is missed with a probability of e⁻⁷⁰, an outline
#: cell the volume covers to a tenth with one of e⁻⁷) and its cell, px.
AREA_SAMPLES = 200_000
AREA_CELL_PX = 8


def image_area(cameras, box, *, rng: np.random.Generator) -> float:
    """Mean over the cameras of the image area a box projects onto, px².

    ``AREA_SAMPLES`` random points fill the box; the cells of ``AREA_CELL_PX`` px that
    their images touch are counted (a cell overestimates the area by about half its
    width along the outline: under 3 % for a volume imaged on 400 px or more).

    Parameters
    ----------
    cameras : sequence of camera models
        Their ``project``.
    box : (lower, upper)
        Corners of the volume, m.
    rng : numpy.random.Generator
        The random points.

    Returns
    -------
    float
    """
    lower, upper = (np.asarray(v, dtype=float) for v in box)
    points = rng.uniform(lower, upper, (AREA_SAMPLES, 3))
    areas = []
    for camera in cameras:
        xy = camera.project(points)
        xy = xy[np.isfinite(xy).all(axis=1)]
        cells = np.unique(np.floor(xy / AREA_CELL_PX).astype(np.int64), axis=0)
        areas.append(len(cells) * AREA_CELL_PX**2)
    return float(np.mean(areas))


def volume_image_area(rig: Rig, *, seed: int = 1) -> float:
    """:func:`image_area` of the rig's volume (its sheet), px², the random points drawn
    with ``seed``."""
    centre, size = np.asarray(rig.sheet.centre), np.asarray(rig.sheet.size)
    box = (centre - size / 2, centre + size / 2)
    return image_area(rig.cameras, box, rng=np.random.default_rng(seed))


def particles_at(ppp: float, rig_name: str) -> int:
    """Tracers that image at ``ppp`` particles per pixel of the volume's image."""
    return max(1, round(ppp * _rig_image_area(rig_name)))


@cache
def _rig_image_area(rig_name: str) -> float:
    return volume_image_area(load_rig(rig_name))


def density_scores(folder: Path) -> dict:
    """The reconstruction's scores of an IPR rung's folder (``reconstruction.json``), as
    the study's columns (module docstring)."""
    s = json.loads((folder / "reconstruction.json").read_text())
    return {
        "yield": s["found"],
        "ghosts": s["ghosts"],
        "found": s["found"],
        "position_rms_um": s["rms_um"],
        "position_rms_px": s["rms_px"],
        "displacement_rms_um": s.get("displacement_rms_um"),
        "ppp_sensor": s["ppp"],
        "seconds_per_exposure": s["seconds_per_exposure"],
    }


def statistics_reach(folder: Path) -> dict:
    """How far down in r the rung's statistics reach (its ``summary.json``): the
    smallest separation its S2 fitted, mm, and the particles its S2 used at the smallest
    Δt (links in the analysis volume, over the snapshots)."""
    summary = json.loads((folder / "summary.json").read_text())
    sf = summary["structure_function"]
    fitted = np.array(sf["fitted"], dtype=bool)
    r = np.asarray(sf["r"], dtype=float)
    return {
        "smallest_fitted_r_mm": float(r[fitted].min() * 1e3) if fitted.any() else None,
        "links_used": int(summary["counts"][0]["links_used"]),
    }
