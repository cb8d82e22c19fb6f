"""``synptv ptv``: the PTV stack on a dataset folder, rendered or real (docs/ptv.md §7)."""

import argparse
import dataclasses
import sys
import tomllib
from pathlib import Path

import numpy as np

from validation.commands.common import COUNT, UsageError, say_took_over
from validation.run.derived_ptv import SHEET_FRACTION
from validation.workflow.files import check_output_folder, hold_output_folder, staged_output
from validation.workflow.progress import ProgressBar


def _ptv_settings(args: argparse.Namespace):
    """The settings file's options (defaults without one), with the command line's
    --max-speed, --snapshots and --min-cameras over them."""
    from ptv.pipeline.settings_file import load_settings
    from ptv.settings import PtvSettings

    settings = PtvSettings() if args.settings is None else load_settings(args.settings)
    given = {
        name: getattr(args, name)
        for name in ("max_speed", "snapshots", "min_cameras")
        if getattr(args, name) is not None
    }
    return dataclasses.replace(settings, pipeline=dataclasses.replace(settings.pipeline, **given))


#: What takes the place of each volume ``synptv ptv`` derives when the settings leave it
#: out.
DERIVED_VOLUMES = {
    "matching.volume": "the calibrated volume the calibration file records, the plate's "
    "dots over the traverse (or the target's points)",
    "statistics.analysis_volume": "the centred {:g} × {:g} × {:g} of the matching volume, "
    "as synptv run takes of the laser sheet".format(*SHEET_FRACTION),
}


def _given_fields(path: str | None) -> set[str]:
    """The ``section.field`` names a settings file gives (read by
    :func:`ptv.pipeline.settings_file.load_settings` first, so it is valid TOML)."""
    if path is None:
        return set()
    spec = tomllib.loads(Path(path).read_text(encoding="utf-8"))
    return {f"{section}.{name}" for section, fields in spec.items() for name in fields}


def with_derived_volumes(settings, given: set[str], calibration: str, *, statistics: bool):
    """The settings with the matching and analysis volumes the settings file leaves out
    derived (:data:`DERIVED_VOLUMES`; the analysis volume only with ``statistics``), and
    one line saying what was derived (None when nothing was).

    Raises
    ------
    UsageError
        The matching volume is left out and the calibration file records no calibrated
        volume.
    """
    from ptv.calibration.io import read_calibrated_volume

    pipeline = settings.pipeline
    volume, said = pipeline.volume, []
    if "matching.volume" not in given:
        volume = read_calibrated_volume(calibration)
        if volume is None:
            raise UsageError(
                f"--calibration {calibration}: the file records no calibrated volume (it was "
                "written before synptv recorded it, or by another path): set [matching] "
                "volume and [statistics] analysis_volume in --settings, m"
            )
        said.append(f"matching volume {_box_text(volume)}: the calibrated volume")
    analysis = pipeline.statistics.analysis_volume
    if statistics and "statistics.analysis_volume" not in given:
        lower, upper = (np.asarray(corner) for corner in volume)
        half = 0.5 * np.asarray(SHEET_FRACTION) * (upper - lower)
        centre = 0.5 * (lower + upper)
        analysis = (tuple(centre - half), tuple(centre + half))
        said.append(
            f"analysis volume {_box_text(analysis)}: "
            "{:g} × {:g} × {:g} of the matching volume".format(*SHEET_FRACTION)
        )
    in_analysis = dataclasses.replace(pipeline.statistics, analysis_volume=analysis)
    pipeline = dataclasses.replace(pipeline, volume=volume, statistics=in_analysis)
    line = f"{'; '.join(said)} (set [matching] volume, [statistics] analysis_volume)"
    return dataclasses.replace(settings, pipeline=pipeline), line if said else None


