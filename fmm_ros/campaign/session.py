"""One campaign session as an independent task: its inputs -> analysis, fit, diagnosis, summary.

The work is the product's per-session pipeline, not a copy of it: the session's files are
read by the one input layer (`fmm_ros.workflows.inputs.read_inputs`: bags, lab files by
content, a mapping) and processed by `fmm_ros.workflows.session.process_records` (analysis, the
friction fit over the accepted hits, the model run for every hit, optionally the diagnosis),
exactly as `fmm report` processes a session, with the rig the session ran on: its normal
force sets mu = F_f / N.

The result (`SessionOutcome`) is plain data: it travels between processes and machines (Dask),
is cached as JSON, and feeds the campaign's statistics and tables. A session whose data the
pipeline refuses (a missing or damaged file, no hit, no accepted hit, a fit friction cannot
explain) is an outcome too, with status 'failed' and the reason; only a bug raises.
"""

from __future__ import annotations

import dataclasses
import glob
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from fmm_ros.core.physics.rig import FMM_RIG, Rig
from fmm_ros.core.signal.analysis import LevelSummary, Summary
from fmm_ros.errors import BadInputError, FmmError
from fmm_ros.io import sniff
from fmm_ros.io.labfiles import load_mapping
from fmm_ros.workflows.inputs import read_inputs
from fmm_ros.workflows.results import FrictionResult, hit_record, level_record
from fmm_ros.workflows.session import SessionOptions, SessionResult, process_records

OK = 'ok'
FAILED = 'failed'
RIG_COLUMNS: tuple[str, ...] = tuple(f.name for f in dataclasses.fields(Rig))
"""Table columns that set a session's rig constants (SI units, as Rig names them)."""
_GLOB_CHARACTERS = frozenset('*?[')
_NOT_DATA = frozenset({'.yaml', '.yml', '.md'})
"""Files of a session folder that are not its data: a mapping, notes."""


@dataclass(frozen=True)
class SessionSpec:
    """One row of a campaign: where its data are and the rig it ran on.

    `source` is a bag (directory, .mcap or .db3), a lab file (text, NPZ, MAT, TDMS, read by
    content: one impact each, or with the options' `continuous` a recording of several hits),
    a folder of them, or a glob. `mapping`: an `fmm import` mapping file for this session's
    lab files, in place of the campaign's.
    """

    session_id: str
    source: Path
    rig: Rig = FMM_RIG
    mapping: Path | None = None


def session_options(spec: SessionSpec, options: SessionOptions) -> SessionOptions:
    """The campaign's options with this session's rig, and its mapping file where it has one."""
    inputs = options.inputs
    if spec.mapping is not None:
        inputs = dataclasses.replace(inputs, mapping=load_mapping(spec.mapping))
    return dataclasses.replace(
        options,
        inputs=inputs,
        model=dataclasses.replace(options.model, rig=spec.rig),
        compare=False,  # the model run for every hit is drawn by the session report only
    )


def options_dict(options: SessionOptions) -> dict:
    """Session options as plain data (the cache key hashes it; the JSON shows it)."""
    return dataclasses.asdict(options)


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
    residual_rms_m_s: float = math.nan
    """RMS of measured minus fitted velocity of this hit at the session's mu [m/s]."""


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
    """Wall time of each step where it was computed [s]: read, and process (analysis, fit,
    the model run for every hit, diagnosis)."""
    cpu_seconds: float = math.nan
    """Processor time the session took where it was computed (user and system) [s]."""
    key: str = ''
    """The cache key (data and settings hash); empty when the inputs could not be hashed."""
    cached: bool = False
    internal_error: bool = False
    """The session failed through a fault in the code or the cluster, not its data: reported
    as an internal error, its traceback in the log (`tasks`)."""

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
            raise BadInputError(f'not a session result: {error}') from error


