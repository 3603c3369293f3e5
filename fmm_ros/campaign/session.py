"""One campaign session as an independent task: its inputs -> analysis, fit, diagnosis, summary.

The work is the product's per-session pipeline, not a copy of it: records are read as `fmm
analyze` reads them (bags through the analyzer's capture, per-impact CSV files, lab files
through `fmm import`'s mapping), analysed by the signal core, and fitted and diagnosed by
`fmm_ros.workflows.session` (`fit_accepted_impacts`, `diagnose_accepted_impacts`) with the
rig the session ran on: its normal force sets mu = F_f / N. `_analyse_fit_diagnose` is the
one place that calls the workflows.

The result (`SessionOutcome`) is plain data: it travels between processes and machines (Dask),
is cached as JSON, and feeds the campaign's statistics and tables. A session whose data the
pipeline refuses (a missing or damaged file, no hit, no accepted hit, a fit friction cannot
explain) is a result too, with status 'failed' and the reason; only a bug raises.
"""

from __future__ import annotations

import dataclasses
import glob
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from fmm_ros.cli.analyze import read_records
from fmm_ros.core.identify.friction import MU_BOUNDS
from fmm_ros.core.physics.rig import FMM_RIG, Rig
from fmm_ros.core.signal.analysis import (
    AnalysisConfig,
    LevelSummary,
    Summary,
    analyze_impact,
    summarize,
)
from fmm_ros.core.signal.capture import DEFAULT_CAPTURE, CaptureConfig, capture_impacts
from fmm_ros.core.signal.records import ImpactRecord
from fmm_ros.io.labfiles import ImportMapping, load_mapping, read_lab_files
from fmm_ros.workflows.replay import is_bag
from fmm_ros.workflows.session import (
    FrictionSummary,
    diagnose_accepted_impacts,
    fit_accepted_impacts,
)

OK = 'ok'
FAILED = 'failed'
RIG_COLUMNS: tuple[str, ...] = tuple(f.name for f in dataclasses.fields(Rig))
"""Table columns that set a session's rig constants (SI units, as Rig names them)."""
_GLOB_CHARACTERS = frozenset('*?[')


@dataclass(frozen=True)
class SessionSpec:
    """One row of a campaign: where its data are and the rig it ran on.

    `source` is a bag (directory, .mcap or .db3), a per-impact CSV file, a folder of them, or
    a glob of such files; with `mapping` (an `fmm import` mapping file) a lab file or folder
    of lab files (CSV, NPZ, MAT, TDMS) joined in name order as one continuous recording.
    """

    session_id: str
    source: Path
    rig: Rig = FMM_RIG
    mapping: Path | None = None


@dataclass(frozen=True)
class SessionSettings:
    """How every session of a campaign is analysed, fitted and diagnosed."""

    capture: CaptureConfig = DEFAULT_CAPTURE
    analysis: AnalysisConfig = AnalysisConfig()
    fit_damping: bool = False
    fit_initial_position: bool = False
    mu_bounds: tuple[float, float] = MU_BOUNDS
    diagnose: bool = False

    def to_dict(self) -> dict:
        """The settings as plain data (the cache key hashes this)."""
        return dataclasses.asdict(self)


@dataclass(frozen=True)
class HitSummary:
    """One impact of a session: the analyzer's verdict and numbers, and its own mu."""

    impact_id: int
    source: str
    level: str
    accepted: bool
    flags: tuple[str, ...]
    impulse_n_s: float
    peak_force_n: float
    contact_duration_s: float
    natural_frequency_hz: float
    peak_receptance_m_per_n: float
    mu: float = math.nan
    """This hit's own mu (c and the rest as in the joint fit); NaN unless fitted."""
    mu_stderr: float = math.nan


@dataclass(frozen=True)
class LevelRow:
    """One force level's averaged FRF, as scalars."""

    level: str
    count: int
    mean_impulse_n_s: float
    std_impulse_n_s: float
    mean_peak_force_n: float
    peak_receptance_m_per_n: float
    natural_frequency_hz: float
    coherence_at_peak: float
    """Coherence of the level's trials at the bin of its peak |receptance| [-]."""


