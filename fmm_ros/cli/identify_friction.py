"""`fmm identify-friction FILE`: mass and friction of a positioning axis without a spring.

One record of the drive force and the motion (position, velocity or acceleration), open or
closed loop, gives the moving mass, viscous and Coulomb friction (also per direction), the
offset and a friction map over speed, by inverse dynamics least squares
(`fmm_ros.core.identify.axis`). A record that model does not describe (a mass not positive, a
relative error of tens of percent) is not reported as an identification: `fits_record` is
false and `why` says what is wrong; an imposed-motion friction test is then fitted without
inertia (per-direction Coulomb, the friction loop and the energy per cycle). A voltage without
a scale is analysed in volts (every figure per V). Exit status: 0 identified (either model),
1 neither model describes the record, 2 bad input.
"""

import argparse
import json
import sys

from fmm_ros.cli import options
from fmm_ros.core.identify.spec import AxisSpec

MOTION_FLAGS = (
    ('position', 'position channel (encoder) [m unless --motion-unit]'),
    ('velocity', 'velocity channel [m/s unless --motion-unit]'),
    ('acceleration', 'acceleration channel [m/s^2 unless --motion-unit]'),
)


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the `identify-friction` subcommand."""
    parser = subparsers.add_parser(
        'identify-friction',
        help='mass, viscous and Coulomb friction of a positioning axis (no spring)',
        description='Identify M, Fv, Fc (each direction too) and the force offset of a one-axis '
        'drive from one record of its force and motion, by inverse dynamics least squares '
        'with zero-phase differentiation and parallel filtering.',
    )
    parser.add_argument('file', help='lab file (CSV, NPZ, .mat, TDMS) with force and motion')
    parser.add_argument('--force', required=True, metavar='NAME', help='drive force channel')
    parser.add_argument(
        '--force-unit',
        help='unit of the force channel (default N); V without --force-scale: analysed in V',
    )
    parser.add_argument(
        '--force-scale',
        metavar='S',
        help='N per file unit of the force (a drive gain in N/V for a voltage): a number or the '
        'name of a scalar variable in the file',
    )
    motion = parser.add_mutually_exclusive_group(required=True)
    for kind, text in MOTION_FLAGS:
        motion.add_argument(f'--{kind}', metavar='NAME', help=text)
    parser.add_argument(
        '--motion-unit', help='unit of the motion channel (m, mm, m/s, g, ...; V: analysed in V)'
    )
    parser.add_argument('--time', metavar='NAME', help='time channel [s] (default: t, time)')
    parser.add_argument('--sample-rate-hz', type=float, help='sample rate, when no time channel')
    options.add_setting(parser, AxisSpec, 'stiffness_n_per_m')
    options.add_setting(parser, AxisSpec, 'cutoff_hz')
    options.add_json(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Read the record, identify the axis, print JSON or a short text."""
    from fmm_ros.workflows.axis import axis_json, identify_axis_file, read_axis_record

    kind = next(k for k, _ in MOTION_FLAGS if getattr(args, k))
    spec = AxisSpec(stiffness_n_per_m=args.stiffness_n_per_m, cutoff_hz=args.cutoff_hz)
    record = read_axis_record(
        args.file,
        force=args.force,
        motion=getattr(args, kind),
        motion_kind=kind,
        time=args.time,
        sample_rate_hz=args.sample_rate_hz,
        force_unit=args.force_unit,
        motion_unit=args.motion_unit,
        force_scale=args.force_scale,
    )
    document = axis_json(identify_axis_file(record, spec), record, spec)
    if args.json:
        json.dump(document, sys.stdout, indent=2)
        print()
    else:
        print(text_report(document))
    return 0 if document['model'] else 1


def text_report(document: dict) -> str:
    """A few lines a person reads: each parameter with its standard error."""
    # label, key, the key of its unit in document['units']
    rows = [
        ('mass', 'mass_kg', 'mass_kg'),
        ('viscous friction', 'viscous_n_s_per_m', 'viscous_n_s_per_m'),
        ('Coulomb friction', 'coulomb_n', 'coulomb_n'),
        ('offset', 'offset_n', 'offset_n'),
        ('Coulomb, moving +', 'coulomb_positive_n', 'coulomb_n'),
        ('Coulomb, moving -', 'coulomb_negative_n', 'coulomb_n'),
        ('viscous, moving +', 'viscous_positive_n_s_per_m', 'viscous_n_s_per_m'),
        ('viscous, moving -', 'viscous_negative_n_s_per_m', 'viscous_n_s_per_m'),
    ]
    units = document['units']
    lines = [f'{document["file"]}: {document["samples_used"]} samples used']
    if not document['fits_record']:
        lines.append(f'  does not fit the record: {document["why"]}')
        imposed = document['imposed_motion']
        if imposed:
            lines.append('  imposed-motion friction (no inertia), on the sliding part:')
            for label, key, unit in rows[4:]:
                lines.append(
                    f'  {label:<18} {imposed[key]:>11.4g} ± {imposed[key + "_stderr"]:.2g} '
                    f'{units[unit]}'
                )
            lines.append(
                f'  moving - exceeds moving + by {100 * imposed["coulomb_asymmetry"]:.1f} %; '
                f'energy per cycle {imposed["energy_per_cycle_mean_j"]:.4g} '
                f'{units["energy_per_cycle_j"]} over {len(imposed["energy_per_cycle_j"])} cycles'
            )
        return '\n'.join(lines)
    for label, key, unit in rows:
        if document.get(key) is not None:
            lines.append(
                f'  {label:<18} {document[key]:>11.4g} ± {document[key + "_stderr"]:.2g} '
                f'{units[unit]}'
            )
    lines.append(
        f'  relative error {100 * document["relative_error"]:.2f} %, '
        f'velocity noise {document["velocity_noise_m_s"] or 0:.2g} {units["velocity"]}'
    )
    return '\n'.join(lines)
