"""The run of a fitting subcommand (fit, identify-rig, and diagnose): inputs in, verdict out.

Inputs are read as `fmm analyze` reads them (CSV files of one impact, bags of many). Fit and
diagnose take the impacts the signal core's `select_impacts` takes: flagged ones (a clipped
force, a double hit, a dead vibrometer...) are left out and named, unless --include-flagged.
A fit the data refuse (`FitError`, or no clean impact) exits 1 with its reason, as JSON with
--json, kept apart from bad input or flags (2, from the `fmm` entry point); a damaged bag's
problems are warnings after the result, and also exit 1, as in `fmm analyze`.
"""

import argparse
import json
import sys
from collections.abc import Callable, Sequence
from typing import Any

from fmm_ros.cli.analyze import read_records
from fmm_ros.cli.progress import report_problems
from fmm_ros.core.identify.conditioning import FitError
from fmm_ros.core.signal.analysis import ImpactSelection, SelectionError
from fmm_ros.core.signal.records import ImpactRecord
from fmm_ros.workflows.session import select_records


def fit_and_report(
    command: str,
    args: argparse.Namespace,
    fit: Callable[[Sequence[ImpactRecord]], Any],
    report: Callable[[Any], dict],
    text_report: Callable[[Any], str],
    *,
    select: bool = True,
) -> int:
    """Read args.inputs, fit them, print the result (or why there is none); the exit status.

    select: take the impacts by `select_impacts` (args.include_flagged); off for commands
    whose records need not hold a hit (identify-rig's free decays).
    """
    records, problems = read_records(args.inputs)
    selection = None
    try:
        if select:
            records, selection = select_records(records, include_flagged=args.include_flagged)
        result = fit(records)
    except (FitError, SelectionError) as failure:
        report_problems(command, problems)
        if isinstance(failure, FitError):
            reason, source = failure.reason, failure.source or None
        else:
            reason, source, selection = 'no_clean_impact', None, failure.selection
        if args.json:
            print(
                json.dumps(
                    {'error': reason, 'message': str(failure), 'file': source}
                    | selection_report(selection)
                )
            )
        else:
            print(f'fmm {command}: cannot fit ({reason}): {failure}', file=sys.stderr)
        return 1
    if args.json:
        print(json.dumps(report(result) | selection_report(selection), indent=2, allow_nan=False))
    else:
        print(text_report(result))
        if selection is not None and selection.note:
            print(selection.note)
    return report_problems(command, problems)


def selection_report(selection: ImpactSelection | None) -> dict:
    """JSON keys naming the impacts left out (and flagged ones taken on request)."""
    if selection is None:
        return {}

    def entries(items: tuple) -> list[dict]:
        return [
            {'impact': impact_id, 'file': source or None, 'flags': list(flags)}
            for impact_id, flags, source in items
        ]

    return {
        'left_out': entries(selection.excluded),
        'included_flagged': entries(selection.included_flagged),
    }