def _box_text(box) -> str:
    """A box as the user reads it: its size and centre, mm."""
    lower, upper = (1e3 * np.asarray(corner) for corner in box)
    size = " × ".join(f"{v:.4g}" for v in upper - lower)
    centre = ", ".join(f"{v:.4g}" for v in 0.5 * (lower + upper))
    return f"{size} mm at ({centre}) mm"


def _overlay_snapshots(given: list[int] | None, dataset) -> list[int]:
    """The snapshots ``--overlay`` names, each checked against the dataset's count at
    the first Δt (before any work)."""
    if not given:
        return []
    count = dataset.frames[0]
    beyond = [m for m in given if m >= count]
    if beyond:
        raise UsageError(
            f"--overlay {beyond[0]}: the dataset has {count} snapshots at the first dt "
            f"(0 … {count - 1})"
        )
    return sorted(set(given))


def _snapshot_list(text: str) -> list[int]:
    """``--overlay``'s argument: snapshot numbers, comma-separated, each >= 0."""
    try:
        numbers = [int(part) for part in text.split(",") if part.strip()]
    except ValueError:
        numbers = []
    if not numbers or min(numbers) < 0:
        raise argparse.ArgumentTypeError(
            f"expected snapshot numbers >= 0, comma-separated (e.g. 0,5), got {text!r}"
        )
    return numbers


def _say_paper_ranges(statistics) -> None:
    """Warn when the statistics ranges are the defaults, which suit the paper's flow: a
    recording's η and L_int are not known to the stack, so they cannot be derived."""
    from ptv.settings import StatisticsSettings

    default = StatisticsSettings()
    names = ("r_min", "r_max", "plateau")
    if any(_same(getattr(statistics, n), getattr(default, n)) for n in names):
        print(
            "synptv ptv: warning: the r range or plateau is the default, chosen for the "
            "paper's 10 Hz flow (r 0.5-35 mm, plateau 2-20 mm): it is not derived from this "
            "recording; set [statistics] r_min, r_max and plateau for your flow (about 10η "
            "to L_int and 40η to L_int/2)",
            file=sys.stderr,
        )


def _same(a, b) -> bool:
    return bool(np.array_equal(np.asarray(a, dtype=float), np.asarray(b, dtype=float)))


