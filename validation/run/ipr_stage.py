"""The stage of one IPR rung of a run: reconstruct, link, average, and score against the
truth.

Writes into the rung's folder what every rung writes (results.h5, summary.json, the
figures, matching.json, population.json: :class:`validation.run.experiment.RungBuilder`)
and ``reconstruction.json``: the reconstruction scored as the LPT Challenge scores it
(:mod:`validation.truth.reconstruction`) over every exposure of the run, with its time
and the OTF it measured.
"""

import json
from pathlib import Path

import numpy as np

from ptv.calibration.io import load_calibrations
from validation.run.ipr_rung import IprRung, ipr_rung
from validation.truth.matching import score_matching
from validation.truth.reconstruction import score_reconstruction

#: The prefix of an IPR rung's name (``ipr-true-cameras``, ``ipr-<method>``).
PREFIX = "ipr-"


def build_ipr_rung(
    builder, target: Path, variant: str, calibrations: Path | None, cache: Path, tick, label: str
) -> None:
    """Build the IPR rung ``variant`` into ``target`` (module docstring).

    Parameters
    ----------
    builder : validation.run.experiment.RungBuilder
        The run's rung builder (its truth, settings, cameras and savers).
    target : Path
        The rung's folder.
    variant : str
        ``ipr-true-cameras`` or ``ipr-<method>``.
    calibrations : Path or None
        The calibration stage's folder (``<method>.h5``).
    cache : Path
        Where finished chunks are kept.
    tick : callable(done, total) or None
        Progress.
    label : str
        The figures' title.
    """
    run, names = builder.run, builder.store.cameras
    method = variant.removeprefix(PREFIX)
    if method == "true-cameras":
        cams, described = builder.true_cameras, "true cameras"
    else:
        path = calibrations / f"{method}.h5"
        cams, described = load_calibrations(path), str(path)
    sheet = builder.truth.rig.sheet
    centre, size = np.asarray(sheet.centre), np.asarray(sheet.size)
    rung = IprRung(
        settings=run.scenario.ipr.settings(),
        box=(tuple(centre - size / 2), tuple(centre + size / 2)),
        otf_regions=tuple(run.scenario.ipr.otf_regions),
        otf_depth_slabs=run.scenario.ipr.otf_depth_slabs,
    )
    result, frame_a, joined, otfs = ipr_rung(
        run.out / "dataset",
        [cams[name] for name in names],
        builder.settings,
        rung,
        run.chunks,
        executor=run.executor,
        cache=cache,
        progress=tick,
    )
    builder.save(result, target, f"{described}, iterative particle reconstruction", label)
    quality = score_matching(
        frame_a,
        builder.truth.runs(0, len(frame_a))[0],
        names,
        builder.settings,
        voxel=builder.voxel,
        regions=builder.regions,
    )
    _write_json(target / "matching.json", quality.as_dict())
    builder.save_population(result, target, quality.rotation, quality.translation)
    lens = builder.truth.rig.cameras[0].lens
    score = score_reconstruction(
        joined.points,
        builder.truth.runs(*joined.snapshots),
        names,
        [builder.true_cameras[name] for name in names],
        voxel=builder.voxel,
        sensor_pixels=float(np.prod(lens.sensor_size)),
        rotation=quality.rotation,
        translation=quality.translation,
    )
    seconds = np.fromiter(joined.seconds.values(), dtype=float)
    report = {
        **score.as_dict(),
        "voxel_m": builder.voxel,
        "seconds_per_exposure": float(np.median(seconds)),
        "seconds_total": float(seconds.sum()),
        "outer_iterations_median": float(np.median(list(joined.iterations.values()))),
        "otf_depth_m": [float(z) for z in otfs[0].grid_z],
        "otf_sigma_px": [  # per camera and depth slab: σ_x, σ_y (medians over the regions)
            np.stack(
                [np.median(o.sigma_x, axis=(1, 2)), np.median(o.sigma_y, axis=(1, 2))], axis=1
            ).tolist()
            for o in otfs
        ],
        "settings": joined.detector,
    }
    _write_json(target / "reconstruction.json", report)


def _write_json(path: Path, data: dict) -> None:
    path.write_text(json.dumps(data, indent=2, allow_nan=False) + "\n")
