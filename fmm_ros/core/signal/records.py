"""One impact's force and velocity samples, and the CSV file format that holds one impact.

`ImpactRecord` is what the streaming capture (`fmm_ros.core.signal.capture`) emits and what the
analysis (`fmm_ros.core.signal.analysis`) consumes, so a record read from a file, replayed from a
bag or captured live goes through exactly the same code. `read_impact_csv` is the one reader of the
per-impact CSV files (`time_s,force_n,velocity_m_s`) that `fmm analyze`, the fitter and the
diagnosis tools all take.
"""

from __future__ import annotations

import csv
import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from fmm_ros.core._checks import time_base
from fmm_ros.errors import BadInputError

CSV_COLUMNS: tuple[str, str, str] = ('time_s', 'force_n', 'velocity_m_s')

# A CSV time column whose steps differ from the mean step by more than this fraction is not
# uniformly sampled (a dropped sample shows up as a step of 2, far beyond it).
TIME_STEP_TOLERANCE = 1e-3

# A header longer than this is not one (a damaged file: its cells would all be held in memory).
MAX_HEADER_CHARS = 65_536

Gaps = tuple[tuple[int, int], ...]


@dataclass(frozen=True, eq=False)
class ImpactRecord:
    """Force [N] and velocity [m/s] of one impact, sample-aligned, with where they came from.

    Indices are counted on the acquisition's sample counter (`SampleBatch.first_sample_index`).
    `window_samples` is the nominal record length: a capture that ended the record early because
    the rig came to rest gives shorter arrays, and the FRF zero-pads them back to this length so
    every trial of a session shares one frequency grid. Samples that never arrived are NaN and
    listed in `force_gaps` / `velocity_gaps` as record-relative [start, stop) ranges.
    """

    force_n: np.ndarray
    velocity_m_s: np.ndarray
    sample_rate_hz: float
    record_start_sample_index: int = 0
    # None: not known yet; the analysis finds it with the capture's trigger rule.
    trigger_sample_index: int | None = None
    window_samples: int = 0
    # Sensor full-scale ranges [N], [m/s]; 0 means unknown (no clipping check).
    force_full_scale_n: float = 0.0
    velocity_full_scale_m_s: float = 0.0
    force_gaps: Gaps = field(default=())
    velocity_gaps: Gaps = field(default=())
    # File name or other origin, for reports.
    source: str = ''
    # The acquisition was restarted (a new one recognised) before the record was complete:
    # its tail never came and is listed as a gap.
    interrupted: bool = False
    # What the response sensor measured (`fmm_ros.core.signal.response`): 'velocity' (then
    # velocity_m_s is the measurement and response None), or 'acceleration' [m/s^2] or
    # 'displacement' [m], whose samples are in response, velocity_m_s being their velocity.
    response_quantity: str = 'velocity'
    response: np.ndarray | None = None
    # The response sensor's range in SI units of response_quantity (0: unknown), when that
    # is not velocity (a velocity sensor's is velocity_full_scale_m_s).
    response_full_scale: float = 0.0
    # The acquisition began after the record's start (mid-hit, or inside the pre-trigger).
    truncated_start: bool = False
    # Time of sample 0 of the record's acquisition [s] by its clock (None: no clock); with
    # the trigger index it names the impact for good (`stable_impact_id`).
    acquisition_origin_s: float | None = None

    def __post_init__(self) -> None:
        force = np.asarray(self.force_n, dtype=float)
        velocity = np.asarray(self.velocity_m_s, dtype=float)
        if force.ndim != 1 or velocity.ndim != 1:
            raise BadInputError('force and velocity must be one-dimensional sample arrays')
        if force.shape != velocity.shape:
            raise BadInputError(
                f'force has {force.size} samples but velocity has {velocity.size}: '
                'the two channels of a record must be sample-aligned'
            )
        if force.size < 2:
            raise BadInputError(f'a record needs at least 2 samples, got {force.size}')
        if not np.isfinite(self.sample_rate_hz) or self.sample_rate_hz <= 0:
            raise BadInputError(f'sample_rate_hz must be positive, got {self.sample_rate_hz}')
        window = self.window_samples or force.size
        if window < force.size:
            raise BadInputError(
                f'window_samples ({window}) is shorter than the record ({force.size} samples)'
            )
        offset = self.trigger_offset
        if offset is not None and not 0 <= offset < force.size:
            raise BadInputError(
                f'trigger sample {self.trigger_sample_index} lies outside the record '
                f'({self.record_start_sample_index} + {force.size} samples)'
            )
        object.__setattr__(self, 'force_n', force)
        object.__setattr__(self, 'velocity_m_s', velocity)
        object.__setattr__(self, 'window_samples', int(window))
        if self.response is not None:
            response = np.asarray(self.response, dtype=float)
            if response.shape != force.shape:
                raise BadInputError(
                    f'the {self.response_quantity} response has {response.size} samples but '
                    f'force has {force.size}: the channels of a record must be sample-aligned'
                )
            object.__setattr__(self, 'response', response)

    @property
    def measured(self) -> tuple[np.ndarray, float]:
        """The response channel as the sensor measured it, and its range (0: unknown)."""
        if self.response is None:
            return self.velocity_m_s, self.velocity_full_scale_m_s
        return self.response, self.response_full_scale

    @property
    def trigger_offset(self) -> int | None:
        """Trigger position inside the arrays [samples], or None when not known."""
        if self.trigger_sample_index is None:
            return None
        return self.trigger_sample_index - self.record_start_sample_index


