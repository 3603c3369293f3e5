"""`fmm diagnose`: name the effects the base model (Eq. 3) misses, or say none explains them.

It also bins the friction the records show against sliding speed and position.

Same inputs and rig flags as `fmm fit` (CSV files of one impact each, or bags). Exit status:
0 diagnosed (whatever was named, 'none' included), 1 the base model cannot be fitted at all
(the reason is printed, as JSON with --json) or a bag was damaged (its problems are printed
as warnings after the result), 2 bad input or flags.

Examples:
    fmm diagnose low_*.csv medium_*.csv high_*.csv
    fmm diagnose hit1.csv hit2.csv hit3.csv --json
    fmm diagnose hit*.csv --plot figures/
    fmm diagnose session.mcap --fit-initial-position
"""

import argparse
import math
from dataclasses import dataclass
from pathlib import Path

from fmm_ros.cli._fitting import fit_and_report
from fmm_ros.cli._model import add_rig_arguments, rig_from_args
from fmm_ros.core.diagnose.result import Diagnosis
from fmm_ros.core.diagnose.workflow import EFFECTS, UNEXPLAINED, diagnose
from fmm_ros.core.physics.rig import Rig

# Resolution of the --plot figures [dots per inch].
PLOT_DPI = 120


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the `diagnose` subcommand."""
    parser = subparsers.add_parser(
        'diagnose',
        help='find where the model and the measurement disagree and name the missing effects',
        description='Fit the base model (Eq. 3, mu fitted) to every impact at once, locate its '
        'misfit in time and frequency, add candidate effects ('
        + ', '.join(EFFECTS)
        + ') one at a time while the Bayesian information criterion improves clearly and '
        'the gap shrinks, check each still earns its place, and say "unexplained" where the '
        'residual stays structured. Also bins the friction the records show against sliding '
        'speed and position.',
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
    parser.add_argument('--json', action='store_true', help='print the result as JSON')
    parser.add_argument(
        '--plot',
        type=Path,
        metavar='DIR',
        help='write residual_before_after.png, frf_overlay.png and friction_map.png here',
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
    """The short tables a person reads in half a minute (and the figures written)."""
    result, files = run_result.diagnosis, run_result.files
    lines = [
        f'{len(files)} impact(s); velocity noise {result.noise_std_m_s:.3g} m/s (from the '
        f'data); base fit mu = {_value(result.mu, result.mu_stderr, "1")}'
    ]
    names = ', '.join(result.named_effects) or 'none'
    lines.append(
        f'missing effects: {names}   gap {result.gap_before:.3g} -> {result.gap_after:.3g}   '
        f'FRF gap {result.frf_gap_before:.3g} -> {result.frf_gap_after:.3g}'
    )
    for named in result.missing_effects:
        if named.effect == UNEXPLAINED:
            lines.append(f'  unexplained: {named.where.summary}')
            continue
        partial = ', a partial description only' if named.partial else ''
        lines.append(
            f'  {named.effect}: score {named.score:.0f}, dropping it again would cost '
            f'{named.drop_score:.0f}{partial}'
        )
        if named.trend is not None:
            trend = named.trend
            lines.append(
                f'    mu per hit {trend.mu[0]:.4f} ... {trend.mu[-1]:.4f}, slope '
                f'{_value(trend.slope_per_hit, trend.slope_stderr, "1")} per hit '
                f'(p = {trend.p_value:.2g})'
            )
        else:
            for parameter in named.parameters:
                lines.append(
                    f'    {parameter.name:<38} '
                    f'{_value(parameter.value, parameter.stderr, parameter.unit)}'
                )
    lines.append(f'where (base model): {result.where.summary}')
    lines.append('')
    lines.append(f'{"candidate (step 1)":<22}{"score (dBIC)":>14}{"gap after":>12}')
    for candidate in result.candidates:
        mark = '  <- named' if candidate.effect in result.named_effects else ''
        if candidate.message.startswith('screened'):
            mark += '  (screened)'
        score = f'{candidate.score:.0f}' if math.isfinite(candidate.score) else 'failed'
        lines.append(f'{candidate.effect:<22}{score:>14}{candidate.gap_after:>12.3g}{mark}')
    lines.append(
        f'(an effect is added when dBIC <= {result.required_score:.0f} and it removes a quarter '
        'of the squared gap left; the named set must halve the gap)'
    )
    lines += result.selection
    lines.append(_friction_line(result))
    lines.append(result.verdict)
    lines += [f'wrote {path}' for path in run_result.figures]
    return '\n'.join(lines)


def _friction_line(result: Diagnosis) -> str:
    """Friction at the slowest and fastest speed bins, and its range over position."""
    speed, position = result.friction_map.speed, result.friction_map.position
    if not speed.mu:
        return 'friction map: no sliding above the noise'
    text = (
        f'friction map: mu {speed.mu[0]:.4f} +- {speed.mu_stderr[0]:.2g} at '
        f'{1e3 * speed.centres[0]:.3g} mm/s, {speed.mu[-1]:.4f} +- {speed.mu_stderr[-1]:.2g} at '
        f'{1e3 * speed.centres[-1]:.3g} mm/s'
    )
    if position.mu:
        text += f'; {min(position.mu):.4f} to {max(position.mu):.4f} over position'
    return text


def plot_diagnosis(result: Diagnosis, records: list, rig: Rig, directory: Path) -> list[Path]:
    """Write residual_before_after.png, frf_overlay.png and friction_map.png; return the paths.

    The figures of the report's diagnosis section (`fmm_ros.report.diagnosis_figures`): one
    row per impact, residuals of the base and the final model over the motion, and |mobility|
    of measurement and models to 20 Hz beside |measured - model|; and mu against sliding
    speed and against position.
    """
    from fmm_ros.report import diagnosis_figures  # matplotlib: only when figures are asked for
    from fmm_ros.report.plotting import png_bytes

    directory.mkdir(parents=True, exist_ok=True)
    paths = [
        directory / 'residual_before_after.png',
        directory / 'frf_overlay.png',
        directory / 'friction_map.png',
    ]
    figures = (
        diagnosis_figures.residual_figure(result, records),
        diagnosis_figures.mobility_gap_figure(result, records, rig.natural_frequency_hz),
        diagnosis_figures.friction_map_figure(result),
    )
    for path, figure in zip(paths, figures, strict=True):
        path.write_bytes(png_bytes(figure, PLOT_DPI))
    return paths
