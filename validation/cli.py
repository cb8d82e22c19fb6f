"""The ``synptv`` command line: the subcommands of :mod:`validation.commands`.

Errors in the user's input end the command with exit status 2 and a one-line message
on stderr; results go to stdout (``--json`` prints one JSON object).
"""

import argparse
import logging
import sys

from validation.commands.calibrate import add_calibrate_parser
from validation.commands.claims import add_claims_parser
from validation.commands.convert import add_convert_parser
from validation.commands.export import add_export_parser
from validation.commands.flow import add_flow_parser
from validation.commands.ptv import add_ptv_parser
from validation.commands.render import add_render_parser
from validation.commands.run import add_run_parser
from validation.commands.scene import add_scene_parser
from validation.commands.score import add_score_parser
from validation.commands.study import add_study_parser
from validation.workflow.compile_note import watch as watch_compiling
from validation.workflow.progress import say_interrupted


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line, exit status 2 (see :func:`main`)."""

    def error(self, message: str):
        raise _ParseError(f"{self.prog}: error: {message} (see {self.prog} -h)")


class _ParseError(Exception):
    """A bad command line, already worded for the user."""


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``synptv`` and its subcommands."""
    parser = _Parser(prog="synptv", description="A virtual 3D-PTV laboratory.")
    parser.add_argument(
        "-v", "--verbose", action="store_true", help="log the libraries' details and warnings"
    )
    sub = parser.add_subparsers(dest="command", required=True)
    for add in (
        add_run_parser,
        add_flow_parser,
        add_render_parser,
        add_calibrate_parser,
        add_study_parser,
        add_claims_parser,
        add_ptv_parser,
        add_score_parser,
        add_export_parser,
        add_convert_parser,
        add_scene_parser,
    ):
        add(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``synptv`` console script."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except _ParseError as err:
        print(err, file=sys.stderr)
        return 2
    logging.basicConfig(
        # The libraries' warnings are per snapshot or per chunk; each command sums them
        # up (summary.json, the report, its warning lines), so they show only with -v.
        level=logging.INFO if args.verbose else logging.ERROR,
        format="%(levelname)s %(name)s: %(message)s",
    )
    try:
        with watch_compiling(quiet=getattr(args, "quiet", False)):
            return args.run(args)
    except ValueError as err:  # bad input: one line, status 2
        print(f"synptv {args.command}: error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:  # run and study say what they keep and resume
        say_interrupted(f"synptv {args.command}: interrupted")
        return 130


if __name__ == "__main__":
    sys.exit(main())
