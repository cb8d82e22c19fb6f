"""``synptv calibrate``: a dataset's cameras from its plate images, dot lists or a 3-D
target of listed points (docs/calibration.md §10)."""

import argparse
import json
import sys
from pathlib import Path

from ptv.calibration.plate_offsets import MODES as PLATE_OFFSET_MODES
from validation.commands.common import UsageError, say_took_over
from validation.workflow.files import check_output_folder, hold_output_folder, write_json_atomic
from validation.workflow.progress import ProgressBar

#: The methods ``synptv calibrate`` fits to a plate when --methods is not given.
PLATE_METHODS = "model-free,tsai,pinhole,soloff"


def run_calibrate(args: argparse.Namespace) -> int:
    from ptv.io.experiment_file import has_point_target, read_experiment
    from validation.dataset.calibrate import calibrate_dataset, check_methods
    from validation.report.calibration_figures import plate_offsets_figure
    from validation.report.png import save_figure

    given = PLATE_METHODS if args.methods is None else args.methods
    methods = [m.strip() for m in given.split(",") if m.strip()]
    check_methods(methods)
    dataset = Path(args.dataset)
    if not dataset.is_dir():
        raise UsageError(f"--dataset {dataset}: no such folder")
    out = check_output_folder(args.out if args.out is not None else dataset / "calibrations")
    try:
        point_target = has_point_target(read_experiment(dataset, needs=("calibration",)))
    except FileNotFoundError as err:
        raise UsageError(str(err)) from None
    if point_target:
        if args.plate_offsets is not None:
            raise UsageError(
                f"--plate-offsets: {dataset / 'experiment.json'} gives a target of listed "
                "points, not a plate on a traverse"
            )
        return _calibrate_point_target(args, dataset, out)
    bar = ProgressBar("calibrate", enabled=not args.quiet)
    with hold_output_folder(out, "synptv calibrate") as took_over:
        say_took_over("calibrate", took_over)
        try:
            result = calibrate_dataset(
                dataset,
                methods=methods,
                out=out,
                plate_offsets=args.plate_offsets,
                progress=bar,
            )
        except FileNotFoundError as err:
            raise UsageError(str(err)) from None
        if result.plate_offsets is not None:
            summary = result.plate_offsets.summary()
            offsets_json = write_json_atomic(out / "plate_offsets.json", summary)
            save_figure(plate_offsets_figure(result.plate_offsets), out / "plate_offsets.png")
    for line in result.warnings:
        print(f"synptv calibrate: warning: {line}", file=sys.stderr)
    if args.json:
        json.dump(
            {
                "table1": result.table1,
                "leave_one_plane_out": result.leave_one_plane_out,
                "files": result.files,
                "max_plane_residual_px": result.max_plane_residual_px,
                "per_image": result.per_image,
                "plate_offsets": (
                    None if result.plate_offsets is None else result.plate_offsets.summary()
                ),
                "warnings": result.warnings,
            },
            sys.stdout,
            indent=2,
        )
        print()
        return 0
    print(
        "largest plane-fit residual (model-free T_j^-1), px: "
        + ", ".join(f"{k} {v:.3f}" for k, v in result.max_plane_residual_px.items())
    )
    print(f"{'method':12s} {'reference':9s} {'d_X':>7s} {'d_Y':>7s} {'d_Z':>7s} {'d':>7s}  (um)")
    for method, refs in result.table1.items():
        for ref, t in refs.items():
            print(
                f"{method:12s} {ref:9s} {t['d_X_um']:7.2f} {t['d_Y_um']:7.2f} "
                f"{t['d_Z_um']:7.2f} {t['d_um']:7.2f}"
            )
    _print_per_image(result.per_image, list(result.table1))
    for method, held in result.leave_one_plane_out.items():
        planes = ", ".join(f"{d:.1f}" for d in held["planes_d_um"])
        print(f"{method:12s} leave-one-plane-out d {held['d_um']:.2f} um (per plane {planes})")
    if result.plate_offsets is not None:
        _print_plate_offsets(result.plate_offsets, offsets_json)
    for method, path in result.files.items():
        print(f"{method} calibration written to {path}")
    return 0


def _print_per_image(per_image: dict, methods: list[str]) -> None:
    """Per plate image: its dots found and each method's reprojection RMS, px."""
    width = max(len(row["image"]) for rows in per_image.values() for row in rows)
    print("per plate image: dots found and each method's reprojection RMS (px)")
    print(
        f"{'camera':12s} {'image':{width}s} {'Z (mm)':>8s} {'dots':>5s} "
        + " ".join(f"{m:>10s}" for m in methods)
    )
    for camera, rows in per_image.items():
        for row in rows:
            print(
                f"{camera:12s} {row['image']:{width}s} {1e3 * row['z_m']:8.3f} "
                f"{row['dots']:5d} " + " ".join(f"{row['rms_px'][m]:10.3f}" for m in methods)
            )


