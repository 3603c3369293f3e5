"""`fmm diagnose`: name the effect the base model (Eq. 3) misses in measured impacts.

Same inputs, rig flags and hit selection as `fmm fit` (CSV files of one impact each, or bags;
flagged hits left out unless --include-flagged). Exit status:
0 diagnosed (whatever was named, 'none' included), 1 the base model cannot be fitted at all
(the reason is printed, as JSON with --json) or a bag was damaged (its problems are printed
as warnings after the result), 2 bad input or flags.

Examples:
    fmm diagnose low_*.csv medium_*.csv high_*.csv
    fmm diagnose hit1.csv hit2.csv hit3.csv --json
    fmm diagnose hit*.csv --plot figures/
"""

import argparse
import math
from dataclasses import dataclass
from pathlib import Path

from fmm_ros.cli._fitting import fit_and_report
from fmm_ros.cli._model import add_rig_arguments, rig_from_args
from fmm_ros.cli.analyze import add_selection_argument
from fmm_ros.core.diagnose.result import Diagnosis
from fmm_ros.core.diagnose.workflow import EFFECTS, NONE, diagnose
from fmm_ros.core.physics.rig import Rig

# Resolution of the --plot figures [dots per inch].
PLOT_DPI = 120


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the `diagnose` subcommand."""
    parser = subparsers.add_parser(
        'diagnose',
        help='find where the model and the measurement disagree and name the missing effect',
        description='Fit the base model (Eq. 3, mu fitted) to every impact at once, locate its '
        'misfit in time and frequency, refit it with each candidate effect ('
        + ', '.join(EFFECTS)
        + ') and name the one that is clearly better by the '
        'Bayesian information criterion, or none.',
    )
    parser.add_argument(
        'inputs',
        nargs='+',
        type=Path,
        metavar='INPUT',
        help='CSV files of one impact each (time_s,force_n,velocity_m_s) or '
        'bags (every impact recorded)',
    )
    parser.add_argument(
        '--fit-initial-position',
        action='store_true',
        help="fit each impact's start position in every model, base and "
        'candidates (a hit that found the rig held off centre by '
        'friction); otherwise each starts at x = 0',
    )
    add_rig_arguments(parser)
    add_selection_argument(parser)
    parser.add_argument('--json', action='store_true', help='print the result as JSON')
    parser.add_argument(
        '--plot',
        type=Path,
        metavar='DIR',
        help='write residual_before_after.png and frf_overlay.png here',
    )
    parser.set_defaults(func=run)


@dataclass(frozen=True)
class _Run:
    """What one `fmm diagnose` produced: the diagnosis, its inputs' names, the figures."""

    diagnosis: Diagnosis
    files: list[str]
    figures: list[Path]


def run(args: argparse.Namespace) -> int:
    """Diagnose the inputs; print a table or JSON; draw the figures if asked."""
    rig = rig_from_args(args)

    def diagnose_records(records) -> _Run:
        result = diagnose(records, rig=rig, fit_initial_position=args.fit_initial_position)
        figures = plot_diagnosis(result, records, rig, args.plot) if args.plot else []
        return _Run(result, [record.source for record in records], figures)

    return fit_and_report('diagnose', args, diagnose_records, report, text_report)


def report(run_result: _Run) -> dict:
    """The JSON document: `Diagnosis.to_dict()`, the input names and the figures written."""
    return {
        **run_result.diagnosis.to_dict(),
        'files': run_result.files,
        'figures': [str(path) for path in run_result.figures],
    }


def _value(value: float, error: float, unit: str) -> str:
    unit = '' if unit == '1' else f' {unit}'
    if math.isfinite(error) and error > 0.0:
        return f'{value:.4g} +- {error:.2g}{unit}'
    return f'{value:.4g}{unit}'


def text_report(run_result: _Run) -> str:
    """The short table a person reads in ten seconds (and the figures written)."""
    result, files = run_result.diagnosis, run_result.files
    lines = [
        f'{len(files)} impact(s); velocity noise {result.noise_std_m_s:.3g} m/s (from the '
        f'data); base fit mu = {_value(result.mu, result.mu_stderr, "1")}'
    ]
    if result.missing_effect == NONE:
        lines.append(
            f'missing effect: none   gap {result.gap_before:.3g} (FRF {result.frf_gap_before:.3g})'
        )
    else:
        lines.append(
            f'missing effect: {result.missing_effect}   gap {result.gap_before:.3g} -> '
            f'{result.gap_after:.3g}   FRF gap {result.frf_gap_before:.3g} -> '
            f'{result.frf_gap_after:.3g}'
        )
        for parameter in result.parameters:
            lines.append(
                f'  {parameter.name:<40} '
                f'{_value(parameter.value, parameter.stderr, parameter.unit)}'
            )
    lines.append(f'where: {result.where.summary}')
    lines.append('')
    lines.append(f'{"candidate":<22}{"score (dBIC)":>14}{"gap after":>12}')
    for candidate in result.candidates:
        mark = '  <- named' if candidate.effect == result.missing_effect else ''
        score = f'{candidate.score:.0f}' if math.isfinite(candidate.score) else 'failed'
        lines.append(f'{candidate.effect:<22}{score:>14}{candidate.gap_after:>12.3g}{mark}')
    lines.append(f'(named when dBIC <= {result.required_score:.0f} and the gap at least halves)')
    lines.append(result.verdict)
    lines += [f'wrote {path}' for path in run_result.figures]
    return '\n'.join(lines)


def plot_diagnosis(result: Diagnosis, records: list, rig: Rig, directory: Path) -> list[Path]:
    """Write residual_before_after.png and frf_overlay.png into directory; return the paths.

    The figures of the report's diagnosis section (`fmm_ros.report.diagnosis_figures`), one
    row per impact: residuals of the base and the named model over the motion, and
    |mobility| of measurement and models to 20 Hz beside |measured - model|.
    """
    from fmm_ros.report import diagnosis_figures  # matplotlib: only when figures are asked for
    from fmm_ros.report.plotting import png_bytes

    directory.mkdir(parents=True, exist_ok=True)
    paths = [directory / 'residual_before_after.png', directory / 'frf_overlay.png']
    figures = (
        diagnosis_figures.residual_figure(result, records),
        diagnosis_figures.mobility_gap_figure(result, records, rig.natural_frequency_hz),
    )
    for path, figure in zip(paths, figures, strict=True):
        path.write_bytes(png_bytes(figure, PLOT_DPI))
    return paths
