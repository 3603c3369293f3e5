"""`fmm fit`: the best-fit friction coefficient (and damping) of impacts from CSV files or bags.

The paper's Sec. 5 step: Eq. 3 driven by each impact's measured force, mu chosen so the
simulated velocity matches the measured one, one mu for all impacts and each one's own mu
beside it. Inputs are read as `fmm analyze` reads them (a CSV file is one impact, a bag gives
every impact its recorded streams hold); hits the quality flags reject are left out and named
(--include-flagged fits them too). Exit status: 0 fitted, 1 the records cannot be explained
by friction or none is clean (the reason is printed, as JSON with --json) or a bag was
damaged (its problems are printed as warnings after the result), 2 bad input or flags.
"""

import argparse
from pathlib import Path

from fmm_ros.cli._fitting import fit_and_report
from fmm_ros.cli._model import add_fit_freedom_arguments, add_rig_arguments, rig_from_args
from fmm_ros.cli.analyze import add_selection_argument
from fmm_ros.constants import MISFIT_BAND_LIMIT_HZ
from fmm_ros.core.identify.friction import MU_BOUNDS, FrictionFit, fit_friction
from fmm_ros.core.identify.output_error import MISFITS
from fmm_ros.io.frf_files import json_number


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the `fit` subcommand."""
    parser = subparsers.add_parser(
        'fit',
        help='best-fit friction coefficient (and damping) from impact CSV files or bags',
        description="Fit mu (and with --fit-damping c) of m x'' + c x' + k x + mu N sgn(x') = "
        "f(t), driven by each file's measured force, to the measured velocity: "
        "one mu for all impacts, and each impact's own mu. Inputs: CSV files of one "
        'impact each (header time_s,force_n,velocity_m_s) or bags (every impact '
        'recorded). Rig flags default to the FMM.',
    )
    parser.add_argument(
        'inputs',
        nargs='+',
        type=Path,
        metavar='INPUT',
        help='one CSV file per impact, or a bag (directory, .mcap or .db3)',
    )
    parser.add_argument('--json', action='store_true', help='print the result as JSON')
    add_selection_argument(parser)
    add_fit_freedom_arguments(parser)
    add_rig_arguments(parser)
    parser.add_argument(
        '--misfit',
        choices=MISFITS,
        default='time',
        help='time: velocity residual (default); frf: mobility residual up to --band-limit-hz',
    )
    parser.add_argument(
        '--band-limit-hz',
        type=float,
        default=MISFIT_BAND_LIMIT_HZ,
        help=f'top of the mobility misfit band [Hz] (default {MISFIT_BAND_LIMIT_HZ:g})',
    )
    parser.add_argument(
        '--mu-min',
        type=float,
        default=MU_BOUNDS[0],
        help=f'lower end of the mu search (default {MU_BOUNDS[0]:g})',
    )
    parser.add_argument(
        '--mu-max',
        type=float,
        default=MU_BOUNDS[1],
        help=f'upper end of the mu search (default {MU_BOUNDS[1]:g})',
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Read the inputs, fit, print the result (or why there is none)."""
    rig = rig_from_args(args)
    return fit_and_report(
        'fit',
        args,
        lambda records: fit_friction(
            records,
            rig=rig,
            fit_damping=args.fit_damping,
            fit_initial_position=args.fit_initial_position,
            mu_bounds=(args.mu_min, args.mu_max),
            misfit=args.misfit,
            band_limit_hz=args.band_limit_hz,
        ),
        report,
        text_report,
    )


def report(result: FrictionFit) -> dict:
    """The JSON document: the issue's keys, then standard errors and the consistency test."""
    joint = result.joint
    return {
        'mu': result.mu,
        'mu_stderr': result.mu_stderr,
        'damping_n_s_per_m': result.damping_n_s_per_m,
        'residual_rms_m_s': joint.residual_rms_m_s,
        'per_file': [
            {
                'file': source,
                'mu': single.mu,
                'impulse_n_s': impulse,
                'residual_rms_m_s': rms,
                'mu_stderr': single.mu_stderr,
                'normalised_residual': normalised,
                'initial_position_m': start,
            }
            for source, single, impulse, rms, normalised, start in zip(
                joint.sources,
                result.per_impact,
                result.impulses_n_s,
                joint.impact_residual_rms_m_s,
                joint.impact_normalised_residual,
                joint.initial_positions_m,
                strict=True,
            )
        ],
        'damping_stderr_n_s_per_m': json_number(result.damping_stderr_n_s_per_m),
        'damping_fitted': 'damping_n_s_per_m' in joint.names,
        'normalised_residual': joint.normalised_residual,
        'noise_std_m_s': joint.noise_std_m_s,
        'mu_consistency_chi2': result.consistency_chi2,
        'mu_consistency_p_value': json_number(result.consistency_p_value),
        'misfit': joint.misfit,
    }


def text_report(result: FrictionFit) -> str:
    """A few lines for a person: the common mu, c, the residual, then one line per impact."""
    joint = result.joint
    count = len(joint.sources)
    lines = [
        f'mu = {result.mu:.5f} +- {result.mu_stderr:.2g}  (one mu for {count} '
        f'impact{"s" if count > 1 else ""}, {joint.misfit} misfit)'
    ]
    if 'damping_n_s_per_m' in joint.names:
        lines.append(
            f'c  = {result.damping_n_s_per_m:.4f} +- '
            f'{result.damping_stderr_n_s_per_m:.2g} N*s/m (fitted)'
        )
    else:
        lines.append(f'c  = {result.damping_n_s_per_m:.4f} N*s/m (rig constant)')
    lines.append(
        f'residual {joint.residual_rms_m_s:.3e} m/s RMS = '
        f'{100 * joint.normalised_residual:.3f} % of the peak velocity '
        f'(velocity noise {joint.noise_std_m_s:.3e} m/s)'
    )
    if count > 1:
        verdict = (
            'serves all impacts'
            if result.consistency_p_value >= 0.01
            else 'does NOT serve all impacts'
        )
        lines.append(
            f'one mu {verdict}: chi^2 {result.consistency_chi2:.3g} over {count - 1} '
            f'degree{"s" if count > 2 else ""} of freedom, p = '
            f'{result.consistency_p_value:.3g}'
        )
    lines += [
        '',
        f'{"impact":<28} {"impulse N*s":>11} {"mu alone":>9} {"+-":>8} '
        f'{"residual m/s":>12}  (at the common mu)',
    ]
    for source, single, impulse, rms in zip(
        joint.sources,
        result.per_impact,
        result.impulses_n_s,
        joint.impact_residual_rms_m_s,
        strict=True,
    ):
        lines.append(
            f'{Path(source).name:<28.28} {impulse:>11.4f} {single.mu:>9.5f} '
            f'{single.mu_stderr:>8.2g} {rms:>12.3e}'
        )
    return '\n'.join(lines)
