"""`fmm --help` answers at once: the parsers import no numerics, and a command builds only its
own parser.

A structural test, not a timed one (benchmarks/bench_cli.py times it): a fresh interpreter
builds every subcommand's help and the modules it imported are listed.
"""

import pytest
from import_probe import modules_after

from fmm_ros.cli import SUBCOMMANDS, build_parser

HEAVY = ('numpy', 'scipy', 'numba', 'matplotlib', 'rclpy', 'dask', 'rosbags', 'pandas')

PROBE = """
import contextlib, io
from fmm_ros.cli import main
for argv in {argvs!r}:
    with contextlib.redirect_stdout(io.StringIO()), contextlib.suppress(SystemExit):
        main(argv)
"""


@pytest.mark.slow
def test_no_help_imports_numerics():
    subcommands = build_parser()._subparsers._group_actions[0].choices
    argvs = [['--help'], *([name, '--help'] for name in subcommands)]
    assert len(argvs) > 10
    imported = {name.split('.')[0] for name in modules_after(PROBE.format(argvs=argvs))}
    assert 'fmm_ros' in imported
    assert [name for name in HEAVY if name in imported] == []


def test_a_subcommand_alone_parses_as_in_the_full_parser():
    """`fmm COMMAND ...` builds only COMMAND's parser: the same parser as the full one has."""
    full = build_parser()._subparsers._group_actions[0].choices
    assert sorted(full) == sorted(SUBCOMMANDS)
    for command in SUBCOMMANDS:
        alone = build_parser(command)._subparsers._group_actions[0].choices
        assert list(alone) == [command]
        assert alone[command].format_help() == full[command].format_help()


@pytest.mark.slow
def test_a_replay_that_shows_no_progress_bar_imports_none(tmp_path):
    """`fmm replay BAG` with stderr not a terminal draws no bar, and imports no tqdm (nor the
    multiprocessing its lock would) to draw none."""
    import numpy as np

    from fmm_ros.io.bags import BagWriter

    bag = tmp_path / 'bag'
    with BagWriter(bag) as writer:
        writer.write_signals(np.zeros(20_000), np.zeros(20_000), 10_000.0)
    imported = modules_after(PROBE.format(argvs=[['replay', str(bag)]]))
    assert 'fmm_ros.workflows.replay' in imported
    assert [name for name in imported if name.split('.')[0] in ('tqdm', 'multiprocessing')] == []
