"""The `fmm` command: offline tools that run without a ROS runtime (and the demo that starts one).

Each subcommand lives in its own module here with `register(subparsers)`, which adds its
parser and sets `func(args) -> int` as the parser default.
"""

import argparse
import importlib
import os
import sys

from fmm_ros import __version__
from fmm_ros.core.memory import keep_freed_memory

# Each subcommand's name and its module, in the order `fmm --help` lists them.
SUBCOMMANDS: dict[str, str] = {
    'demo': 'demo',
    'simulate': 'simulate',
    'analyze': 'analyze',
    'report': 'report',
    'replay': 'replay',
    'record': 'record',
    'foxglove': 'foxglove',
    'import': 'import_lab',
    'bag-info': 'bag_info',
    'export': 'export',
    'fit': 'fit',
    'identify-rig': 'identify_rig',
    'identify-friction': 'identify_friction',
    'diagnose': 'diagnose',
    'campaign': 'campaign',
    'station': 'station',
    'env': 'env',
    'ros': 'ros',
}


class Parser(argparse.ArgumentParser):
    """An ArgumentParser that takes each option only as spelled in full.

    argparse otherwise takes any unambiguous prefix (`--out` for `--output`), so a removed
    spelling that is a prefix of a current one would be taken silently as that one, in its
    unit (`--force-full-scale` in file units as `--force-full-scale-n` in N). The subcommands'
    parsers are of this class too (add_subparsers makes them of the parent's).
    """

    def __init__(self, *args, **kwargs) -> None:
        kwargs.setdefault('allow_abbrev', False)
        super().__init__(*args, **kwargs)


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The `fmm` argument parser with every subcommand registered, or only command's.

    One subcommand's parser is all its command line needs: the other modules, their
    options and the settings they show, cost a tenth of a second of start-up unimported.
    """
    parser = Parser(
        prog='fmm',
        description='Impact-hammer FRF testing and friction identification on the friction '
        'measuring machine (Kossack, Ziegert, Schmitz, NAMRC 2019).',
    )
    parser.add_argument('--version', action='version', version=f'fmm_ros {__version__}')
    subparsers = parser.add_subparsers(dest='command', metavar='COMMAND')
    for module in SUBCOMMANDS.values() if command is None else (SUBCOMMANDS[command],):
        importlib.import_module(f'fmm_ros.cli.{module}').register(subparsers)
    return parser


# Exit status when the reader of stdout went away (`fmm ... | head`): that of a process ended
# by SIGPIPE, as other Unix tools end then.
CLOSED_PIPE_STATUS = 128 + 13


def main(argv: list[str] | None = None) -> int:
    """Entry point of `fmm`: parse, dispatch, and turn bad input into a one-line error."""
    argv = sys.argv[1:] if argv is None else argv
    parser = build_parser(argv[0] if argv and argv[0] in SUBCOMMANDS else None)
    args = parser.parse_args(argv)
    if not getattr(args, 'func', None):
        parser.print_help()
        return 2
    keep_freed_memory()  # a record's arrays reuse the last one's pages (fmm_ros.core.memory)
    try:
        status = args.func(args)
        sys.stdout.flush()  # here, so a closed pipe is caught below and not at exit
        return status
    except BrokenPipeError:
        # Point stdout at /dev/null, or Python's own flush at exit fails again and prints.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return CLOSED_PIPE_STATUS
    except (ValueError, FileNotFoundError) as error:
        print(f'fmm {args.command}: error: {error}', file=sys.stderr)
        return 2


if __name__ == '__main__':
    sys.exit(main())
