"""Calibration studies from the command line: plane count and window obliquity.

Each study writes ``<out>/<study>.json`` (every row) and ``<out>/<study>.png`` (the
curves). Dots are exact projections through the rig's windows plus Gaussian centre
noise, so a sweep takes minutes rather than hours of rendering.
"""

import json
import os
import tempfile
from pathlib import Path

from simulator.rigs import load_rig
from simulator.target import Imperfections, PlateDesign, build_plate, traverse_positions
from validation.calibration_accuracy import synthetic_plane_dots
from validation.calibration_study import obliquity_study, plane_count_study
from validation.figures import obliquity_curves, plane_count_curves, save_figure
from validation.progress import ProgressBar

STUDIES = ("planes", "obliquity")


def _write_json(path: Path, rows: list[dict]) -> None:
    handle, temporary = tempfile.mkstemp(suffix=".json", dir=path.parent, prefix=f".{path.name}.")
    with os.fdopen(handle, "w") as stream:
        json.dump(rows, stream, indent=2)
    os.chmod(temporary, 0o644)
    os.replace(temporary, path)


def run_study(
    study: str, rig_name: str, out: Path, *, noise_px: float, seed: int, quiet: bool
) -> tuple[Path, Path]:
    """Run one calibration study and write its JSON rows and PNG curves.

    Parameters
    ----------
    study : {"planes", "obliquity"}
        Which sweep.
    rig_name : str
        Rig preset or TOML file.
    out : Path
        Output folder (created).
    noise_px : float
        Dot-centre noise, px.
    seed : int
        Seed of the plate, the noise and the test points.
    quiet : bool
        No progress bar.

    Returns
    -------
    (Path, Path)
        The JSON and PNG files.
    """
    if study not in STUDIES:
        raise ValueError(f"unknown study {study!r}; known: {', '.join(STUDIES)}")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    rig = load_rig(rig_name)
    bar = ProgressBar(f"study {study}", enabled=not quiet)
    if study == "planes":
        plate = build_plate(
            PlateDesign(), traverse_positions(), imperfections=Imperfections(), rng=seed
        )
        dots = synthetic_plane_dots(rig.cameras, plate, noise_px=noise_px, rng=seed + 1)
        rows = plane_count_study(rig, plate, dots, rng=seed + 2, progress=bar)
        figure = plane_count_curves(rows)
    else:
        rows = obliquity_study(rig.spec, noise_px=noise_px, rng=seed, progress=bar)
        figure = obliquity_curves(rows)
    json_path = out / f"{study}.json"
    _write_json(json_path, rows)
    return json_path, save_figure(figure, out / f"{study}.png")
