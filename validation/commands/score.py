"""``synptv score``: any code's 3-D positions (and tracks) against a dataset's truth.

Everything the command reads is checked before anything is written (the dataset and
its truth.h5, the options, every row of the positions file): bad input is a one-line
error with exit status 2 and no output folder. The report files are written together
(:func:`validation.workflow.files.staged_output`).
"""

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

from validation.run.scenario import PtvSection, Scenario, pipeline_settings
from validation.workflow.files import (
    as_json,
    check_output_folder,
    hold_output_folder,
    staged_output,
)


def _positive_length(text: str) -> float:
    """An argparse type: a finite length > 0, m."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a length in m, got {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be a finite length > 0 (m), got {text!r}")
    return value


def _box_size(text: str) -> tuple[float, float, float]:
    """An argparse type: three lengths LX,LY,LZ > 0, m."""
    parts = text.split(",")
    if len(parts) != 3:
        raise argparse.ArgumentTypeError(f"must be three sizes LX,LY,LZ in m, got {text!r}")
    return tuple(_positive_length(p) for p in parts)  # type: ignore[return-value]


def add_score_parser(sub) -> None:
    """The ``synptv score`` subcommand."""
    score = sub.add_parser(
        "score",
        help="score any code's 3-D positions (and tracks) against a dataset's truth",
        description="Score 3-D positions (CSV with header dt,snapshot,frame,x,y,z and an "
        "optional track column, metres in the dataset's world frame; or the same columns "
        "in HDF5, e.g. a results.h5 of synptv ptv) against the truth of a rendered "
        "dataset: yield, ghost fraction and position errors per dt and in total, the "
        "links of tracks, and S2/epsilon through synptv's multi-dt statistics against the "
        "truth. Writes score.json, report.html and score.png.",
    )
    score.add_argument(
        "--dataset",
        required=True,
        help="a dataset rendered by synptv (for --tracks CSV: one recording, DIR/sequence<s>)",
    )
    score.add_argument("--positions", help="the positions file (CSV or HDF5)")
    score.add_argument(
        "--tracks",
        nargs="?",
        const=True,
        default=False,
        metavar="CSV",
        help="with --positions: score the links of its track column too; given a file "
        "(CSV with header track,frame,x,y,z and optional vx,vy,vz, ax,ay,az; m, m/s, m/s² in "
        "the world frame) and a rendered recording: score time-resolved tracks against the "
        "true trajectories (docs/score.md §11)",
    )
    score.add_argument("--json", action="store_true", help="print one JSON object")
    score.add_argument("--out", default="synptv-score", help="report folder (default synptv-score)")
    score.add_argument(
        "--voxel", type=_positive_length, help="pairing distance, m (default: one object pixel)"
    )
    score.add_argument(
        "--min-cameras",
        type=int,
        default=2,
        help="cameras a reference particle is imaged by, at least (default 2)",
    )
    score.add_argument(
        "--analysis-size",
        type=_box_size,
        metavar="LX,LY,LZ",
        help="sizes of the centred analysis volume, m (default synptv run's, 0.07,0.07,0.008; "
        "a scenario's [ptv] analysis_size)",
    )
    score.add_argument(
        "--analysis-volume", type=_box_size, dest="old_analysis_size", help=argparse.SUPPRESS
    )
    score.set_defaults(run=run_score)


def _analysis_size(args: argparse.Namespace) -> tuple[float, float, float]:
    """``--analysis-size``, read from its old name ``--analysis-volume`` with a warning, or
    synptv run's default; raises ValueError when both names are given."""
    if args.old_analysis_size is None:
        return args.analysis_size or PtvSection().analysis_size
    if args.analysis_size is not None:
        raise ValueError("--analysis-volume is the old name of --analysis-size: give that only")
    print(
        "synptv score: --analysis-volume is an old name, read as --analysis-size: write that",
        file=sys.stderr,
    )
    return args.old_analysis_size


def _settings(size: tuple[float, float, float]):
    """synptv run's default PTV settings with the analysis volume of ``size``."""
    return pipeline_settings(Scenario("score", ptv=PtvSection(analysis_size=size)))


def _truth(dataset: str):
    """The dataset's :class:`~validation.truth.truth_file.TruthFile`, or a one-line
    error."""
    from validation.truth.truth_file import TruthFile

    folder = Path(dataset)
    if not folder.is_dir():
        raise ValueError(f"--dataset {folder}: no such folder")
    if not (folder / "truth.h5").is_file():
        raise ValueError(
            f"--dataset {folder}: no truth.h5 (score needs a dataset rendered by synptv)"
        )
    return TruthFile(folder)


