"""`fmm analyze`: impulses, FRFs, levels and the linear-in-impulse law, from lab files or bags.

Each lab-file INPUT is one impact (a CSV `time_s,force_n,velocity_m_s` as fmm writes it, or
whatever a lab wrote, read as `fmm import` reads it); a bag INPUT gives every impact in its
recorded streams, found by feeding its batches to the analyzer's capture. All go through the
same trigger rule, quality flags and FRF code as the analyzer node
(`fmm_ros.workflows.inputs`, `fmm_ros.workflows.session.analyse`), so a file, a bag and a
live capture of the same samples get the same verdict.
"""

from __future__ import annotations

import argparse
import json

from fmm_ros.cli import options


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the `analyze` subcommand."""
    parser = subparsers.add_parser(
        'analyze',
        help='impulse, FRFs, force levels and linearity from lab files or bags',
        description='Analyse impacts, one lab file each (CSV time_s,force_n,velocity_m_s, '
        "or a lab's CSV, MATLAB, TDMS or NPZ file read as fmm import reads it) or every "
        'impact recorded in a bag: quality flags, impulse (trapezoid), peak force, '
        'mobility/receptance from the DFT of the whole record, per-level averages (plain '
        'mean, H1, H2, coherence) and the peak |receptance| vs impulse regression.',
    )
    options.add_inputs(parser)
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
    with StatusLine(quiet=args.quiet) as progress:
        read = read_inputs(args.inputs, options.input_options(args, capture), progress=progress)
        summary = analyse(read.records, capture, analysis, progress=progress)
    for path in args.output:
        write_frfs(path, level_curves(summary))
    if args.json:
        print(json.dumps(analysis_dict(summary), indent=2, allow_nan=False))
    else:
        print(analysis_text(summary))
    return report_problems('analyze', read.problems)
