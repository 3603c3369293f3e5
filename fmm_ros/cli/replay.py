"""`fmm replay BAG`: a recorded session through the analyzer's core, as fast as it goes, no ROS.

Each recorded batch is fed to the same capture, in the recorded order, and each completed
record to the same analysis as the live analyzer node, so what is printed is what the node
would have published on /fmm/impacts and /fmm/frf for that session.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from fmm_ros.cli import options


def register(subparsers) -> None:
    """Add the replay subcommand."""
    parser = subparsers.add_parser(
        'replay',
        help='feed a bag through the analyzer core as fast as possible (no ROS)',
        description='Replay a session bag through the impact capture and analysis the live '
        'analyzer runs, batch by batch in recorded order, and print what it would '
        'publish: every impact (level, verdict, flags, impulse, peak force, peak '
        'receptance), the level averages and the linearity fit, and how much '
        'faster than real time it ran. Exit status 1 when the bag is damaged.',
    )
    parser.add_argument('bag', type=Path, help='bag directory, or a .mcap / .db3 file')
    options.add_analysis(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Replay, then print the analyzer's output and the replay speed."""
    from fmm_ros.cli.formats import analysis_text
    from fmm_ros.cli.progress import progress_bar, report_problems
    from fmm_ros.io.frf_files import level_curves, write_frfs
    from fmm_ros.workflows.replay import replay_bag

    capture, analysis = options.analysis_configs(args)
    start = time.perf_counter()
    with progress_bar(None, desc='replaying', unit='batch', quiet=args.quiet) as bar:

        def opened(total: int) -> None:  # the bag's batch count, once it is open
            bar.total = total
            bar.refresh()

        replay = replay_bag(
            args.bag,
            capture,
            analysis,
            on_progress=bar.update,
            on_open=opened,
            level_tolerance_n=options.recorded_level_tolerance(args),
        )
    wall_s = time.perf_counter() - start
    for path in args.output:
        write_frfs(path, level_curves(replay.summary))
    speed = replay.signal_s / wall_s if wall_s > 0 else float('inf')
    if args.json:
        from fmm_ros.workflows.results import analysis_dict  # scipy.signal: only for --json

        document = analysis_dict(replay.summary)
        document['replay'] = {
            'bag': str(args.bag),
            'signal_s': replay.signal_s,
            'batches': replay.batches,
            'wall_s': wall_s,
            'times_real_time': speed,
            'problems': replay.problems,
            'ledger': {name: ledger.to_dict() for name, ledger in replay.ledger.items()},
        }
        print(json.dumps(document, indent=2, allow_nan=False))
    else:
        print(analysis_text(replay.summary))
        print(
            f'\nreplayed {replay.signal_s:.1f} s of signal ({replay.batches} batches) in '
            f'{wall_s:.2f} s: {speed:.0f}x real time'
        )
        for ledger in replay.ledger.values():
            print(f'stream: {ledger.summary()}')
    return report_problems('replay', replay.problems)
