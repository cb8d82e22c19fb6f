"""What every ``synptv`` subcommand shares: the bad-input error, option types, the
parallel options and the line of a stale lock taken over."""

import argparse
import sys

from validation.run.scenario import SIZE_LIMITS


class UsageError(ValueError):
    """Bad command-line input; reported in one line with exit status 2."""


def integer_at_least(minimum: int, maximum: int | None = None, why: str = ""):
    """An argparse type: an integer from ``minimum`` (to ``maximum``), else an error
    naming the option and the limit."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be an integer, got {text!r}") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"must be an integer >= {minimum}, got {value}")
        if maximum is not None and value > maximum:
            raise argparse.ArgumentTypeError(f"must be at most {maximum}{why}, got {value}")
        return value

    return parse


def size(name: str):
    """An argparse type for the size ``name`` of :data:`SIZE_LIMITS`."""
    return integer_at_least(*SIZE_LIMITS[name])


SEED = integer_at_least(0)
COUNT = integer_at_least(1)


def add_parallel_options(parser: argparse.ArgumentParser) -> None:
    """--workers and --scheduler, exclusive."""
    where = parser.add_mutually_exclusive_group()
    where.add_argument(
        "--workers",
        type=int,
        help="local Dask worker processes (default: one per CPU; 1: this process only)",
    )
    where.add_argument(
        "--scheduler", metavar="ADDRESS", help="a running Dask scheduler, e.g. tcp://host:8786"
    )


def say_took_over(command: str, note: str | None) -> None:
    """Print the line of a stale lock taken over, if any."""
    if note:
        print(f"synptv {command}: {note}", file=sys.stderr)
