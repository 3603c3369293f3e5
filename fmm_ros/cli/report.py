"""`fmm report`: the HTML page and PNG figures of a session, or of the paper's simulations.

`fmm report INPUT... --out DIR` analyses the impacts exactly as `fmm analyze` does (same
options), fits mu over the accepted ones as `fmm fit` does, and writes DIR/index.html with
every figure embedded plus DIR/<figure>.png.
`fmm report --paper --out DIR` reproduces the paper's Figs. 2-10 from the physics core.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from fmm_ros.cli._model import add_fit_freedom_arguments, add_rig_arguments, rig_from_args
from fmm_ros.cli.analyze import (
    add_analysis_options,
    add_selection_argument,
    analysis_configs,
    read_records,
)
from fmm_ros.cli.progress import report_problems
from fmm_ros.report import report_session
from fmm_ros.report.paper import build_paper_report
from fmm_ros.report.plotting import DEFAULT_DPI


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the `report` subcommand."""
    parser = subparsers.add_parser(
        'report',
        help='HTML page and PNG figures of a session (or of the paper)',
        description='Write DIR/index.html (figures embedded, every hit in a table with its '
        'quality flags) and each figure as DIR/<name>.png: force pulses and '
        'velocity decays, mobility and receptance per level with trials and mean, '
        'levels compared, odd harmonics of f_n, impulses, and the linearity of '
        'peak receptance in impulse. mu is fitted over the accepted hits (as fmm '
        'fit does) and the fitted model (Eq. 3) driven by each measured force is '
        "drawn over the measurement. --paper draws the paper's Figs. 2-10 from the "
        'physics core instead.',
    )
    parser.add_argument(
        'inputs',
        nargs='*',
        type=Path,
        metavar='INPUT',
        help='one CSV file per impact (time_s,force_n,velocity_m_s), or a bag '
        '(directory, .mcap or .db3) whose every impact is reported',
    )
    parser.add_argument(
        '--out',
        type=Path,
        required=True,
        metavar='DIR',
        help='directory for index.html and the PNG files (created)',
    )
    parser.add_argument(
        '--paper',
        action='store_true',
        help="reproduce the paper's simulation figures (Figs. 2-10); no INPUT",
    )
    model = parser.add_mutually_exclusive_group()
    model.add_argument(
        '--mu',
        type=float,
        default=None,
        help='draw the model with this friction coefficient instead of fitting',
    )
    model.add_argument('--no-fit', action='store_true', help='neither fit mu nor draw a model')
    add_fit_freedom_arguments(parser)
    parser.add_argument(
        '--diagnose',
        action='store_true',
        help='also run the discrepancy workflow (fmm diagnose) over the '
        'accepted hits: the missing effect, the gap before and after',
    )
    add_rig_arguments(parser)
    add_selection_argument(parser)
    parser.add_argument('--title', default='Impact session report', help='page title')
    parser.add_argument(
        '--dpi',
        type=float,
        default=DEFAULT_DPI,
        help=f'PNG resolution [dots per inch] (default {DEFAULT_DPI:g})',
    )
    add_analysis_options(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Write the page and print where it is; 1 if a bag was damaged or a fit was refused."""
    if args.dpi <= 0:
        raise ValueError(f'--dpi must be positive, got {args.dpi:g}')
    if args.paper:
        if args.inputs:
            raise ValueError('--paper draws the simulations of the paper and takes no INPUT')
        print(
            f'wrote {build_paper_report(args.out, dpi=args.dpi)} (figures embedded, and as '
            'PNG files beside it)'
        )
        return 0
    if not args.inputs:
        raise ValueError('give the impact files or bags to report on, or --paper')
    capture, analysis = analysis_configs(args)
    records, problems = read_records(
        args.inputs, args.force_full_scale_n, args.velocity_full_scale_m_s, capture
    )
    result = report_session(
        records,
        args.out,
        capture=capture,
        analysis=analysis,
        rig=rig_from_args(args),
        mu=args.mu,
        fit=not args.no_fit,
        fit_damping=args.fit_damping,
        fit_initial_position=args.fit_initial_position,
        diagnose=args.diagnose,
        include_flagged=args.include_flagged,
        title=args.title,
        inputs=[str(path) for path in args.inputs],
        problems=problems,
        dpi=args.dpi,
    )
    failures = [
        f'cannot {what}: {why}'
        for what, why in (('fit mu', result.fit_failure), ('diagnose', result.diagnosis_failure))
        if why
    ]
    for failure in failures:
        print(f'fmm report: {failure}', file=sys.stderr)
    print(f'wrote {result.page} (figures embedded, and as PNG files beside it)')
    return max(report_problems('report', problems), 1 if failures else 0)