@dataclass(frozen=True)
class SessionOutcome:
    """What one session gave (status 'ok': a fitted mu), or why it gave nothing ('failed')."""

    status: str
    reason: str = ''
    """Why the session failed; empty when it did not."""
    problems: tuple[str, ...] = ()
    """Damage found in a bag (what was readable was analysed)."""
    hits: tuple[HitSummary, ...] = ()
    levels: tuple[LevelRow, ...] = ()
    linearity_slope: float = math.nan
    """Peak |receptance| against mean impulse over the levels [m/(N^2*s)]."""
    linearity_r2: float = math.nan
    normal_force_n: float = math.nan
    """The normal force the fit ran with [N]."""
    mu: float = math.nan
    mu_stderr: float = math.nan
    consistency_chi2: float = math.nan
    """sum ((mu_hit - mu) / stderr_hit)^2 over the accepted hits."""
    consistency_p_value: float = math.nan
    damping_n_s_per_m: float = math.nan
    residual_rms_m_s: float = math.nan
    diagnosis: dict | None = None
    """`Diagnosis.to_dict()` of the accepted hits, when diagnosed."""
    diagnosis_failure: str = ''
    seconds: dict[str, float] = field(default_factory=dict)
    """Wall time of each step where it was computed: read, analyse, fit, diagnose."""
    cpu_seconds: float = math.nan
    """Processor time the session took where it was computed (user and system) [s]."""
    key: str = ''
    """The cache key (data and settings hash); empty when the inputs could not be hashed."""
    cached: bool = False

    @property
    def ok(self) -> bool:
        """Whether the session has a fitted mu."""
        return self.status == OK

    @property
    def accepted_hits(self) -> int:
        """Hits the analysis accepted."""
        return sum(hit.accepted for hit in self.hits)

    @property
    def consistency_dof(self) -> int:
        """Degrees of freedom of the consistency chi^2: accepted hits less one."""
        return max(self.accepted_hits - 1, 0)

    @property
    def birge_ratio(self) -> float:
        """chi^2 / dof of the hits around the session's mu (1 when they agree within errors)."""
        dof = self.consistency_dof
        return self.consistency_chi2 / dof if dof and math.isfinite(self.consistency_chi2) else 1.0

    @property
    def within_variance(self) -> float:
        """The session mu's variance for the campaign: stderr^2 x max(1, Birge ratio).

        Hits that disagree beyond their errors (run-in, a changing contact) make the session's
        mean less certain than the joint fit's error says; the Birge ratio scales it up.
        """
        return self.mu_stderr**2 * max(1.0, self.birge_ratio)

    def to_dict(self) -> dict:
        """Plain data (NaN stays a float; JSON writers decide how to spell it)."""
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, data: dict) -> SessionOutcome:
        """The inverse of `to_dict`; ValueError if the data are not a session result."""
        try:
            values = dict(data)
            values['problems'] = tuple(values.get('problems', ()))
            values['hits'] = tuple(
                HitSummary(**{**hit, 'flags': tuple(hit['flags'])}) for hit in values['hits']
            )
            values['levels'] = tuple(LevelRow(**level) for level in values['levels'])
            values['seconds'] = dict(values.get('seconds', {}))
            return cls(**values)
        except (KeyError, TypeError) as error:
            raise ValueError(f'not a session result: {error}') from error