IMPACT_ID_MODULUS = 2**32
"""Impact ids are ImpactResult.impact_id, a uint32: milliseconds wrap after 49.7 days."""


def stable_impact_id(record: ImpactRecord) -> int:
    """The impact's id: its trigger's acquisition time in ms, modulo 2**32.

    Derived from the trigger's sample index and the acquisition's clock (the time of its
    sample 0, `acquisition_origin_s`; without a clock, ms since sample 0), never a counter:
    an analyzer restarted mid-session, `fmm replay` of the bag and the live analyzer give one
    hit the same id, and two hits never share one (triggers lie at least `min_spacing_s`,
    >= 1 ms, apart; another acquisition has another clock).
    """
    if record.trigger_sample_index is None:
        raise BadInputError('an impact id needs the trigger sample index')
    trigger_ms = round(record.trigger_sample_index * 1000 / record.sample_rate_hz)
    origin_ms = round(record.acquisition_origin_s * 1000) if record.acquisition_origin_s else 0
    return (origin_ms + trigger_ms) % IMPACT_ID_MODULUS


def duration_ms(records: Sequence[ImpactRecord]) -> int:
    """How long an input of these records lasts on a session's axis, to its last sample [ms].

    The next input without a clock starts this long after this one (on the ms after its
    last sample), so their triggers' ids (`stable_impact_id`) differ.
    """
    end_s = max(
        (record.record_start_sample_index + record.force_n.size) / record.sample_rate_hz
        for record in records
    )
    return math.ceil(end_s * 1000) + 1


def on_session_axis(
    records: Sequence[ImpactRecord], start_ms: int
) -> tuple[list[ImpactRecord], int]:
    """One input's records with those lacking an acquisition clock started at start_ms.

    Returns them and where the next such input starts: the ms after this one's last sample
    (`duration_ms`; start_ms again when all its records have a clock of their own).
    """
    clockless = [record for record in records if record.acquisition_origin_s is None]
    if not clockless:
        return list(records), start_ms
    placed = [
        record
        if record.acquisition_origin_s is not None
        else dataclasses.replace(record, acquisition_origin_s=start_ms / 1000)
        for record in records
    ]
    return placed, start_ms + duration_ms(clockless)


def read_impact_csv(path: str | Path) -> ImpactRecord:
    """Read one impact from a CSV file with the header `time_s,force_n,velocity_m_s`.

    Columns may come in any order and extra columns are ignored. The sample rate is taken from
    the time column, which must be uniformly spaced. Raises ValueError naming the file and the
    problem for a missing column, unparsable or non-finite values, or a non-uniform time step,
    so a bad file is refused instead of turning into a wrong FRF.
    """
    path = Path(path)
    try:
        with path.open(newline='', encoding='utf-8') as handle:
            line = handle.readline(MAX_HEADER_CHARS + 1)
        header = next(csv.reader([line]), None) if line else None
    except (UnicodeDecodeError, csv.Error) as error:
        raise BadInputError(f'{path}: not a text CSV file ({error})') from None
    if len(line) > MAX_HEADER_CHARS:
        raise BadInputError(
            f'{path}: the first line is longer than {MAX_HEADER_CHARS} characters: not the '
            f'header {",".join(CSV_COLUMNS)}'
        )
    if header is None:
        raise BadInputError(f'{path}: empty file, expected a header {",".join(CSV_COLUMNS)}')
    names = [name.strip() for name in header]
    missing = [name for name in CSV_COLUMNS if name not in names]
    if missing:
        raise BadInputError(
            f'{path}: missing column(s) {", ".join(missing)}; the header must name '
            f'{",".join(CSV_COLUMNS)}'
        )
    columns = [names.index(name) for name in CSV_COLUMNS]
    try:
        data = np.loadtxt(path, delimiter=',', skiprows=1, usecols=columns, ndmin=2)
    except ValueError as error:
        raise BadInputError(f'{path}: {error}') from None
    if data.shape[0] < 2:
        raise BadInputError(f'{path}: needs at least 2 samples, found {data.shape[0]}')
    for column, name in enumerate(CSV_COLUMNS):
        bad = np.flatnonzero(~np.isfinite(data[:, column]))
        if bad.size:
            raise BadInputError(
                f'{path}: {name} is not finite ({data[bad[0], column]}) at data row '
                f'{bad[0] + 1} and {bad.size - 1} more row(s)'
            )
    sample_rate_hz = time_base(data[:, 0], f'{path}: time_s', TIME_STEP_TOLERANCE).sample_rate_hz
    return ImpactRecord(
        force_n=np.ascontiguousarray(data[:, 1]),
        velocity_m_s=np.ascontiguousarray(data[:, 2]),
        sample_rate_hz=sample_rate_hz,
        source=str(path),
    )


def write_impact_csv(
    path: str | Path, force_n: np.ndarray, velocity_m_s: np.ndarray, sample_rate_hz: float
) -> None:
    """Write one impact in the format `read_impact_csv` reads, samples at full precision."""
    force = np.asarray(force_n, dtype=float)
    velocity = np.asarray(velocity_m_s, dtype=float)
    if force.shape != velocity.shape or force.ndim != 1:
        raise BadInputError('force and velocity must be one-dimensional arrays of equal length')
    time_s = np.arange(force.size) / sample_rate_hz
    np.savetxt(
        path,
        np.column_stack((time_s, force, velocity)),
        delimiter=',',
        header=','.join(CSV_COLUMNS),
        comments='',
        fmt=('%.9f', '%.17g', '%.17g'),
    )
