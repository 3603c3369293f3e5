"""`fmm analyze`: impulses, FRFs, levels and the linear-in-impulse law from CSV files or bags.

Each CSV INPUT is one impact (`time_s,force_n,velocity_m_s`, as `fmm_ros.core.signal.records` reads
it); a bag INPUT gives every impact in its recorded streams, found by feeding its batches to
the analyzer's capture (`fmm_ros.workflows.replay`). Both go through the same trigger rule,
quality flags and FRF code as the analyzer node, so a file, a bag and a live capture of the
same samples get the same verdict.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

import numpy as np

from fmm_ros.cli.progress import report_problems
from fmm_ros.core.signal.analysis import (
    AnalysisConfig,
    NominalLevel,
    Summary,
    analyze_impact,
    paper_levels,
    summarize,
)
from fmm_ros.core.signal.capture import DEFAULT_CAPTURE, FLAGS, CaptureConfig
from fmm_ros.core.signal.records import ImpactRecord, read_impact_csv
from fmm_ros.io.frf_files import json_number, level_curves, write_frfs
from fmm_ros.workflows.replay import bag_impact_records, is_bag

# Relative difference in sample rate beyond which two files are not one measurement series.
RATE_TOLERANCE = 1e-6


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the `analyze` subcommand."""
    parser = subparsers.add_parser(
        'analyze',
        help='impulse, FRFs, force levels and linearity from impact CSV files or bags',
        description='Analyse impacts, one CSV file each (header time_s,force_n,velocity_m_s) '
        'or every impact recorded in a bag: quality flags, impulse (trapezoid), '
        'peak force, mobility/receptance from the DFT of the whole record, '
        'per-level averages (plain mean, H1, H2, coherence) and the peak '
        '|receptance| vs impulse regression.',
    )
    parser.add_argument(
        'inputs',
        nargs='+',
        type=Path,
        metavar='INPUT',
        help='one CSV file per impact, or a bag (directory, .mcap or .db3)',
    )
    parser.add_argument('--json', action='store_true', help='print the results as JSON')
    add_analysis_options(parser)
    parser.add_argument(
        '--export',
        action='append',
        default=[],
        type=Path,
        metavar='PATH',
        help='write the level FRFs to PATH: .uff/.unv (UFF 58), .csv or .json (repeatable)',
    )
    parser.set_defaults(func=run)


def add_analysis_options(parser: argparse.ArgumentParser) -> None:
    """The capture and analysis options `fmm analyze` and `fmm replay` share."""
    defaults, analysis = CaptureConfig(), AnalysisConfig()
    levels = parser.add_mutually_exclusive_group()
    levels.add_argument(
        '--level',
        action='append',
        default=[],
        metavar='NAME=FORCE_N',
        type=_nominal_level,
        help='a nominal force level (repeatable); without levels, peak forces are clustered',
    )
    levels.add_argument(
        '--paper-levels',
        action='store_true',
        help="the paper's levels: low=450, medium=1000, high=1450 N",
    )
    parser.add_argument(
        '--tolerance-n',
        type=float,
        default=50.0,
        help='accepted distance from a nominal peak force [N] (default 50)',
    )
    parser.add_argument(
        '--trigger-n',
        type=float,
        default=defaults.trigger_level_n,
        help=f'trigger level [N] (default {defaults.trigger_level_n:g})',
    )
    parser.add_argument(
        '--rearm-n',
        type=float,
        default=defaults.rearm_level_n,
        help=f're-arm / contact threshold [N] (default {defaults.rearm_level_n:g})',
    )
    parser.add_argument(
        '--window-s',
        type=float,
        default=defaults.window_s,
        help='record length the capture cuts from a bag [s] '
        f'(default {defaults.window_s:g}, as in the paper)',
    )
    parser.add_argument(
        '--rest-velocity-m-s',
        type=float,
        default=defaults.rest_velocity_m_s,
        help=f'|velocity| counted as rest [m/s] (default {defaults.rest_velocity_m_s:g})',
    )
    parser.add_argument(
        '--force-full-scale-n',
        type=float,
        default=0.0,
        help='force sensor range [N], for the clipped flag (default: unknown)',
    )
    parser.add_argument(
        '--velocity-full-scale-m-s',
        type=float,
        default=0.0,
        help='vibrometer range [m/s], for the clipped flag (default: unknown)',
    )
    parser.add_argument(
        '--band-limit-hz',
        type=float,
        default=analysis.band_limit_hz,
        help=f'highest FRF frequency kept [Hz] (default {analysis.band_limit_hz:g})',
    )
    parser.add_argument(
        '--force-window-s',
        type=float,
        default=None,
        help='force window length after the trigger [s] (default: none)',
    )
    parser.add_argument(
        '--exponential-decay-s',
        type=float,
        default=None,
        help='exponential window decay time [s] (default: none)',
    )
    parser.add_argument(
        '--reject',
        type=_flag_list,
        default=FLAGS,
        metavar='FLAG,...',
        help=f'flags that reject an impact, or "none" (default: all of {",".join(FLAGS)})',
    )


