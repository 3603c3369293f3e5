"""`fmm report`: the HTML page and PNG figures of a session, or of the paper's simulations.

`fmm report INPUT... --out DIR` analyses the impacts exactly as `fmm analyze` does (same
options) and writes DIR/index.html with every figure embedded plus DIR/<figure>.png.
`fmm report --paper --out DIR` reproduces the paper's Figs. 2-10 from the physics core.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from fmm_ros.cli.analyze import add_analysis_options, analysis_configs, read_records
from fmm_ros.cli.progress import report_problems
from fmm_ros.core.model import FMM_RIG, Rig
from fmm_ros.report import ModelOverlay, build_report
from fmm_ros.report.paper import build_paper_report
from fmm_ros.report.plotting import DEFAULT_DPI


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the `report` subcommand."""
    parser = subparsers.add_parser(
        'report', help='HTML page and PNG figures of a session (or of the paper)',
        description='Write DIR/index.html (figures embedded, every hit in a table with its '
                    'quality flags) and each figure as DIR/<name>.png: force pulses and '
                    'velocity decays, mobility and receptance per level with trials and mean, '
                    'levels compared, odd harmonics of f_n, impulses, and the linearity of '
                    'peak receptance in impulse. With --mu the model (Eq. 3) driven by each '
                    "measured force is drawn over the measurement. --paper draws the paper's "
                    'Figs. 2-10 from the physics core instead.')
    parser.add_argument('inputs', nargs='*', type=Path, metavar='INPUT',
                        help='one CSV file per impact (time_s,force_n,velocity_m_s), or a bag '
                             '(directory, .mcap or .db3) whose every impact is reported')
    parser.add_argument('--out', type=Path, required=True, metavar='DIR',
                        help='directory for index.html and the PNG files (created)')
    parser.add_argument('--paper', action='store_true',
                        help="reproduce the paper's simulation figures (Figs. 2-10); no INPUT")
    parser.add_argument('--mu', type=float, default=None,
                        help='friction coefficient of the model drawn over the measurement '
                             '(default: no model overlay)')
    rig = FMM_RIG
    parser.add_argument('--mass-kg', type=float, default=rig.mass_kg,
                        help=f'model mass [kg] (default {rig.mass_kg:g}, the FMM)')
    parser.add_argument('--stiffness-n-per-m', type=float, default=rig.stiffness_n_per_m,
                        help=f'model stiffness [N/m] (default {rig.stiffness_n_per_m:g})')
    parser.add_argument('--damping-n-s-per-m', type=float, default=rig.damping_n_s_per_m,
                        help=f'model viscous damping [N*s/m] (default {rig.damping_n_s_per_m:g})')
    parser.add_argument('--normal-force-n', type=float, default=rig.normal_force_n,
                        help=f'model normal force [N] (default {rig.normal_force_n:.4g})')
    parser.add_argument('--title', default='Impact session report', help='page title')
    parser.add_argument('--dpi', type=float, default=DEFAULT_DPI,
                        help=f'PNG resolution [dots per inch] (default {DEFAULT_DPI:g})')
    add_analysis_options(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Write the page and print where it is; exit status 1 if a bag was damaged."""
    if args.dpi <= 0:
        raise ValueError(f'--dpi must be positive, got {args.dpi:g}')
    problems: list[str] = []
    if args.paper:
        if args.inputs:
            raise ValueError('--paper draws the simulations of the paper and takes no INPUT')
        page = build_paper_report(args.out, dpi=args.dpi)
    elif not args.inputs:
        raise ValueError('give the impact files or bags to report on, or --paper')
    else:
        capture, analysis = analysis_configs(args)
        records, problems = read_records(args.inputs, args.force_full_scale_n,
                                         args.velocity_full_scale_m_s, capture)
        model = None
        if args.mu is not None:
            model = ModelOverlay(args.mu, 'given', Rig(
                args.mass_kg, args.stiffness_n_per_m, args.damping_n_s_per_m,
                args.normal_force_n))
        page = build_report(records, args.out, capture=capture, analysis=analysis,
                            model=model, title=args.title,
                            inputs=[str(path) for path in args.inputs], problems=problems,
                            dpi=args.dpi)
    print(f'wrote {page} (figures embedded, and as PNG files beside it)')
    return report_problems('report', problems)
