"""`fmm diagnose`: name the effects the base model (Eq. 3) misses, or say none explains them.

It also bins the friction the records show against sliding speed and position.

Same inputs, hit selection and rig flags as `fmm fit` (lab files of one impact each, or
bags; flagged hits left out and named unless --include-flagged). Exit status: 0 diagnosed
(whatever was named, 'none' and 'unexplained' included), 1 the base model cannot be fitted at
all or no hit is clean (the reason is printed, as JSON with --json) or a bag was damaged (its
problems are printed as warnings after the result), 2 bad input or flags.

Examples:
    fmm diagnose low_*.csv medium_*.csv high_*.csv
    fmm diagnose hit1.csv hit2.csv hit3.csv --json
    fmm diagnose hit*.csv -o figures/
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from fmm_ros.cli import options
from fmm_ros.core.diagnose.vocabulary import EFFECTS
from fmm_ros.core.physics.rig import Rig

if TYPE_CHECKING:
    from fmm_ros.core.diagnose.result import Diagnosis

# Resolution of the figures written into -o DIR [dots per inch].
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
    options.add_inputs(parser)
    options.add_json(parser)
    options.add_output(
        parser,
        'write the figures residual_before_after.png, frf_overlay.png and friction_map.png '
        'into DIR',
        metavar='DIR',
    )
    options.add_model(parser, damping=False)
    options.add_hit_selection(parser, fits=True)
    options.add_quiet(parser)
    options.add_whole_record(parser)
    parser.set_defaults(func=run)


@dataclass(frozen=True)
class _Run:
    """What one `fmm diagnose` produced: the diagnosis, its inputs' names, the figures."""

    diagnosis: Diagnosis
    files: list[str]
    figures: list[Path]


def run(args: argparse.Namespace) -> int:
    """Diagnose the inputs; print a table or JSON; draw the figures if asked."""
    if args.whole_record:
        from fmm_ros.cli import whole_record

        return whole_record.run(args, 'diagnose')
    from fmm_ros.cli._fitting import FitRequest, fit_and_report
    from fmm_ros.cli.formats import diagnosis_text
    from fmm_ros.workflows.results import diagnosis_dict
    from fmm_ros.workflows.session import diagnose_impacts

    model = options.fit_options(args)

    def diagnose_records(records, ids, progress) -> _Run:
        result = diagnose_impacts(records, ids, model, progress=progress).diagnosis
        chosen = [records[i] for i in ids]
        figures = plot_diagnosis(result, chosen, model.rig, args.output) if args.output else []
        return _Run(result, [record.source for record in chosen], figures)

    return fit_and_report(
        FitRequest.from_args('diagnose', args),
        diagnose_records,
        report,
        lambda run: diagnosis_text(diagnosis_dict(run.diagnosis), len(run.files), run.figures),
    )


def report(run_result: _Run) -> dict:
    """The JSON document: `diagnosis_dict`, the input names and the figures written."""
    from fmm_ros.workflows.results import diagnosis_dict

    return {
        **diagnosis_dict(run_result.diagnosis),
        'files': run_result.files,
        'figures': [str(path) for path in run_result.figures],
    }


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
