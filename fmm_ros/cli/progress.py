"""Progress bars for long offline work: on a terminal only, and never with --quiet."""

import argparse
import sys
from typing import TextIO

from tqdm import tqdm


def add_quiet_flag(parser: argparse.ArgumentParser) -> None:
    """The --quiet flag every long-running subcommand takes."""
    parser.add_argument(
        '-q',
        '--quiet',
        action='store_true',
        help='no progress bar (there is none anyway when stderr is not a terminal)',
    )


def progress_bar(
    total: int | None, *, desc: str, unit: str, quiet: bool, stream: TextIO | None = None
) -> tqdm:
    """A tqdm bar on stream (stderr), disabled when quiet or when stream is not a TTY."""
    stream = stream or sys.stderr
    return tqdm(
        total=total,
        desc=desc,
        unit=unit,
        unit_scale=True,
        leave=False,
        file=stream,
        disable=quiet or not stream.isatty(),
        dynamic_ncols=True,
    )


def report_problems(command: str, problems: list[str]) -> int:
    """Print a bag's problems as warnings on stderr; the exit status: 1 if any, else 0."""
    for problem in problems:
        print(f'fmm {command}: warning: {problem}', file=sys.stderr)
    return 1 if problems else 0
