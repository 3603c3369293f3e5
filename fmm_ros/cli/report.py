"""`fmm report`: the HTML page and PNG figures of a session, or of the paper's simulations.

`fmm report INPUT... -o DIR` reads the impacts as `fmm analyze` does (same options), fits mu
over the accepted ones as `fmm fit` does, optionally diagnoses them
(`fmm_ros.workflows.session.process_session`), and writes DIR/index.html with every figure
embedded plus DIR/<figure>.png (`fmm_ros.report.build_report`).
`fmm report --paper -o DIR` reproduces the paper's Figs. 2-10 from the physics core.
"""

from __future__ import annotations

import argparse
import sys

from fmm_ros.cli import options
from fmm_ros.errors import BadInputError
from fmm_ros.report.settings import PageSettings


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the `report` subcommand."""
    parser = subparsers.add_parser(
        'report',
        help='HTML page and PNG figures of a session (or of the paper)',
        description='Write DIR/index.html (figures embedded, every hit in a table with its '
        'quality flags) and each figure as DIR/<name>.png: force pulses and '
        'velocity decays, mobility and receptance per level with trials and mean (real and '
        'imaginary, magnitude and phase), coherence, levels compared, odd harmonics of f_n, '
        'impulses, and the linearity of peak receptance in impulse. mu is fitted over the '
        'accepted hits (as fmm fit does) and the fitted model (Eq. 3) driven by each '
        "measured force is drawn over the measurement. --paper draws the paper's Figs. 2-10 "
        'from the physics core instead.',
    )
    options.add_inputs(parser, nargs='*')
    options.add_output(
        parser,
        'directory for index.html and the PNG files (created)',
        metavar='DIR',
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
    parser.add_argument(
        '--diagnose',
        action='store_true',
        help='also run the discrepancy workflow (fmm diagnose) over the '
        'accepted hits: the missing effect, the gap before and after',
    )
    options.add_setting(parser, PageSettings, 'title')
    options.add_setting(parser, PageSettings, 'dpi')
    options.add_model(parser)
    options.add_hit_selection(parser, fits=True)
    options.add_frf_options(parser)
    options.add_quiet(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Write the page and print where it is; 1 if a bag was damaged or a fit was refused."""
    from fmm_ros.cli.progress import StatusLine, report_problems
    from fmm_ros.report import build_report  # matplotlib: only once the flags are good
    from fmm_ros.report.paper import build_paper_report
    from fmm_ros.workflows.session import SessionOptions, process_session

    dpi = args.dpi
    if dpi <= 0:
        raise BadInputError(f'--dpi must be positive, got {dpi:g}')
    if args.output is None:
        raise BadInputError('give the directory to write the report to with -o DIR')
    if args.paper:
        if args.inputs:
            raise BadInputError('--paper draws the simulations of the paper and takes no INPUT')
        print(
            f'wrote {build_paper_report(args.output, dpi=dpi)} (figures embedded, and as '
            'PNG files beside it)'
        )
        return 0
    if not args.inputs:
        raise BadInputError('give the impact files or bags to report on, or --paper')
    capture, analysis = options.analysis_configs(args)
    session_options = SessionOptions(
        inputs=options.input_options(args, capture),
        analysis=analysis,
        model=options.fit_options(args),
        mu=args.mu,
        fit=not args.no_fit,
        diagnose=args.diagnose,
        include_flagged=args.include_flagged,
    )
    with StatusLine(quiet=args.quiet) as progress:
        session = process_session(args.inputs, session_options, progress=progress)
        page = build_report(session, args.output, title=args.title, dpi=dpi, progress=progress)
    failures = [
        f'cannot {what}: {why}'
        for what, why in (('fit mu', session.fit_failure), ('diagnose', session.diagnosis_failure))
        if why
    ]
    for failure in failures:
        print(f'fmm report: {failure}', file=sys.stderr)
    print(f'wrote {page} (figures embedded, and as PNG files beside it)')
    return max(report_problems('report', session.problems), 1 if failures else 0)
