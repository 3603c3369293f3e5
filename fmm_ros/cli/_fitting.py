"""The run of a fitting subcommand (fit, identify-rig, and diagnose): inputs in, verdict out.

Inputs are read as `fmm analyze` reads them (CSV files of one impact, bags of many). A fit the
data refuse (`FitError`) exits 1 with its reason, as JSON with --json, kept apart from bad
input or flags (2, from the `fmm` entry point); a damaged bag's problems are warnings after
the result, and also exit 1, as in `fmm analyze`.
"""

import argparse
import json
import sys
from collections.abc import Callable, Sequence
from typing import Any

from fmm_ros.cli.analyze import read_records
from fmm_ros.cli.progress import report_problems
from fmm_ros.core.identify.conditioning import FitError
from fmm_ros.core.signal.records import ImpactRecord


def fit_and_report(
    command: str,
    args: argparse.Namespace,
    fit: Callable[[Sequence[ImpactRecord]], Any],
    report: Callable[[Any], dict],
    text_report: Callable[[Any], str],
) -> int:
    """Read args.inputs, fit them, print the result (or why there is none); the exit status."""
    records, problems = read_records(args.inputs)
    try:
        result = fit(records)
    except FitError as failure:
        report_problems(command, problems)
        if args.json:
            print(
                json.dumps(
                    {
                        'error': failure.reason,
                        'message': str(failure),
                        'file': failure.source or None,
                    }
                )
            )
        else:
            print(f'fmm {command}: cannot fit ({failure.reason}): {failure}', file=sys.stderr)
        return 1
    if args.json:
        print(json.dumps(report(result), indent=2, allow_nan=False))
    else:
        print(text_report(result))
    return report_problems(command, problems)
