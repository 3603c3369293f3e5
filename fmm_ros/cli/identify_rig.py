"""`fmm identify-rig`: m, c, k of the flexure with the friction contact lifted (paper Sec. 4).

Files with a hit are impacts: m, c and k are fitted to them together, the measured force
driving m x'' + c x' + k x = f. Files without a hit are free decays (an electromagnet release,
say): f_n and zeta are fitted, and k and c follow from --mass-kg. Bags give their recorded
impacts. Exit status: 0 identified, 1 the records are not the frictionless rig's (reason
printed) or a bag was damaged (warnings), 2 bad input or flags.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from fmm_ros.cli import options
from fmm_ros.core.physics.rig import Rig
from fmm_ros.core.results_schema import ASCII_PM
from fmm_ros.core.results_schema import format_with_uncertainty as pm

if TYPE_CHECKING:
    from fmm_ros.core.identify.rig import RigIdentification


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the `identify-rig` subcommand."""
    parser = subparsers.add_parser(
        'identify-rig',
        help='mass, damping and stiffness of the rig from mu = 0 records',
        description='Identify m, c, k (and f_n, zeta) of the rig with the friction contact '
        'lifted: from impacts (lab files with a hit, or bags) by output error with the '
        'measured force driving the model, or from free decays (files without a hit) with '
        'the mass given.',
    )
    options.add_inputs(parser, what='record')
    options.add_json(parser)
    options.add_quiet(parser)
    options.add_setting(
        parser,
        Rig,
        'mass_kg',
        help='moving mass m for free decays, which cannot tell it; impacts measure it',
    )
    options.add_whole_record(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Read the inputs, identify, print the constants (or why there are none)."""
    if args.whole_record:
        from fmm_ros.cli import whole_record

        return whole_record.run(args, 'identify-rig')
    from fmm_ros.cli._fitting import FitRequest, fit_and_report
    from fmm_ros.core.identify.rig import identify_rig

    return fit_and_report(
        FitRequest.from_args('identify-rig', args),
        lambda records, ids, _: identify_rig([records[i] for i in ids], mass_kg=args.mass_kg),
        report,
        text_report,
    )


def report(result: RigIdentification) -> dict:
    """The JSON document (`workflows.results.rig_identification_dict`)."""
    from fmm_ros.workflows.results import rig_identification_dict

    return rig_identification_dict(result)


def text_report(result: RigIdentification) -> str:
    """The constants with their errors, how they were found, and any free-decay check."""
    given = result.method == 'free_decay'
    mass = '(given: a free decay cannot tell the mass)' if given else ''
    mass_kg = result.mass_kg if given else pm(result.mass_kg, result.mass_stderr_kg, ASCII_PM)
    lines = [
        f'm   = {mass_kg:.5g} kg {mass}' if given else f'm   = {mass_kg} kg',
        f'k   = {pm(result.stiffness_n_per_m, result.stiffness_stderr_n_per_m, ASCII_PM)} N/m',
        f'c   = {pm(result.damping_n_s_per_m, result.damping_stderr_n_s_per_m, ASCII_PM)} N*s/m',
        f'f_n = '
        f'{pm(result.natural_frequency_hz, result.natural_frequency_stderr_hz, ASCII_PM)} Hz, '
        f'zeta = {pm(100 * result.damping_ratio, 100 * result.damping_ratio_stderr, ASCII_PM)} %',
        f'from {len(result.sources)} '
        f'{"free decay" if given else "impact"}{"s" if len(result.sources) > 1 else ""}; '
        f'residual {result.residual_rms_m_s:.3e} m/s RMS = '
        f'{100 * result.normalised_residual:.3f} % of the peak velocity',
    ]
    if not given and result.free_decays:
        lines.append('free decays (check):')
        lines += [
            f'  {Path(decay.source).name}: f_n = {decay.natural_frequency_hz:.6g} Hz, '
            f'zeta = {100 * decay.damping_ratio:.4f} %'
            for decay in result.free_decays
        ]
    return '\n'.join(lines)
