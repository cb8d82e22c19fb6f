"""``synptv convert``: another PTV code's output as the files ``synptv score`` reads.

Everything is read and checked before the output is written (the dataset's
experiment.json, every input file and row): bad input is a one-line error naming the
file, the line and the field, exit status 2, nothing written. The output file is written
under a temporary name and renamed into place (docs/benchmark-your-code.md).
"""

import argparse
from pathlib import Path

from validation.commands.common import UsageError

#: The codes ``--from`` knows: what ``--input`` is for each.
SOURCES = {
    "openptv": "the folder of OpenPTV's rt_is.<number> (and ptv_is.<number>) files, its res/",
    "myptv": "MyPTV's particles file, or its trajectory file (raw or smoothed)",
}


def add_convert_parser(sub) -> None:
    """The ``synptv convert`` subcommand."""
    convert = sub.add_parser(
        "convert",
        help="turn OpenPTV's or MyPTV's output into the positions or tracks file synptv "
        "score reads",
        description="Convert the 3-D particles (and links) another PTV code wrote for a "
        "dataset exported by synptv export into the files synptv score reads, in metres "
        "in the dataset's world frame: for frame pairs the positions file "
        "(dt,snapshot,frame,x,y,z, with a track column where the code linked frame a to "
        "frame b: --out); for a time-resolved recording the tracks file "
        "(track,frame,x,y,z: --tracks). The dataset's experiment.json maps the code's "
        "frame numbers back, as the export numbered them. Inputs: "
        + "; ".join(f"{k}: {v}" for k, v in SOURCES.items())
        + ". See docs/benchmark-your-code.md.",
    )
    convert.add_argument(
        "--from", dest="source", required=True, choices=sorted(SOURCES), help="the code"
    )
    convert.add_argument(
        "--input",
        required=True,
        nargs="+",
        action="extend",
        metavar="PATH",
        help="the code's output, one per dt in the order dt0, dt1, … (frame pairs; fewer "
        "leave the last dt out), or one for a recording",
    )
    convert.add_argument(
        "--dataset",
        required=True,
        help="the dataset the export came from (a recording: DIR/sequence<s>)",
    )
    convert.add_argument("--out", help="positions CSV to write (frame pairs)")
    convert.add_argument("--tracks", help="tracks CSV to write (a time-resolved recording)")
    convert.set_defaults(run=run_convert)


def _output(path: str, option: str) -> Path:
    """``path`` as a file that can be written (its folder made once all is checked)."""
    out = Path(path)
    if out.is_dir():
        raise UsageError(f"{option} {out} is a folder, not a file")
    existing = out.parent
    while not existing.exists() and existing.parent != existing:
        existing = existing.parent
    if not existing.is_dir():
        raise UsageError(f"{option} {out} lies under {existing}, which is a file")
    return out


def convert(source: str, inputs: list[str], dataset: str) -> tuple[str, str, dict]:
    """The file ``synptv score`` reads of a code's output on ``dataset``.

    Parameters
    ----------
    source : str
        A key of :data:`SOURCES`.
    inputs : list of str
        The code's output: one per Δt in order (frame pairs), or one (a recording).
    dataset : str
        The dataset folder (a recording: its ``sequence<s>`` folder).

    Returns
    -------
    (str, str, dict)
        ``"positions"`` or ``"tracks"`` (which file it is), its CSV text, and a summary
        (:func:`validation.convert.points.positions_csv`,
        :func:`~validation.convert.points.tracks_csv`).

    Raises
    ------
    ValueError
        Bad input: one line naming the file, the line and the field.
    """
    from validation.convert import myptv, openptv
    from validation.convert.points import positions_csv, read_frames, tracks_csv

    readers = {
        "openptv": (openptv.read_openptv, openptv.NUMBERING),
        "myptv": (myptv.read_myptv, myptv.NUMBERING),
    }
    if source not in readers:
        raise UsageError(f"--from {source!r}: one of {', '.join(sorted(readers))}")
    read, numbering = readers[source]
    frames = read_frames(dataset)
    points = [read(path) for path in inputs]
    if frames.recording:
        return ("tracks", *tracks_csv(points, frames, numbering))
    return ("positions", *positions_csv(points, frames, numbering))


def run_convert(args: argparse.Namespace) -> int:
    """``synptv convert`` (module docstring)."""
    from validation.convert.points import read_frames
    from validation.workflow.files import write_text_atomic

    if (args.out is None) == (args.tracks is None):
        raise UsageError(
            "give --out positions.csv (a dataset of frame pairs) or --tracks tracks.csv "
            "(a time-resolved recording)"
        )
    frames = read_frames(args.dataset)
    if frames.recording and args.out is not None:
        raise UsageError(
            f"--dataset {args.dataset} is a time-resolved recording, scored by its tracks: "
            "write them with --tracks tracks.csv"
        )
    if not frames.recording and args.tracks is not None:
        raise UsageError(
            f"--dataset {args.dataset} holds frame pairs: write --out positions.csv (the "
            "a → b links go in its track column; synptv score --positions FILE --tracks)"
        )
    option, path = ("--tracks", args.tracks) if frames.recording else ("--out", args.out)
    out = _output(path, option)
    kind, text, summary = convert(args.source, args.input, args.dataset)
    out.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(out, text)
    if kind == "tracks":
        print(
            f"{args.source} → {out}: {summary['points']} points in {summary['frames']} frames, "
            f"{summary['tracks']} tracks ({summary['linked_tracks']} of two points or more)"
        )
        print(f"score them: synptv score --dataset {args.dataset} --tracks {out}")
        return 0
    links = summary["links"]
    print(
        f"{args.source} → {out}: {summary['positions']} positions in {summary['frames']} "
        f"frames of dt {', '.join(map(str, summary['dt']))}; "
        + ("no links (no track column)" if links is None else f"{links} a → b links (track column)")
    )
    print(
        f"score them: synptv score --dataset {args.dataset} --positions {out}"
        + ("" if links is None else " --tracks")
    )
    return 0
