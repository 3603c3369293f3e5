"""The run of a fitting subcommand (fit, identify-rig, and diagnose): inputs in, verdict out.

Inputs are read by the one input layer (`fmm_ros.workflows.inputs`: lab files of one impact,
bags of many); with a hit-selection option only the accepted hits are fitted. A fit the data
refuse (`FitError`) exits 1 with its reason, as JSON with --json, kept apart from bad input or
flags (2, from the `fmm` entry point); a damaged bag's problems are warnings after the
result, and also exit 1, as in `fmm analyze`.
"""

import argparse
import json
import sys
from collections.abc import Callable, Sequence
from typing import Any

from fmm_ros.cli import options
from fmm_ros.cli.progress import StatusLine, report_problems
from fmm_ros.core.identify.conditioning import FitError
from fmm_ros.core.signal.capture import CaptureConfig
from fmm_ros.core.signal.records import ImpactRecord
from fmm_ros.workflows.inputs import read_inputs
from fmm_ros.workflows.session import accepted_ids, analyse

Fit = Callable[[list[ImpactRecord], Sequence[int], Callable[[str], None]], Any]


def fit_and_report(
    command: str,
    args: argparse.Namespace,
    fit: Fit,
    report: Callable[[Any], dict],
    text_report: Callable[[Any], str],
) -> int:
    """Read args.inputs, pick the hits, fit them, print the result (or why there is none).

    fit(records, impact_ids, progress) fits records[i] for i in impact_ids.
    """
    selecting = hasattr(args, 'paper_levels') and options.selects_hits(args)
    capture, analysis = (
        options.analysis_configs(args) if hasattr(args, 'trigger_n') else (CaptureConfig(), None)
    )
    with StatusLine(quiet=args.quiet) as progress:
        read = read_inputs(args.inputs, options.input_options(args, capture), progress=progress)
        records = read.records
        ids = (
            accepted_ids(analyse(records, capture, analysis, progress=progress))
            if selecting
            else list(range(len(records)))
        )
        try:
            result = fit(records, ids, progress)
        except FitError as failure:
            result = failure
    if isinstance(result, FitError):
        report_problems(command, read.problems)
        if args.json:
            print(
                json.dumps(
                    {'error': result.reason, 'message': str(result), 'file': result.source or None}
                )
            )
        else:
            print(f'fmm {command}: cannot fit ({result.reason}): {result}', file=sys.stderr)
        return 1
    if args.json:
        print(json.dumps(report(result), indent=2, allow_nan=False))
    else:
        print(text_report(result))
    return report_problems(command, read.problems)