def session_files(spec: SessionSpec) -> list[Path]:
    """The files a session reads, in the order they are read; ValueError if there are none.

    A bag is one entry (its directory or file); a folder gives its *.csv files (or, with a
    mapping, every file in it but the mapping), sorted by name; a glob its matches.
    """
    source = spec.source
    text = str(source)
    if any(character in text for character in _GLOB_CHARACTERS):
        paths = sorted(Path(match) for match in glob.glob(text))
        if not paths:
            raise ValueError(f'{source}: no file matches')
        return paths
    if not source.exists():
        raise ValueError(f'{source}: no such file or directory')
    if spec.mapping is None and is_bag(source):
        return [source]
    if source.is_dir():
        if spec.mapping is None:
            paths = sorted(source.glob('*.csv'))
        else:
            mapping = spec.mapping.resolve()
            paths = sorted(p for p in source.iterdir() if p.is_file() and p.resolve() != mapping)
        if not paths:
            kind = 'lab file' if spec.mapping else 'bag or per-impact CSV file'
            raise ValueError(f'{source}: a folder with no {kind} in it')
        return paths
    return [source]


def read_session(
    spec: SessionSpec, capture: CaptureConfig = DEFAULT_CAPTURE
) -> tuple[list[ImpactRecord], list[str]]:
    """The session's impact records, and the damage its bags showed (see `session_files`)."""
    paths = session_files(spec)
    if spec.mapping is None:
        return read_records(paths, capture=capture)
    mapping = ImportMapping.from_dict(load_mapping(spec.mapping))
    records: list[ImpactRecord] = []
    first_index = 0
    for recording in read_lab_files(paths, mapping):
        records += capture_impacts(
            recording.force_n,
            recording.velocity_m_s,
            recording.sample_rate_hz,
            capture,
            first_index,
            recording.full_scale_force_n,
            recording.full_scale_velocity_m_s,
        )
        first_index += len(recording.force_n)
    if not records:
        raise ValueError(
            f'{spec.source}: no impact in the recording (the force never reaches the '
            f'trigger level {capture.trigger_level_n:g} N)'
        )
    return [
        dataclasses.replace(r, source=f'{spec.source}@{r.trigger_sample_index}') for r in records
    ], []


def compute_session(spec: SessionSpec, settings: SessionSettings) -> SessionOutcome:
    """Run the session's pipeline; data the pipeline refuses give a 'failed' result."""
    seconds: dict[str, float] = {}
    cpu = time.process_time()
    try:
        records, problems = _Timer(seconds)('read', lambda: read_session(spec, settings.capture))
    except (ValueError, OSError) as error:  # bag, CSV and lab-file errors are ValueErrors
        result = SessionOutcome(FAILED, f'cannot read: {error}', seconds=seconds)
    else:
        result = _analyse_fit_diagnose(records, tuple(problems), spec.rig, settings, seconds)
    return dataclasses.replace(result, cpu_seconds=time.process_time() - cpu)


@dataclass(frozen=True)
class _Processed:
    """What the pipeline gave, under the names workflows' session results use."""

    summary: Summary
    friction: FrictionSummary | None
    fit_failure: str
    diagnosis: dict | None
    diagnosis_failure: str


def _analyse_fit_diagnose(
    records: Sequence[ImpactRecord],
    problems: tuple[str, ...],
    rig: Rig,
    settings: SessionSettings,
    seconds: dict[str, float],
) -> SessionOutcome:
    """The product's per-session pipeline over records, summarised as plain data."""
    return _outcome(_process(records, rig, settings, _Timer(seconds)), problems, rig, seconds)


def _process(
    records: Sequence[ImpactRecord], rig: Rig, settings: SessionSettings, timed: _Timer
) -> _Processed:
    """Analyse every record, fit mu over the accepted ones, diagnose them if asked.

    The one place that calls the workflows: what `fmm report` computes for a session.
    """
    summary = timed(
        'analyse',
        lambda: summarize(
            [
                analyze_impact(record, settings.capture, settings.analysis, impact_id=number)
                for number, record in enumerate(records)
            ],
            settings.analysis,
        ),
    )
    friction, fit_failure = None, ''
    try:
        friction = timed(
            'fit',
            lambda: fit_accepted_impacts(
                records,
                summary,
                rig=rig,
                fit_damping=settings.fit_damping,
                fit_initial_position=settings.fit_initial_position,
                mu_bounds=settings.mu_bounds,
            ),
        )
    except ValueError as error:  # FitError is one; so is 'no accepted impact to fit'
        fit_failure = str(error)
    diagnosis, diagnosis_failure = None, ''
    if settings.diagnose:
        try:
            diagnosis = timed(
                'diagnose',
                lambda: diagnose_accepted_impacts(
                    records, summary, rig=rig, fit_initial_position=settings.fit_initial_position
                ),
            ).diagnosis.to_dict()
        except ValueError as error:
            diagnosis_failure = str(error)
    return _Processed(summary, friction, fit_failure, diagnosis, diagnosis_failure)


