"""`fmm campaign TABLE`: many sessions under conditions a lab chooses, run on Dask and compared.

TABLE (CSV or YAML, see `fmm_ros.campaign.table`) lists the sessions and their conditions.
Each session is analysed, fitted (with the normal force of its row) and optionally diagnosed
as `fmm report` would, as one task of a Dask graph: on local worker processes by default, on
an existing cluster with --scheduler, or in this process with --serial. Results are cached
per session (a hash of its data and the settings), so a rerun computes only what changed.
Then mu is compared across conditions with a random-effects model (`fmm_ros.campaign.compare`).
Writes DIR/index.html (figures beside it), the tidy tables as CSV and Parquet, and
DIR/campaign.json. Exit status: 0 every session fitted, 1 some session gave no mu (the
others are still compared), 2 bad input or flags.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import signal
import sys
from pathlib import Path

from fmm_ros.cli import options
from fmm_ros.errors import BadInputError
from fmm_ros.report.settings import PageSettings

EPILOG = """\
table (CSV; YAML takes the same columns as a list under `sessions:`, plus by/trend/mapping):
  session,id,lubricant,normal_force_n,date,operator,notes
  bags/a1,A1,PTFE-A,6.67,2026-11-02,kb,
  csv/b1,B1,PTFE-B,9.81,2026-11-03,tz,new counterface

  `session` is a bag, a lab file (one impact, or with --continuous a recording), a folder of
  them or a glob (relative to the table); `mapping` a mapping file for its lab files;
  `normal_force_n` (and mass_kg, stiffness_n_per_m, damping_n_s_per_m) set the rig of that
  session's fit; any other column is a condition.