def add_selection_argument(parser: argparse.ArgumentParser) -> None:
    """--include-flagged: the subcommands that fit (fit, diagnose, report) take flagged hits too."""
    parser.add_argument(
        '--include-flagged',
        action='store_true',
        help='also fit hits the quality flags reject (clipped, double hit, dead vibrometer, '
        '...); they are left out by default and named',
    )


def analysis_configs(args: argparse.Namespace) -> tuple[CaptureConfig, AnalysisConfig]:
    """The capture and analysis configuration of the options add_analysis_options added."""
    capture = CaptureConfig(
        trigger_level_n=args.trigger_n,
        rearm_level_n=args.rearm_n,
        rest_velocity_m_s=args.rest_velocity_m_s,
        window_s=args.window_s,
    )
    levels = (
        paper_levels(args.tolerance_n)
        if args.paper_levels
        else tuple(dataclasses.replace(level, tolerance_n=args.tolerance_n) for level in args.level)
    )
    analysis = AnalysisConfig(
        band_limit_hz=args.band_limit_hz,
        force_window_s=args.force_window_s,
        exponential_decay_s=args.exponential_decay_s,
        levels=levels,
        reject_flags=args.reject,
    )
    return capture, analysis


def run(args: argparse.Namespace) -> int:
    """Analyse the files and bags, print the report, write any exports."""
    capture, analysis = analysis_configs(args)
    records, problems = read_records(
        args.inputs, args.force_full_scale_n, args.velocity_full_scale_m_s, capture
    )
    results = [
        analyze_impact(record, capture, analysis, impact_id=number)
        for number, record in enumerate(records)
    ]
    summary = summarize(results, analysis)
    for path in args.export:
        write_frfs(path, level_curves(summary))
    if args.json:
        print(json.dumps(report(summary), indent=2, allow_nan=False))
    else:
        print(text_report(summary))
    return report_problems('analyze', problems)


def read_records(
    paths: list[Path],
    force_full_scale_n: float = 0.0,
    velocity_full_scale_m_s: float = 0.0,
    capture: CaptureConfig = DEFAULT_CAPTURE,
) -> tuple[list[ImpactRecord], list[str]]:
    """The inputs as records on one frequency grid, and the problems of damaged bags.

    A CSV file is one record; a bag gives every record the capture finds in it (each as long
    as the capture window). Shorter records are zero-padded to the longest window. A full
    scale given here replaces a recorded one. Raises ValueError when the inputs do not share
    one sample rate: their FRFs could not be averaged, and a mixed-up file is the likely cause.
    """
    records: list[ImpactRecord] = []
    problems: list[str] = []
    for path in paths:
        if is_bag(path):
            found, damage = bag_impact_records(path, capture)
            if not found:
                raise ValueError(
                    f'{path}: no impact in the recorded streams (the force never '
                    f'reaches the trigger level {capture.trigger_level_n:g} N)'
                )
            records += found
            problems += [f'{path}: {problem}' for problem in damage]
        else:
            records.append(read_impact_csv(path))
    rate = records[0].sample_rate_hz
    odd = [
        record for record in records if abs(record.sample_rate_hz - rate) > RATE_TOLERANCE * rate
    ]
    if odd:
        raise ValueError(
            f'mismatched sample rates: {records[0].source} is sampled at {rate:.6g} '
            f'Hz but {odd[0].source} at {odd[0].sample_rate_hz:.6g} Hz'
        )
    window = max(record.window_samples for record in records)
    return [
        dataclasses.replace(
            record,
            window_samples=window,
            force_full_scale_n=force_full_scale_n or record.force_full_scale_n,
            velocity_full_scale_m_s=velocity_full_scale_m_s or record.velocity_full_scale_m_s,
        )
        for record in records
    ], problems