def score(args: argparse.Namespace) -> tuple[dict, np.ndarray]:
    """The score of ``args.positions`` (module docstring) and the position errors of
    its true positives (N, 3), m; raises ValueError on bad input, writes nothing."""
    from validation.run.experiment import object_pixel
    from validation.run.score_statistics import score_statistics
    from validation.score.positions import check_positions, read_positions
    from validation.score.reference import score_positions
    from validation.score.scores import per_dt, summarize, track_scores
    from validation.truth.matching import rotation_angle_deg

    truth = _truth(args.dataset)
    cameras = len(truth.rig.camera_names)
    if not 1 <= args.min_cameras <= cameras:
        raise ValueError(
            f"--min-cameras {args.min_cameras}: must be 1 to the dataset's {cameras} cameras"
        )
    size = _analysis_size(args)
    positions = read_positions(args.positions, tracks=args.tracks)
    check_positions(positions, n_dt=len(truth.dt), snapshots=truth.frames, sheet=truth.rig.sheet)
    settings = _settings(size)
    box = settings.statistics.analysis_volume
    voxel = object_pixel(truth.rig) if args.voxel is None else args.voxel
    scored = score_positions(positions, truth, voxel=voxel, min_cameras=args.min_cameras, box=box)
    result = {
        **summarize(scored.frames),
        "per_dt": per_dt(scored.frames, truth.dt),
        "snapshots_per_dt": min(
            len({f.m for f in scored.frames if f.k == k}) for k in {f.k for f in scored.frames}
        ),
        "tracks": track_scores(positions, scored.frames) if args.tracks else None,
        "statistics": score_statistics(positions, scored, truth, settings, voxel=voxel),
        "alignment": {
            "rotation": scored.rotation,
            "rotation_deg": rotation_angle_deg(scored.rotation),
            "translation_m": scored.translation,
        },
        "settings": {
            "dataset": str(args.dataset),
            "positions": str(args.positions),
            "voxel_m": voxel,
            "min_cameras": args.min_cameras,
            "analysis_size_m": list(size),
            "rows": len(positions.k),
        },
    }
    result["reconstruction"] = _reconstruction_scores(positions, truth, voxel, scored)
    errors = np.concatenate([f.error[f.tp_in] for f in scored.frames])
    return as_json(result), errors


def _reconstruction_scores(positions, truth, voxel: float, scored) -> dict:
    """The LPT Challenge's scores of every exposure the file holds positions for, over
    the whole volume (validation.truth.reconstruction: found among the particles every
    camera images, ghosts, errors in µm and projected px, the displacement between the
    frames of a pair, and each by depth and by the nearest other particle image)."""
    from validation.truth.reconstruction import score_reconstruction

    keys = np.stack([positions.k, positions.snapshot, positions.frame], axis=1)
    points = {
        (int(k), int(m), "ab"[f]): positions.xyz[(keys == (k, m, f)).all(axis=1)]
        for k, m, f in np.unique(keys, axis=0)
    }
    lens = truth.rig.cameras[0].lens
    return score_reconstruction(
        points,
        truth.runs(0, truth.frames),
        truth.rig.camera_names,
        truth.rig.cameras,
        voxel=voxel,
        sensor_pixels=float(np.prod(lens.sensor_size)),
        rotation=scored.rotation,
        translation=scored.translation,
    ).as_dict()


#: Effective independent snapshots below which a verdict is too weak to mean much: at
#: 0.1 % false alarms the Student quantile of 9 degrees of freedom is 4.8 standard
#: errors (3.3 for many), of 3 (four snapshots) 12.9.
MIN_SNAPSHOTS_FOR_VERDICT = 10


