"""`fmm --help` and `fmm SUBCOMMAND --help`: how long a user waits, against `python -c pass`.

Run: .venv/bin/python benchmarks/bench_cli.py [--quick] [--repeats R]

Each command runs as a fresh process (the `fmm` console script beside this Python), as a
user starts it; the figure is the median wall time of R runs. The baseline, in the same run,
is the bare interpreter (`python -c pass`): what no Python command can beat; beside it, the
eager way: `fmm --help` after importing what the commands import to run (numpy,
scipy, numba, matplotlib, the bag reader, the workflows, campaigns), as a CLI does whose
parsers are not declared apart from their work. The parsers
import no numerics (numpy, scipy, numba, matplotlib, rclpy; `test_cli_startup` holds that),
so the target is an answer within 0.3 s.
--quick: three runs of `fmm --help` and two subcommands, nothing written. A full run writes
its section of benchmarks/RESULTS.md.
"""

import argparse
import statistics
import subprocess
import sys
import time
from pathlib import Path

from results_file import write_section

from fmm_ros.cli import build_parser

TARGET_S = 0.3
# What the commands import to run: the eager way imports all of it first.
EAGER = (
    'fmm_ros.workflows.session',
    'fmm_ros.workflows.replay',
    'fmm_ros.report.session',
    'fmm_ros.io.bags',
    'fmm_ros.io.labfiles',
    'fmm_ros.campaign.results',
    'fmm_ros.campaign.report',
)
FMM = Path(sys.executable).with_name('fmm')


def wall_s(command: list[str], repeats: int) -> float:
    """Median wall time of running command repeats times [s] (output discarded)."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        subprocess.run(command, check=True, stdout=subprocess.DEVNULL)
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> None:
    """Time the bare interpreter, `fmm --help` and each subcommand's --help; print the ratios."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--quick', action='store_true', help='a few runs, write nothing')
    parser.add_argument('--repeats', type=int, default=None, help='runs per command')
    args = parser.parse_args()
    repeats = args.repeats or (3 if args.quick else 15)
    # What the console script runs, where it is not installed (a source tree on PYTHONPATH).
    script = 'import sys; from fmm_ros.cli import main; sys.exit(main())'
    fmm = [str(FMM)] if FMM.exists() else [sys.executable, '-c', script]
    names = list(build_parser()._subparsers._group_actions[0].choices)
    commands = {'fmm --help': [*fmm, '--help']}
    for name in names[:2] if args.quick else names:
        commands[f'fmm {name} --help'] = [*fmm, name, '--help']
    baseline = wall_s([sys.executable, '-c', 'pass'], repeats)
    rows = [f'| `python -c pass` (baseline) | {baseline * 1e3:.0f} | 1.0 |']
    eager = 'import sys; ' + ''.join(f'import {name}; ' for name in EAGER) + script
    before = wall_s([sys.executable, '-c', eager, '--help'], max(2, repeats // 5))
    rows.append(
        f"| `fmm --help` the way before (every command's imports first) | "
        f'{before * 1e3:.0f} | {before / baseline:.1f} |'
    )
    worst = 0.0
    for label, command in commands.items():
        seconds = wall_s(command, repeats)
        worst = max(worst, seconds)
        rows.append(f'| `{label}` | {seconds * 1e3:.0f} | {seconds / baseline:.1f} |')
    verdict = 'met' if worst <= TARGET_S else 'MISSED'
    body = '\n'.join(
        [
            f'Median wall time of {repeats} fresh processes each; target <= {TARGET_S} s '
            f'for every command: {verdict} (slowest {worst * 1e3:.0f} ms).',
            '',
            '| command | ms | x `python -c pass` |',
            '|---|---:|---:|',
            *rows,
        ]
    )
    print(body)
    write_section('bench_cli', body, quick=args.quick)


if __name__ == '__main__':
    main()