def run_ptv(args: argparse.Namespace) -> int:
    from ptv.calibration.io import load_calibrations
    from ptv.detect.frames import ImageDetector
    from ptv.io.dataset import cameras_in_order, open_dataset
    from ptv.pipeline.double_frame import run_pipeline
    from ptv.pipeline.results import save_results
    from ptv.pipeline.settings_file import settings_toml
    from ptv.pipeline.summary import summary
    from ptv.pipeline.time_resolved import run_recording
    from ptv.pipeline.track_csv import save_fitted_tracks_csv, save_tracks_csv
    from validation.report.overlay import save_overlays
    from validation.report.ptv_figures import save_ptv_figures
    from validation.report.track_figure import save_tracks_figure

    if args.print_settings:
        given = _given_fields(args.settings)
        left_out = {
            field.split(".")[1]: text
            for field, text in DERIVED_VOLUMES.items()
            if field not in given
        }
        print(settings_toml(_ptv_settings(args), left_out=left_out), end="")
        return 0
    missing = [f"--{name}" for name in ("dataset", "calibration", "out") if not getattr(args, name)]
    if missing:
        raise UsageError(f"the following arguments are required: {', '.join(missing)}")
    out = check_output_folder(args.out)
    settings = _ptv_settings(args)
    try:
        dataset = open_dataset(args.dataset)
        calibrations = load_calibrations(args.calibration)
    except FileNotFoundError as err:
        raise UsageError(str(err)) from None
    if args.tracks and dataset.sequence is None:
        raise UsageError(
            f"--tracks needs a time-resolved recording ('time_resolved' in experiment.json, "
            f"docs/experiment.md §5), but {args.dataset} holds frame pairs"
        )
    given = settings.pipeline.min_cameras
    if given is not None and given > len(dataset.cameras):
        raise UsageError(
            f"min_cameras is {settings.pipeline.min_cameras} but the dataset has "
            f"{len(dataset.cameras)} cameras"
        )
    cameras_in_order(dataset, calibrations)  # the same cameras, before the volumes
    settings, volumes = with_derived_volumes(
        settings,
        _given_fields(args.settings),
        args.calibration,
        statistics=not args.positions_only,
    )
    if volumes is not None:
        print(volumes)
    overlay = _overlay_snapshots(args.overlay, dataset)
    bar = ProgressBar("ptv", enabled=not args.quiet)
    run = run_recording if args.tracks else run_pipeline
    tracked = []  # tracks.csv and tracks.png, with --tracks
    with hold_output_folder(out, "synptv ptv") as took_over:
        say_took_over("ptv", took_over)
        detector = ImageDetector(dataset, settings.detection)
        if overlay:
            with staged_output(out) as staging:  # before the run: to judge the settings
                drawn = save_overlays(detector, overlay, staging)
            print(f"detections drawn over {len(drawn)} images: {out}/overlay_*.png")
        try:
            result = run(
                detector,
                calibrations,
                settings.pipeline,
                progress=bar,
                statistics=not args.positions_only,
            )
        except FileNotFoundError as err:
            raise UsageError(str(err)) from None
        track_fit = _fit_tracks(result, settings.tracks) if args.tracks else None
        with staged_output(out) as staging:  # results and figures replace the old together
            written = list(save_results(result, staging, calibration=str(args.calibration)))
            if not args.positions_only:
                label = (
                    f"dataset {Path(args.dataset).name}, calibration {Path(args.calibration).name}"
                )
                written += save_ptv_figures(result, staging, label=label).values()
            if args.tracks:
                tracked = [
                    save_tracks_csv(result, staging),
                    save_tracks_figure(result.recording, staging),
                ]
            if track_fit is not None:
                save_fitted_tracks_csv(result, track_fit, staging)
    h5_path, json_path, *figures = (out / path.name for path in written)
    s = summary(result, calibration=str(args.calibration))
    for line in s["warnings"]:
        print(f"synptv ptv: warning: {line}", file=sys.stderr)
    if not args.positions_only:
        _say_paper_ranges(settings.pipeline.statistics)
    _print_counts(s)
    if args.tracks:
        csv_path, png_path = (out / path.name for path in tracked)
        _print_tracks(s["tracks"])
        print(f"tracks written to {csv_path} and {h5_path} (/tracks), drawn in {png_path}")
        if track_fit is not None:
            _print_track_fit(track_fit, out)
    if args.positions_only:
        print(f"positions and links written to {h5_path} and {json_path}")
        return 0
    _print_statistics(s)
    print(f"results written to {h5_path} and {json_path}")
    print(f"figures written to {', '.join(str(p) for p in figures)}")
    return 0


def _fit_tracks(result, settings):
    """The fit of a recording's tracks (:func:`ptv.pipeline.track_fit.fit_recording`), or
    None with a warning when no track is long enough."""
    from ptv.pipeline.track_fit import fit_recording

    recording = result.recording
    try:
        return fit_recording(
            recording.tracks.track,
            recording.frame_number,
            recording.tracks.positions,
            recording.frame_rate,
            settings,
            statistics=True,
        )
    except ValueError as err:
        print(f"synptv ptv: warning: tracks not fitted: {err}", file=sys.stderr)
        return None