def _outcome(
    processed: _Processed, problems: tuple[str, ...], rig: Rig, seconds: dict[str, float]
) -> SessionOutcome:
    """A processed session as plain data: failed when it has no fitted mu."""
    summary, friction = processed.summary, processed.friction
    common = dict(
        problems=problems,
        hits=_hits(summary, friction),
        levels=tuple(_level_row(level) for level in summary.levels),
        linearity_slope=float(summary.linearity.slope),
        linearity_r2=float(summary.linearity.r2),
        normal_force_n=rig.normal_force_n,
        diagnosis=processed.diagnosis,
        diagnosis_failure=processed.diagnosis_failure,
        seconds=seconds,
    )
    if friction is None:
        return SessionOutcome(FAILED, f'cannot fit mu: {processed.fit_failure}', **common)
    return SessionOutcome(
        OK,
        mu=friction.mu,
        mu_stderr=friction.mu_stderr,
        consistency_chi2=friction.consistency_chi2,
        consistency_p_value=friction.consistency_p_value,
        damping_n_s_per_m=friction.rig.damping_n_s_per_m,
        residual_rms_m_s=friction.residual_rms_m_s,
        **common,
    )


class _Timer:
    """Runs a step and adds its wall time to `seconds[name]`."""

    def __init__(self, seconds: dict[str, float]) -> None:
        self.seconds = seconds

    def __call__(self, name: str, step: Callable):
        clock = time.perf_counter()
        try:
            return step()
        finally:
            self.seconds[name] = time.perf_counter() - clock


def _hits(summary: Summary, friction: FrictionSummary | None) -> tuple[HitSummary, ...]:
    """Every impact of the summary, with its own mu where the fit gave one."""
    own = {}
    if friction is not None:
        own = {
            impact_id: (mu, stderr)
            for impact_id, mu, stderr in zip(
                friction.impact_ids,
                friction.per_impact_mu,
                friction.per_impact_mu_stderr,
                strict=True,
            )
        }
    return tuple(
        HitSummary(
            impact_id=impact.impact_id,
            source=impact.source,
            level=impact.level,
            accepted=impact.accepted,
            flags=tuple(impact.flags),
            impulse_n_s=float(impact.impulse_n_s),
            peak_force_n=float(impact.peak_force_n),
            contact_duration_s=float(impact.contact_duration_s),
            natural_frequency_hz=float(impact.natural_frequency_hz),
            peak_receptance_m_per_n=float(impact.peak_receptance_m_per_n),
            mu=float(own.get(impact.impact_id, (math.nan,))[0]),
            mu_stderr=float(own.get(impact.impact_id, (0.0, math.nan))[1]),
        )
        for impact in summary.impacts
    )


def _level_row(level: LevelSummary) -> LevelRow:
    """A level's scalars; coherence read at the peak-receptance frequency."""
    coherence = math.nan
    if level.frequency_hz.size and math.isfinite(level.natural_frequency_hz):
        peak_bin = int(np.argmin(np.abs(level.frequency_hz - level.natural_frequency_hz)))
        coherence = float(level.coherence[peak_bin])
    return LevelRow(
        level=level.level,
        count=level.count,
        mean_impulse_n_s=float(level.mean_impulse_n_s),
        std_impulse_n_s=float(level.std_impulse_n_s),
        mean_peak_force_n=float(level.mean_peak_force_n),
        peak_receptance_m_per_n=float(level.peak_receptance_m_per_n),
        natural_frequency_hz=float(level.natural_frequency_hz),
        coherence_at_peak=coherence,
    )
