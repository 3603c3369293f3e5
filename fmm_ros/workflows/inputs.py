"""What a lab hands the offline tools, as impact records: the one input layer.

`fmm analyze`, `fit`, `diagnose`, `identify-rig` and `report` (and `fmm campaign`) read their
INPUTs here, and only here. Each path is told apart by its content (`fmm_ros.io.sniff`):

- a bag (directory, .mcap or .db3): every impact the analyzer's own capture finds in its
  recorded streams (`fmm_ros.workflows.replay.bag_impact_records`); damage does not stop it,
  and is returned as problems. The decisions recorded about its hits are matched
  to the records by trigger sample, its session metadata is read
  (`fmm_ros.io.bags.station`), and, when asked, the levels its analyzer named
  (`fmm_ros.workflows.replay.recorded_levels`): all from the one open of the bag;
- a lab file (delimited text, NPZ, MATLAB v4-v7.3, TDMS): read by `fmm_ros.io.labfiles` with
  the channel mapping semantics of `fmm import` (a mapping file and flags, else what the file
  states: canonical names `time_s,force_n,velocity_m_s`, a units row, bracketed units, TDMS
  unit strings), converted to N and m/s. The whole file is one impact record, as the
  per-impact CSV files fmm writes, or with `continuous` one recording of several hits, cut as
  a bag's streams are.

All records share one sample rate (their FRFs are averaged on one grid) and are zero-padded to
the longest window. A full scale given here replaces a recorded one.

Impact ids are trigger times on one session axis (`schema.IMPACT_ID`): a bag's hits keep its
acquisition clock; inputs without one (lab files, bags written without a clock) are laid end
to end in the order given, each starting on the next ms after the previous one ended
(`on_session_axis`), so their hits' ids differ, and depend on that order.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from fmm_ros.core.signal.capture import DEFAULT_CAPTURE, CaptureConfig, capture_impacts
from fmm_ros.core.signal.config import AnalysisConfig, NominalLevel, SensorRanges
from fmm_ros.core.signal.judging import Decision, by_trigger
from fmm_ros.core.signal.records import ImpactRecord, on_session_axis, stable_impact_id
from fmm_ros.core.signal.response import as_measured
from fmm_ros.errors import BadInputError, FmmError
from fmm_ros.io import sniff
from fmm_ros.io.bags.reader import BagReader
from fmm_ros.io.bags.station import bag_decisions, bag_session_info
from fmm_ros.io.labfiles import LabRecording, read_lab_file
from fmm_ros.io.session_info import SessionInfo
from fmm_ros.io.textfiles import DETECT, TextFormat
from fmm_ros.workflows.replay import nominal_levels, reader_impact_records, recorded_levels

RATE_TOLERANCE = 1e-6
"""Relative difference in sample rate beyond which two inputs are not one measurement series."""

Progress = Callable[[str], None]
"""Told each step of a long job in words ('analysing hit 3/30'); the CLI shows them."""


@dataclass(frozen=True)
class InputOptions:
    """How the inputs are read.

    mapping: the channel mapping in its YAML form (`fmm_ros.io.labfiles`), any part left out
    that the files state themselves. text_format: delimiter, decimal, rows to skip, encoding
    of text files (detected when not given). capture: how impacts are cut from bags (and from
    continuous lab files). ranges: the sensors' ranges (`SensorRanges`, 0: as recorded),
    laid over every record's force and velocity ranges, a bag's too (a lab file's mapping
    also carries each quantity's own). continuous: each lab file is one recording of hits.
    level_tolerance_n: the tolerance [N] of the levels the bags' analyzer named, which are
    then read (`SessionInputs.levels`); None: they are not.
    """

    mapping: dict = field(default_factory=dict)
    text_format: TextFormat = DETECT
    capture: CaptureConfig = DEFAULT_CAPTURE
    ranges: SensorRanges = field(default_factory=SensorRanges)
    continuous: bool = False
    level_tolerance_n: float | None = None


DEFAULT_INPUTS = InputOptions()


@dataclass(frozen=True)
class SessionInputs:
    """The records of a session's inputs, in input order, and what reading them found."""

    records: list[ImpactRecord]
    problems: list[str]
    """What went wrong reading a damaged bag (what was readable is in records)."""
    notes: list[str]
    """How each lab file was read: format, channels, units, rate (the import report)."""
    paths: list[str]
    decisions: dict[int, Decision] = field(default_factory=dict)
    """The newest recorded decision about each hit, by impact id (bags only)."""
    session_info: dict[str, SessionInfo] = field(default_factory=dict)
    """Each bag's session metadata, by path (bags that hold some)."""
    levels: tuple[NominalLevel, ...] = ()
    """The levels the bags' analyzer named, by ascending force (see InputOptions)."""

    def grouped(self, analysis: AnalysisConfig) -> AnalysisConfig:
        """The analysis with the bags' recorded levels, where it names none of its own."""
        if analysis.levels or not self.levels:
            return analysis
        return dataclasses.replace(analysis, levels=self.levels)


def read_inputs(
    paths: Sequence[str | Path],
    options: InputOptions = DEFAULT_INPUTS,
    *,
    progress: Progress | None = None,
) -> SessionInputs:
    """Every input as impact records on one frequency grid (see the module doc).

    Raises ValueError naming the file for input that cannot be read as stated (no channel
    mapping, a non-uniform time column, a non-finite sample of a one-impact file), a bag or
    continuous file without an impact, and inputs of different sample rates.
    """
    if not paths:
        raise BadInputError('no inputs given')
    records: list[ImpactRecord] = []
    problems: list[str] = []
    notes: list[str] = []
    decisions: dict[int, Decision] = {}
    infos: dict[str, SessionInfo] = {}
    levels: dict[str, float] = {}
    axis_ms = 0  # where the next input without an acquisition clock starts
    for number, path in enumerate(map(Path, paths), 1):
        if progress:
            progress(f'reading {path.name} ({number}/{len(paths)})')
        if sniff.file_kind(path) == sniff.BAG:
            with BagReader(path, strict=False) as reader:
                found, damage = reader_impact_records(reader, options.capture)
                problems += [f'{path}: {problem}' for problem in damage]
                found, axis_ms = on_session_axis(_some(found, path, options.capture), axis_ms)
                records += found
                judged, lost = _bag_decisions(reader, found)
                decisions.update(judged)
                problems += [f'{path}: {problem}' for problem in lost]
                try:
                    info = bag_session_info(path, reader)
                except FmmError as error:
                    problems.append(f'{path}: {error}')
                    info = None
                if info is not None:
                    infos[str(path)] = info
                if options.level_tolerance_n is not None:
                    levels.update(recorded_levels(reader))
            continue
        recording = read_lab_file(path, options.mapping, options.text_format)
        notes += recording.report
        if options.continuous:
            found = _some(_cut(recording, options.capture), path, options.capture)
        else:
            found = [_one_impact(recording, options.capture)]
        found, axis_ms = on_session_axis(found, axis_ms)
        records += found
    return SessionInputs(
        _on_one_grid(records, options),
        problems,
        notes,
        [str(p) for p in paths],
        decisions,
        infos,
        nominal_levels(levels, options.level_tolerance_n) if levels else (),
    )


def _bag_decisions(
    reader: BagReader, records: list[ImpactRecord]
) -> tuple[dict[int, Decision], list[str]]:
    """A bag's recorded decisions under the impact ids of its records.

    Also a problem for each decision that found no hit (or was malformed).
    """
    recorded, problems = bag_decisions(reader)
    triggers = {record.trigger_sample_index: stable_impact_id(record) for record in records}
    judged, lost = by_trigger(recorded, triggers)
    problems += [
        f'{decision.describe()} names trigger sample {decision.trigger_sample_index}, where '
        'replay found no hit: not applied'
        for decision in lost
    ]
    return judged, problems


def _one_impact(recording: LabRecording, capture: CaptureConfig) -> ImpactRecord:
    """A lab file as one impact record; a non-finite sample is refused, naming its channel."""
    channels = (
        ('force', recording.force_n),
        (recording.response_quantity, recording.response),
    )
    for quantity, values in channels:
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            raise BadInputError(
                f'{recording.source}: {recording.channel_names[quantity]} is not finite '
                f'({values[bad[0]]}) at data row {bad[0] + 1} and {bad.size - 1} more row(s): '
                'a record with missing samples has no FRF (fmm import keeps them in a bag, '
                'where the impact over them is flagged)'
            )
    record = ImpactRecord(
        force_n=recording.force_n,
        velocity_m_s=recording.response,
        sample_rate_hz=recording.sample_rate_hz,
        force_full_scale_n=recording.full_scale_force_n,
        velocity_full_scale_m_s=recording.full_scale_response,
        source=str(recording.source),
    )
    return as_measured(record, recording.response_quantity, capture)


def _cut(recording: LabRecording, capture: CaptureConfig) -> list[ImpactRecord]:
    """Every impact of a continuous lab recording, tagged file@trigger as a bag's are."""
    return [
        as_measured(
            dataclasses.replace(
                record, source=f'{recording.source.name}@{record.trigger_sample_index}'
            ),
            recording.response_quantity,
            capture,
        )
        for record in capture_impacts(
            recording.force_n,
            recording.response,
            recording.sample_rate_hz,
            capture,
            force_full_scale_n=recording.full_scale_force_n,
            velocity_full_scale_m_s=recording.full_scale_response,
        )
    ]


def _some(records: list[ImpactRecord], path: Path, capture: CaptureConfig) -> list[ImpactRecord]:
    """The records of a recording of several hits, which must hold one at least."""
    if not records:
        raise BadInputError(
            f'{path}: no impact in the recorded streams (the force never reaches the trigger '
            f'level {capture.trigger_level_n:g} N)'
        )
    return records


def _on_one_grid(records: list[ImpactRecord], options: InputOptions) -> list[ImpactRecord]:
    """The records zero-padded to the longest window, full scales replaced where given.

    Raises ValueError when the inputs do not share one sample rate: their FRFs could not be
    averaged, and a mixed-up file is the likely cause.
    """
    rate = records[0].sample_rate_hz
    odd = [
        record for record in records if abs(record.sample_rate_hz - rate) > RATE_TOLERANCE * rate
    ]
    if odd:
        raise BadInputError(
            f'mismatched sample rates: {records[0].source} is sampled at {rate:.6g} '
            f'Hz but {odd[0].source} at {odd[0].sample_rate_hz:.6g} Hz'
        )
    window = max(record.window_samples for record in records)
    return [
        dataclasses.replace(
            record,
            window_samples=window,
            force_full_scale_n=options.ranges.force_full_scale_n or record.force_full_scale_n,
            velocity_full_scale_m_s=(
                options.ranges.velocity_full_scale_m_s or record.velocity_full_scale_m_s
            ),
        )
        for record in records
    ]
