"""`fmm export BAG -o DIR`: a bag's impact results and level FRFs as CSV files."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from fmm_ros.constants import FRF_FORMATS, FRF_TOPIC, IMPACTS_TOPIC

if TYPE_CHECKING:
    from fmm_ros.io.bags import BagReader


def register(subparsers) -> None:
    """Add the export subcommand."""
    parser = subparsers.add_parser(
        'export',
        help='recorded impact results and level FRFs of a bag as CSV / UFF 58',
        description='Write impacts.csv (one row per recorded impact: impulse, peak force, '
        'level, flags, ...) with impact_<id>.csv (its mobility and receptance over '
        'frequency), and levels.csv with level_<name>.csv (mean mobility and '
        'receptance, H1, H2 and coherence of the newest summary of each level). '
        'FRF files can be UFF 58 or JSON instead.',
    )
    parser.add_argument('bag', help='bag directory, or a .mcap / .db3 file')
    parser.add_argument('-o', '--output', required=True, help='folder for the CSV files')
    parser.add_argument(
        '--frf-format',
        choices=FRF_FORMATS,
        default='csv',
        help='format of the FRF files: csv, uff (UFF 58, for modal software) or json (default csv)',
    )
    parser.add_argument('--impacts-topic', default=IMPACTS_TOPIC)
    parser.add_argument('--frf-topic', default=FRF_TOPIC)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Export what the bag recorded on the two result topics."""
    from fmm_ros.cli.progress import report_problems
    from fmm_ros.io.bags import FRF_SUMMARY, IMPACT_RESULT, BagReader
    from fmm_ros.io.bags.tables import export_results

    with BagReader(args.bag, strict=False) as reader:
        impacts_topic = _found(reader, args.impacts_topic, IMPACT_RESULT)
        frf_topic = _found(reader, args.frf_topic, FRF_SUMMARY)
        if impacts_topic is None and frf_topic is None:
            reader.find(args.impacts_topic, IMPACT_RESULT)  # raises, naming what it has
        impacts = list(reader.impacts(impacts_topic)) if impacts_topic else []
        summaries = list(reader.frf_summaries(frf_topic)) if frf_topic else []
        written = export_results(impacts, summaries, args.output, frf_format=args.frf_format)
        problems = reader.problems
    print(
        f'{len(impacts)} impacts, {len({s.level for s in summaries})} levels: wrote '
        f'{len(written)} files to {args.output}'
    )
    return report_problems('export', problems)


def _found(reader: BagReader, topic: str, msgtype: str) -> str | None:
    """The bag's name for topic (see BagReader.find), or None when it has none."""
    from fmm_ros.io.bags import MissingTopicError

    try:
        return reader.find(topic, msgtype)
    except MissingTopicError:
        return None