def session_files(spec: SessionSpec) -> list[Path]:
    """The files a session reads, in the order they are read; ValueError if there are none.

    A bag is one entry (its directory or file); a glob gives its matches; a folder every
    file in it but hidden ones, YAML and Markdown (a mapping, notes), sorted by name.
    """
    source = spec.source
    text = str(source)
    if any(character in text for character in _GLOB_CHARACTERS):
        paths = sorted(Path(match) for match in glob.glob(text))
        if not paths:
            raise BadInputError(f'{source}: no file matches')
        return paths
    if not source.exists():
        raise BadInputError(f'{source}: no such file or directory')
    if source.is_dir() and not _is_bag(source):
        paths = sorted(
            path
            for path in source.iterdir()
            if path.is_file()
            and not path.name.startswith('.')
            and path.suffix.lower() not in _NOT_DATA
        )
        if not paths:
            raise BadInputError(f'{source}: a folder with no bag or lab file in it')
        return paths
    return [source]


def _is_bag(folder: Path) -> bool:
    """Whether a folder is a bag (metadata.yaml, .mcap or .db3 in it) rather than files."""
    try:
        return sniff.file_kind(folder) == sniff.BAG
    except ValueError:
        return False


def compute_session(spec: SessionSpec, options: SessionOptions) -> SessionOutcome:
    """Run the session's pipeline; data the pipeline refuses give a 'failed' outcome."""
    seconds: dict[str, float] = {}
    timed = _Timer(seconds)
    cpu = time.process_time()
    try:
        mine = session_options(spec, options)  # reads its mapping file, if it has one
        read = timed('read', lambda: read_inputs(session_files(spec), mine.inputs))
        processed = timed(
            'process',
            lambda: process_records(
                read.records,
                mine,
                inputs=read.paths,
                problems=read.problems,
                notes=read.notes,
            ),
        )
    except (FmmError, OSError) as error:  # refused data; anything else is a bug (`tasks`)
        step = 'read' if 'process' not in seconds else 'analyse'
        outcome = SessionOutcome(FAILED, f'cannot {step}: {error}', seconds=seconds)
    else:
        outcome = _outcome(processed, mine.model.rig, seconds)
    return dataclasses.replace(outcome, cpu_seconds=time.process_time() - cpu)


def _outcome(processed: SessionResult, rig: Rig, seconds: dict[str, float]) -> SessionOutcome:
    """A processed session as plain data: failed when it has no fitted mu."""
    summary, friction = processed.summary, processed.friction
    common = dict(
        problems=tuple(processed.problems),
        hits=_hits(summary, friction),
        levels=tuple(_level_row(level) for level in summary.levels),
        linearity_slope=float(summary.linearity.slope),
        linearity_r2=float(summary.linearity.r2),
        normal_force_n=rig.normal_force_n,
        diagnosis=processed.diagnosis.to_dict() if processed.diagnosis else None,
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


def _hits(summary: Summary, friction: FrictionResult | None) -> tuple[HitSummary, ...]:
    """Every impact of the summary, with its own mu and residual where the fit gave them."""
    fitted = {}
    if friction is not None:
        residuals = friction.per_impact_residual_rms_m_s or (math.nan,) * len(friction.impact_ids)
        fitted = {
            impact_id: tuple(values)
            for impact_id, *values in zip(
                friction.impact_ids,
                friction.per_impact_mu,
                friction.per_impact_mu_stderr,
                residuals,
                strict=True,
            )
        }
    hits = []
    for impact in summary.impacts:
        mu, mu_stderr, residual = fitted.get(impact.impact_id, (math.nan,) * 3)
        hits.append(
            HitSummary(
                source=impact.source,
                **hit_record(impact),
                mu=float(mu),
                mu_stderr=float(mu_stderr),
                residual_rms_m_s=float(residual),
            )
        )
    return tuple(hits)


def _level_row(level: LevelSummary) -> LevelRow:
    """A level's scalars; coherence read at the peak-receptance frequency."""
    coherence = math.nan
    if level.frequency_hz.size and math.isfinite(level.natural_frequency_hz):
        peak_bin = int(np.argmin(np.abs(level.frequency_hz - level.natural_frequency_hz)))
        coherence = float(level.coherence[peak_bin])
    return LevelRow(**level_record(level), coherence_at_peak=coherence)