def _print_track_fit(track_fit, out: Path) -> None:
    """What the fit of the tracks did, in two lines."""
    d = track_fit.as_dict()
    noise = ", ".join(f"{v * 1e6:.3g}" for v in d["noise"])
    print(
        f"tracks fitted  {d['tracks']} tracks, {d['points']} points (window {d['window']}, "
        f"{'chosen' if d['window_chosen'] else 'given'}), noise x, y, z {noise} um, "
        f"{d['outliers']} outliers and {d['points_left_out']} points left out"
    )
    if track_fit.statistics is not None:
        a = track_fit.statistics.acceleration
        u = track_fit.statistics.velocity
        print(
            f"Lagrangian     <|a|^2> {a.total:.4g} ± {a.total_se:.2g} m^2/s^4, <|u|^2> "
            f"{u.total:.4g} ± {u.total_se:.2g} m^2/s^2, noise removed over steps "
            f"{', '.join(str(s) for s in a.steps)} (S2L and rho in tracks_fit.json)"
        )
    print(f"fitted tracks written to {out / 'tracks_fitted.csv'} and {out / 'tracks_fit.json'}")


def _print_tracks(t: dict) -> None:
    """The tracks of a ``synptv ptv --tracks`` summary: counts and lengths."""
    first, last = t["frames"]
    mean = "-" if t["mean_length"] is None else f"{t['mean_length']:.1f}"
    print(
        f"tracks          {t['tracks']} through frames {first} … {last} "
        f"({t['points_per_frame']:.0f} points per frame), mean length {mean} points"
    )
    edges, count = t["length_histogram"]["edges"], t["length_histogram"]["count"]
    bins = [
        f"{lo}: {n}" if hi == lo + 1 else f"{lo}-{hi - 1}: {n}"
        for lo, hi, n in zip(edges[:-1], edges[1:], count, strict=True)
    ]
    print(f"                lengths {', '.join(bins)}")


def _print_counts(s: dict) -> None:
    """The matching tolerance, the link speed and the counts per Δt of a ``synptv ptv``
    summary."""
    tolerance = s["match_tolerance"]
    if tolerance is None:
        print(f"matching tolerance {s['settings']['tolerance'] * 1e6:.4g} µm (given)")
    else:
        print(
            f"matching tolerance {tolerance['tolerance'] * 1e6:.4g} µm "
            f"({tolerance['tolerance'] / tolerance['pixel_footprint']:.3g} px of "
            f"{tolerance['pixel_footprint'] * 1e6:.3g} µm; median ray distance "
            f"{tolerance['median_ray_distance'] * 1e6:.3g} µm on {tolerance['rays']} rays)"
        )
    speed = s["link_speed"]
    if speed is None:
        print(f"max_speed {s['settings']['max_speed']:.4g} m/s (given)")
    else:
        print(
            f"max_speed {speed['max_speed']:.4g} m/s, measured on {speed['links']} links of "
            f"{speed['snapshots']} snapshots at dt = {speed['dt'] * 1e3:.4g} ms (mean velocity "
            f"{', '.join(f'{v:.3g}' for v in speed['mean_velocity'])} m/s, rms "
            f"{', '.join(f'{v:.3g}' for v in speed['velocity_rms'])} m/s)"
        )
    print(
        f"{'dt (ms)':>8s} {'snap':>5s} {'detections':>11s} {'matches':>8s} {'links':>7s} "
        f"{'outliers':>8s} {'used':>6s} {'radius':>7s} {'spacing':>7s} {'ambig.':>6s}"
    )
    for c in s["counts"]:
        det = sum(d["a"] + d["b"] for d in c["detections"].values())
        spacing = c["particle_spacing"]
        print(
            f"{c['dt'] * 1e3:8.4f} {c['snapshots_kept']:5d} {det:11d} "
            f"{c['matches']['a'] + c['matches']['b']:8d} {c['links']:7d} "
            f"{c['outliers']:8d} {c['links_used']:6d} {c['link_radius'] * 1e3:5.3g}mm "
            f"{'-' if spacing is None else f'{spacing * 1e3:.3g}mm':>7s} "
            f"{100 * (c['ambiguity'] or 0):5.1f}%"
        )


