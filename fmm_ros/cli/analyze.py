"""`fmm analyze`: impulses, FRFs, levels and the linear-in-impulse law, from lab files or bags.

Each lab-file INPUT is one impact (a CSV `time_s,force_n,velocity_m_s` as fmm writes it, or
whatever a lab wrote, read as `fmm import` reads it); a bag INPUT gives every impact in its
recorded streams, found by feeding its batches to the analyzer's capture. All go through the
same trigger rule, quality flags and FRF code as the analyzer node
(`fmm_ros.workflows.inputs`, `fmm_ros.workflows.session.analyse`), so a file, a bag and a
live capture of the same samples get the same verdict. With `--force-only` the files' force
channels alone are read and every hit is listed (`fmm_ros.workflows.hammer`).
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import TYPE_CHECKING

from fmm_ros.cli import options

if TYPE_CHECKING:
    from fmm_ros.workflows.hammer import FileHits


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the `analyze` subcommand."""
    parser = subparsers.add_parser(
        'analyze',
        help='impulse, FRFs, force levels and linearity from lab files or bags',
        description='Analyse impacts, one lab file each (CSV time_s,force_n,velocity_m_s, '
        "or a lab's CSV, MATLAB, TDMS or NPZ file read as fmm import reads it) or every "
        'impact recorded in a bag: quality flags, impulse (trapezoid), peak force, '
        'mobility/receptance from the DFT of the whole record, per-level averages (plain '
        'mean, H1, H2, coherence) and the peak |receptance| vs impulse regression. The '
        'response may be a velocity, an acceleration or a displacement; the FRFs come in '
        'all three forms (accelerance, mobility, receptance).',
    )
    options.add_inputs(parser)
    parser.add_argument(
        '--force-only',
        action='store_true',
        help='the hammer alone: read only the force of each lab file and list every hit '
        '(time, peak, impulse, contact time, flags); no response channel needed',
    )
    options.add_analysis(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Analyse the files and bags, print the report, write any exports."""
    from fmm_ros.cli.formats import analysis_text
    from fmm_ros.cli.progress import StatusLine, report_problems
    from fmm_ros.io.frf_files import level_curves, write_frfs
    from fmm_ros.workflows.inputs import read_inputs
    from fmm_ros.workflows.results import analysis_dict
    from fmm_ros.workflows.session import analyse

    capture, analysis = options.analysis_configs(args)
    if args.force_only:
        from fmm_ros.workflows.hammer import read_hammer_hits

        return _hammer_only(
            args,
            read_hammer_hits(
                args.inputs, options.input_options(args, capture), analysis.reject_flags
            ),
        )
    with StatusLine(quiet=args.quiet) as progress:
        read = read_inputs(args.inputs, options.input_options(args, capture), progress=progress)
        summary = analyse(read.records, capture, read.grouped(analysis), progress=progress)
    for path in args.output:
        write_frfs(path, level_curves(summary))
    if args.json:
        print(json.dumps(analysis_dict(summary), indent=2, allow_nan=False))
    else:
        print(analysis_text(summary))
        for note in read.notes:
            if 'stamps' in note:  # a rate from date-time stamps, and their jitter
                print(f'fmm analyze: {note.strip()}', file=sys.stderr)
    return report_problems('analyze', read.problems)


def _hammer_only(args: argparse.Namespace, files: list[FileHits]) -> int:
    """Print every file's hits (JSON or a table); exit 0 whether hits were found or not."""
    if args.json:
        from fmm_ros.core.results_schema import HAMMER_HIT, keys
        from fmm_ros.workflows.results import json_safe

        document = {
            'files': [
                {
                    'file': str(found.path),
                    'sample_rate_hz': found.sample_rate_hz,
                    'verdict': found.verdict,
                    'hits': [
                        {key: getattr(hit, key) for key in keys(HAMMER_HIT)} for hit in found.hits
                    ],
                    'notes': found.notes,
                }
                for found in files
            ]
        }
        print(json.dumps(json_safe(document), indent=2, allow_nan=False))
        return 0
    from fmm_ros.core.results_schema import CONTACT_TIME, HIT_TIME, IMPULSE, PEAK_FORCE, label

    lines = []
    for found in files:
        lines.append(found.verdict)
        lines += [f'  {note.strip()}' for note in found.notes if 'sample rate' in note]
        if found.hits:
            lines.append(
                f'  {"hit":>4} {label(HIT_TIME, ascii=True):>10} '
                f'{label(PEAK_FORCE, ascii=True, short=True):>9} '
                f'{label(IMPULSE, ascii=True):>13} {label(CONTACT_TIME, ascii=True):>12}  flags'
            )
        for number, hit in enumerate(found.hits, 1):
            lines.append(
                f'  {number:>4} {hit.time_s:>10.4f} {hit.peak_force_n:>9.4g} '
                f'{hit.impulse_n_s:>13.4g} {CONTACT_TIME.shown(hit.contact_time_s):>12.3f}  '
                f'{",".join(hit.flags) or "-"}'
            )
    print('\n'.join(lines))
    return 0