def _print_plate_offsets(offsets, path: Path) -> None:
    """The self-calibrated plate's figures, one line each."""
    summary = offsets.summary()
    rms, largest = summary["rms_offset_um"], summary["max_abs_offset_um"]
    residual = summary["map_residual_rms_um"]
    print(
        f"plate offsets ({offsets.mode}): dX rms {rms[0]:.1f} um (max {largest[0]:.1f}), "
        f"dY rms {rms[1]:.1f} um (max {largest[1]:.1f}); plane-map residual "
        f"{residual['nominal']:.1f} -> {residual['corrected']:.1f} um; in {path} "
        "and plate_offsets.png"
    )


def _calibrate_point_target(args: argparse.Namespace, dataset: Path, out: Path) -> int:
    """``synptv calibrate`` on a dataset whose target is a 3-D target of listed points."""
    from validation.dataset.calibrate import POINT_TARGET_METHOD, calibrate_point_dataset

    if args.methods is not None and args.methods.strip() != POINT_TARGET_METHOD:
        raise UsageError(
            f"--methods {args.methods}: {dataset / 'experiment.json'} gives a target of "
            f"listed points, imaged once per camera, which calibrates with "
            f"{POINT_TARGET_METHOD} only"
        )
    bar = ProgressBar("calibrate", enabled=not args.quiet)
    with hold_output_folder(out, "synptv calibrate") as took_over:
        say_took_over("calibrate", took_over)
        try:
            result = calibrate_point_dataset(dataset, out=out, progress=bar)
        except FileNotFoundError as err:
            raise UsageError(str(err)) from None
    summary = result.as_dict()
    for line in result.warnings:
        print(f"synptv calibrate: warning: {line}", file=sys.stderr)
    if args.json:
        json.dump(summary, sys.stdout, indent=2)
        print()
        return 0
    print(
        f"{'camera':12s} {'points':>6s} {'blobs':>6s} {'seeds':>5s} {'rms (px)':>8s}  "
        "model (f_x, f_y; c_x, c_y px)"
    )
    for name, cam in summary["cameras"].items():
        (fx, fy), (cx, cy) = cam["focal_px"], cam["principal_point_px"]
        print(
            f"{name:12s} {cam['points']:6d} {cam['blobs']:6d} {cam['seeds']:5d} "
            f"{cam['rms_px']:8.3f}  {cam['model']} ({fx:.0f}, {fy:.0f}; {cx:.0f}, {cy:.0f})"
            + (", behind its window" if "window" in cam else "")
        )
    t = summary["target_points"]
    print(
        f"target points seen by two or more cameras, triangulated back: {t['points']}; "
        f"d_X {t['d_X_um']:.1f}, d_Y {t['d_Y_um']:.1f}, d_Z {t['d_Z_um']:.1f}, "
        f"d {t['d_um']:.1f} um"
    )
    for method, path in summary["files"].items():
        print(f"{method} calibration written to {path}")
    return 0


def add_calibrate_parser(sub) -> None:
    """The ``synptv calibrate`` subcommand."""
    cal = sub.add_parser(
        "calibrate",
        help="calibrate a dataset's cameras from its plate images (or dot lists); print the "
        "Table 1 metric",
        description="Find and index the dots on every plate image of a dataset folder (or "
        "read the dot lists its experiment.json names instead), "
        "calibrate each camera with each method, write one calibration file per method "
        "and print the paper's Table 1 metric (against the nominal dot positions, and "
        "against the true centres when the folder holds truth.h5). A dataset whose target "
        "is a 3-D target of listed points (one image per camera) gets one pinhole per "
        "camera (fitted through the camera's glass wall when experiment.json gives its "
        "window), its reprojection RMS and the target points triangulated back.",
    )
    cal.add_argument("--dataset", required=True, help="folder written by synptv render")
    cal.add_argument(
        "--methods",
        help=f"comma-separated: model-free, tsai, pinhole, soloff (default {PLATE_METHODS}; "
        "pinhole only for a point target)",
    )
    cal.add_argument(
        "--out", help="folder for the calibration files (default DATASET/calibrations)"
    )
    cal.add_argument(
        "--plate-offsets",
        choices=PLATE_OFFSET_MODES,
        help="self-calibrate the plate: estimate each column's and row's (or each dot's) "
        "offset from the nominal grid with the calibration, fit every method on the "
        "corrected grid and add Table 1 against it (plate_offsets.json and .png in OUT)",
    )
    cal.add_argument("--json", action="store_true", help="print one JSON object")
    cal.add_argument("--quiet", action="store_true", help="no progress bar")
    cal.set_defaults(run=run_calibrate)
