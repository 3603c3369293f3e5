"""`fmm import FILE [FILE ...] -o BAG`: lab measurements (CSV, NPZ, MAT, TDMS) into a bag."""

from __future__ import annotations

import argparse
from datetime import datetime

from fmm_ros.cli import options
from fmm_ros.errors import BadInputError
from fmm_ros.ros.settings import NodeSettings
from fmm_ros.units import FORCE_UNITS, VELOCITY_UNITS

EPILOG = f"""\
force units: {', '.join(FORCE_UNITS)}; velocity units: {', '.join(VELOCITY_UNITS)}.
Any other unit (V, mV, counts) needs --force-scale / --velocity-scale in N or m/s per unit.

mapping file (flags override its entries):
  force:    {{name: Hammer, unit: lbf}}
  velocity: {{name: Vibrometer, unit: V, scale: 0.125}}   # 125 mm/s per V
  sample_rate_hz: 10000          # or a variable name, or leave out and give:
  time:     {{name: Time, unit: s}}

Without a mapping, a file that states its units (a units row under a text header, "Hammer
[lbf]" in a header, TDMS unit strings, the names time_s, force_n, velocity_m_s) has its one
channel in force units taken as force, and likewise velocity and time; what was taken is
printed.
"""


def register(subparsers) -> None:
    """Add the import subcommand."""
    parser = subparsers.add_parser(
        'import',
        help='lab files (CSV, NPZ, MATLAB .mat, NI TDMS) into a session bag',
        description='Convert lab measurements to the session bag the recorder writes: force '
        'in N and velocity in m/s on one sample index, in 500-sample batches. '
        'Which channel is which, their units and the sample rate are stated (or stated '
        'by the file), never guessed. Several files are joined in order.',
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        'files', nargs='+', help='lab files: delimited text, .npz, .mat (v4-v7.3), .tdms'
    )
    options.add_output(parser, 'bag directory to create', metavar='BAG')
    parser.add_argument(
        '--list', action='store_true', help='list the channels each file holds, and stop'
    )
    group = parser.add_argument_group('the channels (flags override the mapping file)')
    options.add_mapping_flags(group)
    options.add_full_scale_flags(group)
    options.add_setting(parser, NodeSettings, 'storage')
    options.add_setting(parser, NodeSettings, 'batch_size', metavar='SAMPLES')
    parser.add_argument(
        '--start-time',
        metavar='ISO8601',
        help="acquisition time of the first sample (default: the file's own, "
        'else its modification time minus its duration)',
    )
    options.add_quiet(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """List the files' channels, or import them into a bag."""
    from fmm_ros.cli.progress import progress_bar
    from fmm_ros.io.labfiles import open_lab_file, read_lab_files, write_recordings

    if args.list:
        for path in args.files:
            lab = open_lab_file(path, options.text_format(args))
            print(f'{path} ({lab.format}{", " + lab.layout() if lab.layout() else ""}):')
            for name in lab.names():
                unit = lab.channel_unit(name)
                increment = lab.channel_increment_s(name)
                extra = ''.join(
                    [f' [{unit}]' if unit else '', f' at {1 / increment:g} Hz' if increment else '']
                )
                print(f'  {name}{extra}')
        return 0
    if not args.output:
        raise BadInputError('give the bag to write with -o BAG (or --list to see the channels)')
    start_ns = None
    if args.start_time:
        start_ns = round(datetime.fromisoformat(args.start_time).timestamp() * 1e9)
    recordings = read_lab_files(args.files, options.mapping_spec(args), options.text_format(args))
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
