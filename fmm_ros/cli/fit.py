"""`fmm fit`: the best-fit friction coefficient (and damping) of impacts from lab files or bags.

The paper's Sec. 5 step: Eq. 3 driven by each impact's measured force, mu chosen so the
simulated velocity matches the measured one, one mu for all impacts and each one's own mu
beside it. Inputs are read as `fmm analyze` reads them (a lab file is one impact, a bag gives
every impact its recorded streams hold); only the hits the quality flags accept are fitted,
the others named (--include-flagged fits them too). Exit status: 0 fitted, 1 the records
cannot be explained by friction or none is clean (the reason is printed, as JSON with
--json) or a bag was damaged (its problems are printed as warnings after the result), 2 bad
input or flags.
"""

from __future__ import annotations

import argparse

from fmm_ros.cli import options
from fmm_ros.core.identify.spec import FitSpec


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the `fit` subcommand."""
    parser = subparsers.add_parser(
        'fit',
        help='best-fit friction coefficient (and damping) from lab files or bags',
        description="Fit mu (and with --fit-damping c) of m x'' + c x' + k x + mu N sgn(x') = "
        "f(t), driven by each impact's measured force, to the measured velocity: "
        "one mu for all impacts, and each impact's own mu. Inputs: lab files of one "
        'impact each (CSV time_s,force_n,velocity_m_s, or as fmm import reads them) or '
        'bags (every impact recorded). Rig flags default to the FMM.',
    )
    options.add_inputs(parser)
    options.add_json(parser)
    options.add_model(parser)
    group = parser.add_argument_group('the fit')
    options.add_setting(
        group,
        FitSpec,
        'misfit',
        help='time: velocity residual; frf: mobility residual up to --misfit-band-limit-hz',
    )
    options.add_setting(group, FitSpec, 'band_limit_hz', flag='--misfit-band-limit-hz')
    options.add_range_setting(group, FitSpec, 'mu_bounds', ('--mu-min', '--mu-max'))
    options.add_hit_selection(parser, fits=True)
    options.add_quiet(parser)
    options.add_whole_record(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Read the inputs, fit, print the result (or why there is none)."""
    if args.whole_record:
        from fmm_ros.cli import whole_record

        return whole_record.run(args, 'fit')
    from fmm_ros.cli._fitting import FitRequest, fit_and_report
    from fmm_ros.cli.formats import friction_text
    from fmm_ros.workflows.results import FrictionResult
    from fmm_ros.workflows.session import fit_impacts

    fit = options.fit_options(args)
    return fit_and_report(
        FitRequest.from_args('fit', args),
        lambda records, ids, progress: fit_impacts(records, ids, fit, progress=progress),
        FrictionResult.to_dict,
        friction_text,
    )