a cluster: `dask scheduler` on one machine (it prints tcp://HOST:8786), `dask worker
tcp://HOST:8786 --nworkers N --nthreads 1` on each machine with the same fmm_ros and access
to the session files and the cache folder at the same paths; then --scheduler tcp://HOST:8786.
"""


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the `campaign` subcommand."""
    parser = subparsers.add_parser(
        'campaign',
        help='compare mu across many sessions and conditions (lubricants, loads, dates)',
        description='Analyse, fit and diagnose every session of a campaign '
        'table as Dask tasks, cached per session, then compare mu across conditions with a '
        'random-effects model: mu by condition with 95 % intervals, pairwise differences '
        '(Holm-adjusted), trends against numeric or date columns, and the verdict in words. '
        'Writes an HTML report, tidy CSV and Parquet tables and JSON.',
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument('table', type=Path, metavar='TABLE', help='campaign table (.csv, .yaml)')
    options.add_output(
        parser,
        'where the report, tables and JSON go (default: TABLE_STEM_results beside TABLE)',
        metavar='DIR',
    )
    parser.add_argument(
        '--by',
        type=_names,
        metavar='COLUMN[,COLUMN]',
        help='the condition columns compared (default: the YAML by:, else every column but '
        'dates and the reserved session, id, mapping, notes)',
    )
    parser.add_argument(
        '--trend',
        type=_names,
        metavar='COLUMN[,COLUMN]',
        help='numeric or date columns to regress mu on (default: the YAML trend:, else none)',
    )
    where = parser.add_mutually_exclusive_group()
    where.add_argument(
        '--scheduler',
        metavar='ADDRESS',
        help='an existing dask.distributed scheduler (tcp://host:8786) to run the sessions on',
    )
    where.add_argument(
        '--serial',
        action='store_true',
        help='run the sessions one after the other in this process (no Dask)',
    )
    parser.add_argument(
        '--workers',
        type=int,
        metavar='N',
        help='local worker processes (default: one a core)',
    )
    cache = parser.add_mutually_exclusive_group()
    cache.add_argument(
        '--cache',
        type=Path,
        metavar='DIR',
        help='per-session result cache (default: DIR/cache of the output)',
    )
    cache.add_argument('--no-cache', action='store_true', help='compute every session anew')
    parser.add_argument(
        '--diagnose',
        action=argparse.BooleanOptionalAction,
        default=True,
        help="run the discrepancy workflow on each session too: the missing effects, mu's "
        "drift, the friction map (default; it adds to each session's time)",
    )
    options.add_model(parser)
    options.add_setting(
        parser, PageSettings, 'title', default='', help="report title ('': the table's)"
    )
    options.add_setting(parser, PageSettings, 'dpi')
    options.add_json(parser, 'the campaign (also written as DIR/campaign.json)')
    options.add_quiet(parser)
    options.add_hit_selection(parser, fits=True)
    options.add_frf_options(parser)
    options.add_lab_file_reading(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run, compare and write the campaign; print the verdict (or the JSON)."""
    from fmm_ros.campaign.report import write_campaign_report
    from fmm_ros.campaign.results import run_campaign, to_json, write_json, write_tables
    from fmm_ros.campaign.table import read_campaign_table
    from fmm_ros.campaign.tasks import SERIAL
    from fmm_ros.cli.progress import progress_bar
    from fmm_ros.workflows.session import SessionOptions

    if args.dpi <= 0:
        raise BadInputError(f'--dpi must be positive, got {args.dpi:g}')
    table = read_campaign_table(args.table, options.rig_from_args(args))
    capture, analysis = options.analysis_configs(args)
    session_options = SessionOptions(
        inputs=options.input_options(args, capture),
        analysis=analysis,
        model=options.fit_options(args),
        diagnose=args.diagnose,
        include_flagged=args.include_flagged,
    )
    output = args.output or args.table.with_name(f'{args.table.stem}_results')
    cache = None if args.no_cache else (args.cache or output / 'cache')
    failures = 0
    with (
        _stop_on_sigterm(),
        progress_bar(len(table.sessions), desc='sessions', unit='session', quiet=args.quiet) as bar,
    ):

        def done(_index: int, result) -> None:
            nonlocal failures
            failures += not result.ok
            bar.update(1)
            if failures:
                bar.set_postfix(failed=failures)

        campaign = run_campaign(
            table,
            session_options,
            by=args.by,
            trend=args.trend,
            scheduler=SERIAL if args.serial else args.scheduler,
            workers=args.workers,
            cache_dir=cache,
            on_result=done,
        )
    write_tables(campaign, output)
    write_json(campaign, output / 'campaign.json')
    page = write_campaign_report(campaign, output, title=args.title, dpi=args.dpi)
    if args.json:
        print(json.dumps(to_json(campaign), indent=1, allow_nan=False))
    else:
        print(text_report(campaign))
        print(f'\nwrote {page}, the tables (CSV, Parquet) and campaign.json in {output}')
    for session, reason in campaign.failed:
        print(f'fmm campaign: session {session}: {reason}', file=sys.stderr)
    return 1 if campaign.failed else 0


@contextlib.contextmanager
def _stop_on_sigterm():
    """SIGTERM (a process manager, a batch system) ends the run as Ctrl-C does.

    Python's default would kill the process where it stands; as an exception it unwinds, so
    the local cluster's worker processes are stopped and finished sessions stay cached.
    """

    def stop(signum, _frame):
        raise SystemExit(128 + signum)

    previous = signal.signal(signal.SIGTERM, stop)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def text_report(campaign) -> str:
    """Sessions with their mu, then the verdict, the notes and the failures."""
    from fmm_ros.campaign.table import format_value
    from fmm_ros.core.results_schema import format_with_uncertainty

    names = [column.name for column in campaign.table.columns]
    header = f'{"session":<20} ' + ' '.join(f'{n[:14]:<14}' for n in names)
    lines = [f'{header} {"hits":>7}  mu']
    for session, result in zip(campaign.table.sessions, campaign.results, strict=True):
        values = ' '.join(f'{format_value(session.conditions[n])[:14]:<14}' for n in names)
        hits = f'{result.accepted_hits}/{len(result.hits)}'
        mu = (
            format_with_uncertainty(result.mu, result.mu_stderr)
            if result.ok and math.isfinite(result.mu)
            else f'- ({result.status})'
        )
        cached = '  (cached)' if result.cached else ''
        lines.append(f'{session.session_id[:20]:<20} {values} {hits:>7}  {mu}{cached}')
    comparison = campaign.comparison
    lines += ['', f'compared by {", ".join(campaign.by)}:']
    lines += [f'- {verdict}' for verdict in comparison.verdicts]
    lines += [f'  note: {note}' for note in comparison.notes]
    return '\n'.join(lines)


def _names(text: str) -> tuple[str, ...]:
    """A comma-separated list of column names."""
    names = tuple(name.strip() for name in text.split(',') if name.strip())
    if not names:
        raise argparse.ArgumentTypeError('expected COLUMN[,COLUMN...]')
    return names
