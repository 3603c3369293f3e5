"""`fmm import FILE... -o BAG`: lab measurements (CSV, NPZ, .mat, TDMS) into a session bag."""

import argparse
from datetime import datetime

from fmm_ros.cli.progress import add_quiet_flag, progress_bar
from fmm_ros.io.labfiles import (
    FORCE_UNITS,
    VELOCITY_UNITS,
    ImportMapping,
    load_mapping,
    open_lab_file,
    read_lab_files,
    write_recordings,
)

EPILOG = f"""\
force units: {', '.join(FORCE_UNITS)}; velocity units: {', '.join(VELOCITY_UNITS)}.
Any other unit (V, mV, counts) needs --force-scale / --velocity-scale in N or m/s per unit.

mapping file (flags override its entries):
  force:    {{name: Hammer, unit: lbf}}
  velocity: {{name: Vibrometer, unit: V, scale: 0.125}}   # 125 mm/s per V
  sample_rate_hz: 10000          # or a variable name, or leave out and give:
  time:     {{name: Time, unit: s}}
"""


def register(subparsers) -> None:
    """Add the import subcommand."""
    parser = subparsers.add_parser(
        'import',
        help='lab files (CSV, NPZ, MATLAB .mat, NI TDMS) into a session bag',
        description='Convert lab measurements to the session bag the recorder writes: force '
        'in N and velocity in m/s on one sample index, in 500-sample batches. '
        'Which channel is which, their units and the sample rate are stated, '
        'never guessed. Several files are joined in order.',
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument('files', nargs='+', help='.csv/.txt/.tsv, .npz, .mat, .tdms files')
    parser.add_argument('-o', '--output', help='bag directory to create')
    parser.add_argument(
        '--list', action='store_true', help='list the channels each file holds, and stop'
    )
    parser.add_argument('-m', '--mapping', help='YAML mapping file (see below)')
    for quantity in ('force', 'velocity'):
        parser.add_argument(
            f'--{quantity}',
            metavar='NAME',
            help=f'{quantity} column, variable (struct.field) or TDMS group/channel',
        )
        parser.add_argument(f'--{quantity}-unit', metavar='UNIT', help=f'unit of {quantity}')
        parser.add_argument(
            f'--{quantity}-scale',
            type=float,
            metavar='SI_PER_UNIT',
            help=f'SI units per file unit, for a sensor unit of {quantity}',
        )
        parser.add_argument(
            f'--{quantity}-full-scale',
            type=float,
            metavar='VALUE',
            help=f'sensor range of {quantity} in file units (clipping check)',
        )
    parser.add_argument(
        '--sample-rate-hz',
        metavar='HZ_OR_VARIABLE',
        help='sample rate, or the name of the variable holding it',
    )
    parser.add_argument('--time', metavar='NAME', help='a time column to take the rate from')
    parser.add_argument('--time-unit', default=None, metavar='UNIT', help='s, ms or us')
    parser.add_argument('--storage', choices=('mcap', 'sqlite3'), default='mcap')
    parser.add_argument('--batch-size', type=int, default=500, metavar='SAMPLES')
    parser.add_argument(
        '--start-time',
        metavar='ISO8601',
        help="acquisition time of the first sample (default: the file's own, "
        'else its modification time minus its duration)',
    )
    add_quiet_flag(parser)
    parser.set_defaults(func=run)


def mapping_from_args(args: argparse.Namespace) -> ImportMapping:
    """The mapping file's entries with the flags laid over them."""
    spec = load_mapping(args.mapping) if args.mapping else {}
    for quantity in ('force', 'velocity', 'time'):
        entry = spec.get(quantity)
        entry = {'name': entry} if isinstance(entry, str) else dict(entry or {})
        flags = {
            'name': getattr(args, quantity),
            'unit': getattr(args, f'{quantity}_unit'),
            'scale': getattr(args, f'{quantity}_scale', None),
            'full_scale': getattr(args, f'{quantity}_full_scale', None),
        }
        entry.update({key: value for key, value in flags.items() if value is not None})
        if entry:
            spec[quantity] = entry
    if args.sample_rate_hz is not None:
        try:
            spec['sample_rate_hz'] = float(args.sample_rate_hz)
        except ValueError:
            spec['sample_rate_hz'] = args.sample_rate_hz
    return ImportMapping.from_dict(spec)


def run(args: argparse.Namespace) -> int:
    """List the files' channels, or import them into a bag."""
    if args.list:
        for path in args.files:
            lab = open_lab_file(path)
            print(f'{path} ({lab.format}):')
            for name in lab.names():
                unit = lab.channel_unit(name)
                increment = lab.channel_increment_s(name)
                extra = ''.join(
                    [f' [{unit}]' if unit else '', f' at {1 / increment:g} Hz' if increment else '']
                )
                print(f'  {name}{extra}')
        return 0
    if not args.output:
        raise ValueError('give the bag to write with -o BAG (or --list to see the channels)')
    mapping = mapping_from_args(args)
    start_ns = None
    if args.start_time:
        start_ns = round(datetime.fromisoformat(args.start_time).timestamp() * 1e9)
    recordings = read_lab_files(args.files, mapping)
    total = sum(len(r.force_n) for r in recordings)
    with progress_bar(total, desc='writing', unit='sample', quiet=args.quiet) as bar:
        summary = write_recordings(
            recordings,
            args.output,
            storage=args.storage,
            batch_size=args.batch_size,
            start_time_ns=start_ns,
            on_progress=bar.update,
        )
    print('\n'.join(summary.report))
    print(
        f'wrote {summary.bag}: {summary.samples} samples per channel '
        f'({summary.duration_s:.3f} s at {summary.sample_rate_hz:g} Hz)'
    )
    return 0
