"""The run of a fitting subcommand (fit, identify-rig, and diagnose): inputs in, verdict out.

Inputs are read by the one input layer (`fmm_ros.workflows.inputs`: lab files of one impact,
bags of many); fit and diagnose take only the hits the quality flags accept, naming the
others (`select_impacts`; --include-flagged takes them too). A fit the data refuse
(`FitError`, or no clean hit) exits 1 with its reason, as JSON with --json, kept apart from
bad input or flags (2, from the `fmm` entry point); a damaged bag's problems are warnings
after the result, and also exit 1, as in `fmm analyze`.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from fmm_ros.cli import options

if TYPE_CHECKING:
    from fmm_ros.core.signal.capture import CaptureConfig
    from fmm_ros.core.signal.config import AnalysisConfig
    from fmm_ros.core.signal.records import ImpactRecord
    from fmm_ros.workflows.inputs import InputOptions

Fit = Callable[[Mapping[int, 'ImpactRecord'], Sequence[int], Callable[[str], None]], Any]


@dataclass(frozen=True)
class FitRequest:
    """What a fitting subcommand was asked, in the workflows' own types (no Namespace).

    paths and inputs: what is read and how; capture and analysis: how hits are cut and
    judged (analysis None: every record is taken, as identify-rig does: free decays hold no
    hit); include_flagged, chain_starts: `select_records` and `ImpactSelection.chained`;
    json, quiet: how the answer is shown.
    """

    command: str
    paths: tuple[Path, ...]
    inputs: InputOptions
    capture: CaptureConfig
    analysis: AnalysisConfig | None
    include_flagged: bool = False
    chain_starts: bool = False
    json: bool = False
    quiet: bool = False

    @classmethod
    def from_args(cls, command: str, args: argparse.Namespace) -> FitRequest:
        """The request of a fitting subcommand's flags (its hit options, where it has them)."""
        from fmm_ros.core.signal.capture import CaptureConfig

        selecting = hasattr(args, 'include_flagged')
        capture, analysis = options.analysis_configs(args) if selecting else (CaptureConfig(), None)
        return cls(
            command,
            tuple(args.inputs),
            options.input_options(args, capture),
            capture,
            analysis,
            include_flagged=selecting and args.include_flagged,
            chain_starts=getattr(args, 'chain_starts', False),
            json=args.json,
            quiet=args.quiet,
        )


def fit_and_report(
    request: FitRequest,
    fit: Fit,
    report: Callable[[Any], dict],
    text_report: Callable[[Any], str],
) -> int:
    """Read the inputs, pick the hits, fit them, print the result (or why there is none).

    fit(records, impact_ids, progress) fits records[i] for i in impact_ids. A command with
    the hit-selection options (fit, diagnose) takes the hits `select_impacts` takes (the
    accepted ones; all with --include-flagged), records by impact id, and names the others
    after the result; one without (identify-rig: free decays hold no hit, so no impact id)
    takes every record, by position.
    """
    from fmm_ros.cli.progress import StatusLine, report_problems
    from fmm_ros.errors import FitError, SelectionError
    from fmm_ros.workflows.inputs import read_inputs
    from fmm_ros.workflows.results import selection_dict
    from fmm_ros.workflows.session import impact_ids, select_records

    command = request.command
    selection = None
    with StatusLine(quiet=request.quiet) as progress:
        read = read_inputs(request.paths, request.inputs, progress=progress)
        records = read.records
        try:
            if request.analysis is not None:
                selection = select_records(
                    records,
                    request.capture,
                    read.grouped(request.analysis),
                    include_flagged=request.include_flagged,
                    decisions=read.decisions,
                    progress=progress,
                )
            if selection:
                selection.chained(request.chain_starts)
            if selection:
                ids = selection.chosen
                chosen = dict(zip(impact_ids(records, request.capture), records, strict=True))
            else:
                ids, chosen = tuple(range(len(records))), dict(enumerate(records))
            result = fit(chosen, ids, progress)
        except (FitError, SelectionError) as failure:
            result = failure
    if isinstance(result, FitError | SelectionError):
        report_problems(command, read.problems)
        if isinstance(result, SelectionError):
            reason, source, selection = 'no_clean_impact', None, result.selection
        else:
            reason, source = result.reason, result.source or None
        if request.json:
            print(
                json.dumps(
                    {'error': reason, 'message': str(result), 'file': source}
                    | selection_dict(selection)
                )
            )
        else:
            print(f'fmm {command}: cannot fit ({reason}): {result}', file=sys.stderr)
        return 1
    if request.json:
        print(json.dumps(report(result) | selection_dict(selection), indent=2, allow_nan=False))
    else:
        print(text_report(result))
        if selection is not None and selection.note:
            print(selection.note)
    return report_problems(command, read.problems)