def _statistics_lines(statistics: dict, snapshots: int) -> list[str]:
    """c1, the plateau ε and u′ against the truth of the same snapshots, each with its
    tolerance and verdict; where the snapshots are too few for a verdict with any power
    (:data:`MIN_SNAPSHOTS_FOR_VERDICT` effective snapshots), a line saying so."""
    c1, eps = statistics["c1"], statistics["epsilon"]
    deviation = c1["max_abs_deviation"]
    lines = [
        "c1 within "
        + ("–" if deviation is None else f"{100 * deviation:.3g} %")
        + f" of the sample truth over the check range (≤ {100 * c1['tolerance']:g} % + "
        f"{c1['z']:.3g}σ per bin): "
        + ("PASS" if c1["passed"] else "FAIL"),
    ]
    if "relative_to_exact_rung" in eps:
        lines.append(
            f"plateau epsilon {100 * eps['relative_to_exact_rung']:+.3g} % from the true "
            f"positions of the same snapshots (≤ {100 * eps['tolerance']:.3g} %, "
            f"{'paired' if eps['paired'] else 'unpaired'}): "
            + ("PASS" if eps["passed"] else "FAIL")
        )
    else:
        relative = eps["relative_to_exact_d_ll"]
        tolerance = "–" if eps["tolerance"] is None else f"{100 * eps['tolerance']:.3g} %"
        lines.append(
            "plateau epsilon "
            + ("–" if relative is None else f"{100 * relative:+.3g} %")
            + f" from the estimator on the exact D_LL (≤ {tolerance}): "
            + ("PASS" if eps["passed"] else "FAIL")
        )
    up = statistics.get("u_prime")
    if up is not None:
        lines.append(
            f"u' {100 * up['relative_to_exact_rung']:+.3g} % from the true positions of the "
            f"same snapshots (≤ {100 * up['tolerance']:.3g} %): "
            + ("PASS" if up["passed"] else "FAIL")
        )
    effective = statistics.get("effective_snapshots")
    if effective is not None and effective < MIN_SNAPSHOTS_FOR_VERDICT:
        lines.append(
            f"too few snapshots for a verdict with power: {snapshots} per dt "
            f"({effective:.3g} effective), so each check allows {c1['z']:.3g} standard errors "
            f"per bin at 0.1 % false alarms; score at least {MIN_SNAPSHOTS_FOR_VERDICT} "
            "(docs/score.md §6)"
        )
    return lines


def _print(result: dict, out: Path) -> None:
    """The score in a few lines."""
    print(
        f"{'dt (ms)':>8s} {'frames':>6s} {'reference':>9s} {'positions':>9s} {'yield':>7s} "
        f"{'ghosts':>7s}  RMS x, y, z (um)"
    )
    for label, s in [(f"{1e3 * s['dt_s']:8.4f}", s) for s in result["per_dt"]] + [
        (f"{'total':>8s}", result)
    ]:
        rms = ", ".join("–" if v is None else f"{v:.3g}" for v in s["position_rms_um"].values())
        print(
            f"{label} {s['frames']:6d} {s['n_reference']:9d} {s['n_found']:9d} "
            f"{s['yield']:7.4f} {s['ghost_fraction']:7.4f}  {rms}"
        )
    tracks = result["tracks"]
    if tracks is not None:
        print(
            f"links: {tracks['links']}, correct {tracks['correct']}, wrong {tracks['wrong']}; "
            f"broken {tracks['broken']} of {tracks['found_in_both']} particles found in both frames"
        )
    r = result["reconstruction"]
    rms = "–" if r["rms_um"] is None else f"{r['rms_um']:.3g} um ({r['rms_px']:.3g} px)"
    print(
        f"as the LPT Challenge scores it (whole volume, {r['exposures']} exposures, "
        f"{r['ppp']:.3g} particles per pixel): found {r['found']:.4f} of {r['particles']}, "
        f"ghosts {r['ghosts']:.4f} of {r['points']}, rms {rms}; by depth and by image "
        "overlap in score.json"
    )
    statistics = result["statistics"]
    if statistics["computed"]:
        for line in _statistics_lines(statistics, result["snapshots_per_dt"]):
            print(line)
    else:
        print(statistics["reason"])
    print(f"report written to {out / 'report.html'}")


def run_score(args: argparse.Namespace) -> int:
    """``synptv score`` (module docstring)."""
    from validation.report.score_report import write_report

    if isinstance(args.tracks, str):
        if args.positions is not None:
            raise ValueError("--tracks CSV scores a recording's tracks: leave out --positions")
        return run_track_score(args)
    if args.positions is None:
        raise ValueError("--positions is required (or --tracks CSV, for a recording's tracks)")
    out = check_output_folder(args.out)
    result, errors = score(args)
    with hold_output_folder(out, "synptv score") as took_over:
        if took_over:
            print(f"synptv score: {took_over}", file=sys.stderr)
        with staged_output(out) as staging:
            write_report(staging, result, errors)
    if args.json:
        json.dump(result, sys.stdout, indent=2, allow_nan=False)
        print()
    else:
        _print(result, out)
    return 0