def _print_statistics(s: dict) -> None:
    """u', the plateau ε, its Δt subsets and the mean displacement of a summary."""
    up = s["u_prime"]
    if up is not None and up["value"] is not None:
        print(f"u' (Eulerian variance fit)        {up['value']:.4g} ± {up['se']:.2g} m/s")
    p = s["epsilon"]["plateau"]
    if p is not None:
        print(
            f"epsilon plateau ({p['r_min'] * 1e3:g}-{p['r_max'] * 1e3:g} mm, C2 = "
            f"{s['epsilon']['kolmogorov_c2']:g}) {p['epsilon']:.4g} ± {p['se_epsilon']:.2g} "
            f"m^2/s^3  (paper's S2^1.5/r: {p['epsilon_paper_caption']:.4g})"
        )
    else:
        print("epsilon plateau                  none (no fitted bin in the plateau range)")
    for name, sub in s["subsets"].items():
        if sub["plateau"] is not None:
            print(
                f"  {name:30s} {sub['plateau']['epsilon']:.4g} ± "
                f"{sub['plateau']['se_epsilon']:.2g} m^2/s^3"
            )
    md = s["mean_displacement"]
    offset = ", ".join(
        f"{o * 1e6:.2f} ± {e * 1e6:.2f}"
        for o, e in zip(md["offset"], md["se_offset_scaled"], strict=True)
    )
    print(f"mean displacement vs dt: offset (X, Y, Z) {offset} um")


def add_ptv_parser(sub) -> None:
    """The ``synptv ptv`` subcommand."""
    ptv = sub.add_parser(
        "ptv",
        help="run 3D-PTV on a dataset: particles, links, multi-dt S2, epsilon, u'",
        description="Detect particles in every frame pair of a dataset folder, match them "
        "between cameras with a calibration file, link frame a to frame b, and compute the "
        "noise-free S2(r) by the multi-dt fit, epsilon(r) and its plateau, the dt subsets, "
        "the mean-displacement linearity check and u'. Writes results.h5, summary.json and "
        "the paper's Fig. 5a, 5b, 6a and 6b as PNG. On a time-resolved recording, --tracks "
        "also matches every frame and links the points into tracks: tracks.csv, /tracks in "
        "results.h5, tracks.png.",
    )
    ptv.add_argument("--dataset", help="folder in the synptv render layout (required)")
    ptv.add_argument("--calibration", help="calibration file, synptv calibrate's (required)")
    ptv.add_argument("--out", help="output folder, created if needed (required)")
    ptv.add_argument(
        "--settings",
        help="TOML file of every option: detection, matching, linking, statistics "
        "(--print-settings shows them)",
    )
    ptv.add_argument(
        "--print-settings",
        action="store_true",
        help="print the settings as a TOML file (the defaults, or --settings with the "
        "options below over it) and exit",
    )
    ptv.add_argument(
        "--max-speed",
        type=float,
        help="largest particle speed, m/s (the link radius; default: measured on the links "
        "of the first snapshots, docs/ptv.md §4)",
    )
    ptv.add_argument("--snapshots", type=COUNT, help="process the first N snapshots per dt")
    ptv.add_argument(
        "--min-cameras",
        type=int,
        help="fewest cameras a match must use (default 2; matches seen by more are preferred)",
    )
    ptv.add_argument(
        "--positions-only",
        action="store_true",
        help="write the matched positions and the links only: no statistics and none of "
        "their figures",
    )
    ptv.add_argument(
        "--tracks",
        action="store_true",
        help="a time-resolved recording only: also match every frame and link the points "
        "frame to frame into tracks (tracks.csv, /tracks in results.h5, tracks.png)",
    )
    ptv.add_argument(
        "--overlay",
        type=_snapshot_list,
        metavar="M[,M...]",
        help="draw the detections over frames a and b of these snapshots at the first dt, "
        "one PNG per camera (OUT/overlay_<camera>_<m>_<a|b>.png), written before the run "
        "to judge the detection settings",
    )
    ptv.add_argument("--quiet", action="store_true", help="no progress bar")
    ptv.set_defaults(run=run_ptv)
