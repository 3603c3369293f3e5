"""`fmm bag-info BAG`: topics, counts, duration, sample rate and gaps of a session bag."""

from __future__ import annotations

import argparse
import json

from fmm_ros.cli import options


def register(subparsers) -> None:
    """Add the bag-info subcommand."""
    parser = subparsers.add_parser(
        'bag-info',
        help='what a bag holds: topics, duration, sample rate, gaps, damage',
        description='Read a whole rosbag2 bag (MCAP or sqlite3, also an unfinished or damaged '
        'one) and report its topics, message counts, duration, sample channels '
        'with rate and gaps, and recorded impacts. Exit status 1 when the bag is '
        'damaged or was not closed.',
    )
    parser.add_argument('bag', help='bag directory, or a .mcap / .db3 file')
    options.add_json(parser, 'one object')
    options.add_quiet(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Summarize the bag and print it."""
    from fmm_ros.cli.progress import progress_bar, report_problems
    from fmm_ros.io.bags import BagReader
    from fmm_ros.io.bags.summary import format_summary, summarize_bag

    with BagReader(args.bag, strict=False) as reader:
        total = sum(info.count for info in reader.topics.values())
        with progress_bar(total, desc='reading', unit='msg', quiet=args.quiet) as bar:
            summary = summarize_bag(reader, on_progress=bar.update)
    if args.json:
        print(json.dumps(summary.to_dict(), indent=2))
        return 1 if summary.problems else 0
    print(format_summary(summary))
    return report_problems('bag-info', summary.problems)