def score_recorded_tracks(args: argparse.Namespace) -> dict:
    """The scores of a tracks CSV against a rendered recording's true trajectories
    (:mod:`validation.score.trajectories`); raises ValueError on bad input."""
    from validation.run.experiment import object_pixel
    from validation.score.recorded_tracks import align_tracks, alignment_dict, true_trajectories
    from validation.score.track_file import read_tracks
    from validation.score.trajectories import trajectory_scores
    from validation.truth.recording_truth import read_recording_truth

    folder = Path(args.dataset)
    if not folder.is_dir():
        raise ValueError(f"--dataset {folder}: no such folder")
    if (folder / "sequence0").is_dir():  # the recordings of validation.run.render_recording
        raise ValueError(
            f"--dataset {folder}: a recorded dataset; name one of its recordings, e.g. "
            f"{folder / 'sequence0'}"
        )
    truth = read_recording_truth(folder)
    cameras = len(truth.visible)
    if not 1 <= args.min_cameras <= cameras:
        raise ValueError(
            f"--min-cameras {args.min_cameras}: must be 1 to the recording's {cameras} cameras"
        )
    tracks = read_tracks(args.tracks)
    frames = len(truth.times)
    outside = (tracks.frame < 0) | (tracks.frame >= frames)
    if outside.any():
        raise ValueError(
            f"{args.tracks}: frame {int(tracks.frame[outside][0])} is outside the recording's "
            f"frames 0 … {frames - 1}"
        )
    radius = object_pixel(truth.rig) if args.voxel is None else args.voxel
    moved, rotation, translation = align_tracks(tracks, truth)
    return as_json(
        {
            **trajectory_scores(true_trajectories(truth, args.min_cameras), moved, radius),
            "alignment": alignment_dict(rotation, translation),
            "settings": {
                "dataset": str(folder),
                "tracks": str(args.tracks),
                "radius_m": radius,
                "min_cameras": args.min_cameras,
                "rows": len(tracks.frame),
            },
        }
    )


def _print_track_scores(result: dict, out: Path) -> None:
    """The scores of a recording's tracks in a few lines."""

    def shown(value, scale=1.0, unit=""):
        return "–" if value is None else f"{value * scale:.4g}{unit}"

    lengths = result["lengths"]
    print(
        f"tracks {result['tracks']}, true trajectories {result['trajectories']}, "
        f"observed particle-frames {result['observed_particle_frames']}"
    )
    print(
        f"tracked {shown(result['tracked'], 100, ' %')}, fragmentation "
        f"{shown(result['fragmentation'])} segments per trajectory, mislinks "
        f"{shown(result['mislinks'], 100, ' %')} (avoidable "
        f"{shown(result['avoidable_mislinks'], 100, ' %')}), ghost tracks "
        f"{shown(result['ghost_tracks'], 100, ' %')}, ghost links "
        f"{shown(result['ghost_links'], 100, ' %')}"
    )
    print(
        f"mean length: tracks {shown(lengths['tracks']['mean'])} points, trajectories "
        f"{shown(lengths['trajectories']['mean'])} frames"
    )
    for key, value in result["errors"].items():
        if value is not None:
            print(f"rms error {key}: " + ", ".join(f"{a} {v:.3g}" for a, v in value.items()))
    print(f"report written to {out / 'score.json'} and {out / 'track_lengths.png'}")


def run_track_score(args: argparse.Namespace) -> int:
    """``synptv score --tracks CSV`` on a rendered recording: score.json and the
    track-length figure; everything is read and checked before the folder is made."""
    from validation.report.png import save_figure
    from validation.report.track_score_figures import track_lengths_figure

    out = check_output_folder(args.out)
    result = score_recorded_tracks(args)
    with hold_output_folder(out, "synptv score") as took_over:
        if took_over:
            print(f"synptv score: {took_over}", file=sys.stderr)
        with staged_output(out) as staging:
            (staging / "score.json").write_text(json.dumps(result, indent=2, allow_nan=False))
            title = f"tracks {Path(args.tracks).name} against recording {Path(args.dataset).name}"
            save_figure(track_lengths_figure(result, title), staging / "track_lengths.png")
    if args.json:
        json.dump(result, sys.stdout, indent=2, allow_nan=False)
        print()
    else:
        _print_track_scores(result, out)
    return 0
