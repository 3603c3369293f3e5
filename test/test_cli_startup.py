"""`fmm --help` answers at once: the parsers import no numerics; `fmm replay` imports no more
than it runs.

Structural tests, not timed ones (benchmarks/bench_cli.py and bench_replay.py time them): a
fresh interpreter builds every subcommand's help, or replays a bag, and the modules it
imported are listed.
"""

import subprocess
import sys

import pytest

from fmm_ros.cli import SUBCOMMANDS, build_parser
from fmm_ros.sim.session import simulated_session, write_session_bag

HEAVY = ('numpy', 'scipy', 'numba', 'matplotlib', 'rclpy', 'dask', 'rosbags', 'pandas')

PROBE = """
import contextlib, io, sys
from fmm_ros.cli import main
for argv in {argvs!r}:
    with contextlib.redirect_stdout(io.StringIO()), contextlib.suppress(SystemExit):
        main(argv)
print(' '.join(sorted({{name.split('.')[0] for name in sys.modules}})))
"""


@pytest.mark.slow
def test_no_help_imports_numerics():
    subcommands = build_parser()._subparsers._group_actions[0].choices
    argvs = [['--help'], *([name, '--help'] for name in subcommands)]
    assert len(argvs) > 10
    imported = subprocess.run(
        [sys.executable, '-c', PROBE.format(argvs=argvs)],
        check=True,
        capture_output=True,
        text=True,
    ).stdout.split()
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


# What `fmm replay` of a clean bag must not import: ROS, the fitting and model numerics (the
# model terms among them), the report, and what only writing a bag or decoding a message needs
# (a typestore's standard types, the mcap writer).
NOT_FOR_REPLAY = (
    'rclpy',
    'fmm_interfaces',
    'scipy',
    'numba',
    'matplotlib',
    'fmm_ros.core.identify.friction',
    'fmm_ros.core.physics.terms',
    'fmm_ros.report',
    'rosbags.typesys.stores.ros2_jazzy',
    'mcap.writer',
)

REPLAY_PROBE = """
import contextlib, io, sys
from fmm_ros.cli import main
with contextlib.redirect_stdout(io.StringIO()):
    assert main(['replay', {bag!r}]) == 0
print(' '.join(sorted(sys.modules)))
"""


@pytest.mark.slow
def test_replay_of_a_clean_bag_imports_only_what_it_runs(tmp_path):
    bag = write_session_bag(tmp_path / 'session', simulated_session(1, spacing_s=6.0, seed=5))
    imported = subprocess.run(
        [sys.executable, '-c', REPLAY_PROBE.format(bag=str(bag))],
        check=True,
        capture_output=True,
        text=True,
    ).stdout.split()
    assert 'fmm_ros.io.bags.arrays' in imported  # read whole: the road measured
    assert [name for name in NOT_FOR_REPLAY if name in imported] == []