def report(summary: Summary) -> dict:
    """The JSON document: impacts, levels and linearity (undefined numbers as null)."""
    return {
        'impacts': [
            {
                'file': result.source,
                'accepted': result.accepted,
                'flags': list(result.flags),
                'impulse_n_s': json_number(result.impulse_n_s),
                'peak_force_n': json_number(result.peak_force_n),
                'peak_receptance_m_per_n': json_number(result.peak_receptance_m_per_n),
                'natural_frequency_hz': json_number(result.natural_frequency_hz),
            }
            for result in summary.impacts
        ],
        'levels': [
            {
                'name': level.level,
                'count': level.count,
                'mean_impulse_n_s': json_number(level.mean_impulse_n_s),
                'peak_receptance_m_per_n': json_number(level.peak_receptance_m_per_n),
            }
            for level in summary.levels
        ],
        'linearity': {
            'slope': json_number(summary.linearity.slope),
            'intercept': json_number(summary.linearity.intercept),
            'r2': json_number(summary.linearity.r2),
        },
    }


def text_report(summary: Summary) -> str:
    """A table of impacts, one of levels, and the regression line."""
    lines = [
        f'{"impact":<28} {"level":<8} {"ok":<3} {"impulse N*s":>11} {"peak N":>8} '
        f'{"|X/F| m/N":>10} {"f_n Hz":>7}  flags'
    ]
    for result in summary.impacts:
        lines.append(
            f'{Path(result.source).name:<28.28} {result.level or "-":<8} '
            f'{"yes" if result.accepted else "no":<3} {result.impulse_n_s:>11.4g} '
            f'{result.peak_force_n:>8.4g} {result.peak_receptance_m_per_n:>10.4g} '
            f'{result.natural_frequency_hz:>7.3f}  {",".join(result.flags) or "-"}'
        )
    lines += [
        '',
        f'{"level":<8} {"count":>5} {"mean impulse N*s":>16} {"|X/F| m/N":>10} {"f_n Hz":>7}',
    ]
    for level in summary.levels:
        lines.append(
            f'{level.level:<8} {level.count:>5} {level.mean_impulse_n_s:>16.4g} '
            f'{level.peak_receptance_m_per_n:>10.4g} {level.natural_frequency_hz:>7.3f}'
        )
    if not summary.levels:
        lines.append('(no level has an accepted impact)')
    fit = summary.linearity
    lines.append('')
    if np.isnan(fit.slope):
        lines.append('linearity: needs accepted impacts at 2 or more levels')
    else:
        lines.append(
            f'linearity: |X/F| peak = {fit.slope:.4g} m/(N^2*s) * impulse + '
            f'{fit.intercept:.4g} m/N over {fit.count} levels, R^2 = {fit.r2:.4f}'
        )
    return '\n'.join(lines)


def _nominal_level(text: str) -> NominalLevel:
    """NAME=FORCE_N from the command line."""
    name, _, force = text.partition('=')
    try:
        value = float(force)
    except ValueError:
        value = float('nan')
    if not name.strip() or not np.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(
            f'expected NAME=FORCE_N with a positive force, got {text!r}'
        )
    return NominalLevel(name.strip(), value)


def _flag_list(text: str) -> tuple[str, ...]:
    """A comma-separated flag list, or "none"."""
    if text.strip().lower() == 'none':
        return ()
    flags = tuple(flag.strip() for flag in text.split(',') if flag.strip())
    unknown = [flag for flag in flags if flag not in FLAGS]
    if unknown:
        raise argparse.ArgumentTypeError(
            f'unknown flag(s) {", ".join(unknown)}; known: {", ".join(FLAGS)}'
        )
    return flags
