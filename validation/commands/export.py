"""``synptv export``: write a rendered dataset in the layout another PTV code reads.

The dataset is read and checked first (experiment.json, every image, truth.h5); the
export is then built under a temporary name beside ``--out`` and renamed into place
when complete, so bad input or a failure half-way leaves nothing behind (one-line
error, exit status 2).
"""

import argparse
import shutil
import sys
import tempfile
from pathlib import Path

from validation.workflow.files import check_output_folder, hold_new_folder

#: The layouts ``--format`` knows, each with what it is for.
FORMATS = {
    "openptv": "OpenPTV (liboptv, optv, pyptv): parameters/*.par, cal/, img/",
    "myptv": "MyPTV's workflow: params_file.yml, camera files, Calibration/, Images/",
    "openlpt": "OpenLPT 2.2.4: camFile/ (pinholes fitted to the plate dots), camFileTrue/ "
    "(the true cameras as polynomials), imgFile/ and image lists, config_dt<k>.txt, "
    "tracerConfig_dt<k>.txt, run_ipr.py",
}


def add_export_parser(sub) -> None:
    """The ``synptv export`` subcommand."""
    export = sub.add_parser(
        "export",
        help="write a rendered dataset in the layout OpenPTV, MyPTV or OpenLPT reads",
        description="Write a dataset rendered by synptv (plate images, particle images, "
        "the rig's cameras and windows) in the folder layout of another PTV code, with its "
        "parameter files, initial camera guesses (for OpenLPT its calibration from the "
        "plate dots and the true cameras) and a README.txt saying what each file is "
        "and which settings were guessed. A recorded dataset (synptv run's dataset folder "
        "of a [recording] scenario) exports to OpenPTV as one image sequence per "
        "recording. Formats: "
        + "; ".join(f"{k}: {v}" for k, v in FORMATS.items())
        + ". See docs/export.md.",
    )
    export.add_argument("--dataset", required=True, help="a dataset rendered by synptv")
    export.add_argument("--format", required=True, choices=sorted(FORMATS), help="the layout")
    export.add_argument("--out", required=True, help="new folder to write")
    export.set_defaults(run=run_export)


def export_dataset(dataset: str | Path, layout: str, out: str | Path) -> list[Path]:
    """Export ``dataset`` in the layout ``layout`` into the new folder ``out``.

    Parameters
    ----------
    dataset : path-like
        A folder written by ``synptv render``.
    layout : str
        A key of :data:`FORMATS`.
    out : path-like
        A folder that does not exist yet.

    Returns
    -------
    list of Path
        The files written, under ``out``.

    Raises
    ------
    ValueError
        Bad input (one line naming the file and the field), a recording asked of a
        layout that takes frame pairs only; nothing is written.
    """
    from validation.export.myptv import write_myptv
    from validation.export.openlpt import write_openlpt
    from validation.export.openptv import write_openptv
    from validation.export.source import read_source

    writers = {"openptv": write_openptv, "myptv": write_myptv, "openlpt": write_openlpt}
    if layout not in writers:
        raise ValueError(f"--format {layout!r}: one of {', '.join(sorted(writers))}")
    out = check_output_folder(out)
    if out.exists():
        raise ValueError(f"--out {out} already exists; choose a new folder")
    source = read_source(dataset)
    if source.recordings and layout != "openptv":
        raise ValueError(
            f"--dataset {source.folder}: a time-resolved recording; --format {layout} "
            "exports frame pairs only (export recordings with --format openptv)"
        )
    with hold_new_folder(out, "synptv export") as took_over:
        if took_over:
            print(f"synptv export: {took_over}", file=sys.stderr)
        staging = Path(tempfile.mkdtemp(prefix=f".{out.name}.partial-", dir=out.parent))
        try:
            written = writers[layout](source, staging / out.name)
            (staging / out.name).rename(out)
        finally:
            shutil.rmtree(staging, ignore_errors=True)
    return [out / path.relative_to(staging / out.name) for path in written]


def run_export(args: argparse.Namespace) -> int:
    """``synptv export`` (module docstring)."""
    written = export_dataset(args.dataset, args.format, args.out)
    print(f"{args.format} export of {args.dataset}: {len(written)} files in {args.out}")
    print(f"what each file is and what was guessed: {Path(args.out) / 'README.txt'}")
    return 0
