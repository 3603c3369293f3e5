"""One session's inputs through analysis, the friction fit and the diagnosis: the pipeline.

`process_session(paths, options)` is everything `fmm report` computes (and `fmm campaign`
runs per session): read the inputs (`fmm_ros.workflows.inputs`), analyse every impact
(impulse, flags, FRFs, levels, linearity), fit mu over the impacts the signal core's
`select_impacts` takes (the accepted ones, flagged ones left out and named, unless
include_flagged), as the fitter node and `fmm fit` take them, optionally diagnose them, and
run the resulting model for every hit. Its
`SessionResult` holds the records and every result, and `to_dict()` is its JSON. The report
(`fmm_ros.report`) draws a SessionResult and computes nothing. `process_records` does the same for
records already in hand (the demo, from its bag) and takes a fit made elsewhere (the fitter
service's answer) instead of fitting again.

A fit or diagnosis the data refuse does not stop the pipeline: the result says why.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from fmm_ros.constants import MISFIT_BAND_LIMIT_HZ
from fmm_ros.core._threads import thread_imap
from fmm_ros.core.diagnose.result import Diagnosis
from fmm_ros.core.diagnose.workflow import diagnose
from fmm_ros.core.identify.friction import fit_friction
from fmm_ros.core.identify.spec import FRICTION_FIT, MU_BOUNDS, FitSpec
from fmm_ros.core.physics.rig import FMM_RIG, Rig
from fmm_ros.core.signal.analysis import (
    AnalysisConfig,
    ImpactAnalysis,
    ImpactSelection,
    Summary,
    analyze_impact,
    select_impacts,
    summarize,
)
from fmm_ros.core.signal.capture import DEFAULT_CAPTURE, CaptureConfig, with_trigger
from fmm_ros.core.signal.judging import Decision
from fmm_ros.core.signal.records import ImpactRecord, on_session_axis, stable_impact_id
from fmm_ros.errors import BadInputError, FitError, SelectionError
from fmm_ros.io.session_info import SessionInfo
from fmm_ros.workflows.inputs import DEFAULT_INPUTS, InputOptions, Progress, read_inputs
from fmm_ros.workflows.model import ModelComparison, ModelOverlay, compare_model
from fmm_ros.workflows.results import (
    FrictionResult,
    analysis_dict,
    diagnosis_dict,
    json_safe,
    selection_dict,
)


@dataclass(frozen=True)
class FitOptions:
    """The model a friction fit (and a diagnosis) uses, and what it frees besides mu."""

    rig: Rig = FMM_RIG
    fit_damping: bool = False
    fit_initial_position: bool = True
    """Fit each record's start (in a session a hit finds the rig where friction left it)."""
    chain_starts: bool = False
    """Chain the starts instead (`FitSpec.chain_starts`): one continuous session in hit order."""
    mu_bounds: tuple[float, float] = MU_BOUNDS
    misfit: str = 'time'
    band_limit_hz: float = MISFIT_BAND_LIMIT_HZ

    def spec(self) -> FitSpec:
        """The FitSpec of a session's fit: `fit_friction`'s default with these choices."""
        return FRICTION_FIT.but(
            fit_damping=self.fit_damping,
            fit_initial_position=self.fit_initial_position,
            chain_starts=self.chain_starts,
            mu_bounds=self.mu_bounds,
            misfit=self.misfit,
            band_limit_hz=self.band_limit_hz,
        )


DEFAULT_FIT = FitOptions()


@dataclass(frozen=True)
class SessionOptions:
    """How a session is processed: inputs, analysis, fit, diagnosis.

    mu: draw the model with this mu instead of fitting one; fit=False: neither fit nor draw.
    compare: run the model for every hit and analyse its velocity as the measurement's (what
    the report draws; a fifth of a session's work, which `fmm campaign` draws none of).
    include_flagged: fit and diagnose the impacts the flags reject too (`select_impacts`).
    """

    inputs: InputOptions = DEFAULT_INPUTS
    analysis: AnalysisConfig = field(default_factory=AnalysisConfig)
    model: FitOptions = DEFAULT_FIT
    mu: float | None = None
    fit: bool = True
    diagnose: bool = False
    compare: bool = True
    include_flagged: bool = False


@dataclass(frozen=True)
class SessionDiagnosis:
    """A diagnosis (`fmm_ros.core.diagnose`) of these impacts of the session, in this order."""

    diagnosis: Diagnosis
    impact_ids: tuple[int, ...]
    rig: Rig = FMM_RIG
    """The rig constants the diagnosis ran with."""

    def __post_init__(self) -> None:
        if len(self.diagnosis.base_residuals_m_s) != len(self.impact_ids):
            raise BadInputError(
                f'the diagnosis covers {len(self.diagnosis.base_residuals_m_s)} '
                f'impacts but {len(self.impact_ids)} impact ids were given'
            )

    def to_dict(self) -> dict:
        """`diagnosis_dict` and the impacts it covers."""
        return {**diagnosis_dict(self.diagnosis), 'impact_ids': list(self.impact_ids)}


@dataclass(frozen=True, eq=False)
class SessionResult:
    """A session processed: its records and everything computed from them.

    records[i] is impact i of summary (its position; `impact_id` is the hit's trigger time,
    `records_by_id` maps one to the other). friction/diagnosis are None when not tried or refused
    (then fit_failure/diagnosis_failure say why). comparison: the model (fitted or given) run
    for every hit, None without a model.
    """

    records: list[ImpactRecord]
    summary: Summary
    capture: CaptureConfig
    analysis: AnalysisConfig
    friction: FrictionResult | None = None
    fit_failure: str = ''
    diagnosis: SessionDiagnosis | None = None
    diagnosis_failure: str = ''
    comparison: ModelComparison | None = None
    selection: ImpactSelection | None = None
    """Which impacts the fit and diagnosis took, and which they left out (flagged)."""
    inputs: list[str] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)
    """What went wrong reading the inputs (a damaged bag): shown, never dropped."""
    notes: list[str] = field(default_factory=list)
    """How each lab file was read (format, channels, units, rate)."""
    session_info: dict[str, SessionInfo] = field(default_factory=dict)
    """Each bag's session metadata (who, pin, counterface, lubricant, load...), by path."""

    def __post_init__(self) -> None:
        if len(self.summary.impacts) != len(self.records):
            raise BadInputError(
                f'the summary names {len(self.summary.impacts)} impact(s) but '
                f'{len(self.records)} record(s) were given (impact i of it is record i)'
            )
        known = {impact.impact_id for impact in self.summary.impacts}
        for name, result in (('friction fit', self.friction), ('diagnosis', self.diagnosis)):
            unknown = sorted(set(result.impact_ids) - known) if result is not None else []
            if unknown:
                raise BadInputError(f'the {name} names impact(s) {unknown} the session lacks')

    @property
    def records_by_id(self) -> dict[int, ImpactRecord]:
        """Each record under its impact's id."""
        return _by_id(self.summary, self.records)

    @property
    def model(self) -> ModelOverlay | None:
        """The model drawn over the measurement, if any."""
        return self.comparison.model if self.comparison else None

    def to_dict(self) -> dict:
        """The session as JSON: inputs, problems, analysis, fit and diagnosis (or why not)."""
        model = self.model
        return json_safe(
            {
                'inputs': self.inputs,
                'problems': self.problems,
                **analysis_dict(self.summary),
                'fit': self.friction.to_dict() if self.friction else None,
                'fit_failure': self.fit_failure or None,
                'diagnosis': self.diagnosis.to_dict() if self.diagnosis else None,
                'diagnosis_failure': self.diagnosis_failure or None,
                **selection_dict(self.selection),
                'model': {'mu': model.mu, 'source': model.source} if model else None,
                'residual_rms_m_s': {
                    str(i): hit.residual_rms_m_s for i, hit in self.comparison.hits.items()
                }
                if self.comparison
                else {},
            }
        )


def analyse(
    records: Sequence[ImpactRecord],
    capture: CaptureConfig = DEFAULT_CAPTURE,
    analysis: AnalysisConfig | None = None,
    *,
    decisions: Mapping[int, Decision] | None = None,
    progress: Progress | None = None,
    threads: int | None = None,
) -> Summary:
    """The signal core's verdict on every record, impact i being record i.

    Each impact's id is its trigger time (`impact_ids`). decisions (by impact id) decide
    which hits the level averages take (`summarize`).
    The records are analysed side by side in threads, as a replay analyses them (`threads`,
    default the cores there are: `thread_imap`); each alone, so the results are the same
    whatever the count.
    """
    analysis = analysis or AnalysisConfig()

    ids = impact_ids(records, capture)

    def numbered() -> Iterator[tuple[int, ImpactRecord]]:
        for number, record in enumerate(records):
            if progress:  # on this thread, as the hit goes to be analysed
                progress(f'analysing hit {number + 1}/{len(records)}')
            yield ids[number], record

    def analysed(item: tuple[int, ImpactRecord]) -> ImpactAnalysis:
        return analyze_impact(item[1], capture, analysis, impact_id=item[0])

    return summarize(list(thread_imap(analysed, numbered(), threads)), analysis, decisions)


def _by_id(summary: Summary, records: Sequence[ImpactRecord]) -> dict[int, ImpactRecord]:
    """records[i], impact i of summary, under that impact's id."""
    return {
        impact.impact_id: record for impact, record in zip(summary.impacts, records, strict=True)
    }


def impact_ids(
    records: Sequence[ImpactRecord], capture: CaptureConfig = DEFAULT_CAPTURE
) -> list[int]:
    """Each record's impact id: its trigger's time on its session's axis (`stable_impact_id`).

    Records still without an acquisition clock (records in hand, not from `read_inputs`) are
    laid on the axis as inputs, each after the one before, as lab files would be. Records that
    follow each other on one sample axis (each starting after the last one ended) are one
    input, as a capture of one stream gives them, so they keep the ids the analyzer gave them
    live; a record starting before the last one ended (a file's, at sample 0) is another.
    Raises BadInputError naming both inputs when two hits would share an id: merged, one
    would take the other's decisions, fit and report entries.
    """
    placed: list[ImpactRecord] = []
    axis_ms = 0  # where the next clockless input starts
    for one_input in _inputs_in_hand(records):
        one_input, axis_ms = on_session_axis(one_input, axis_ms)
        placed += one_input
    ids: list[int] = []
    seen: dict[int, str] = {}
    for record in placed:
        impact_id = stable_impact_id(with_trigger(record, capture))
        if impact_id in seen:
            raise BadInputError(
                f'{seen[impact_id] or "a record"} and {record.source or "a record"} trigger at '
                f"one time on the session's axis (impact id {impact_id}): give each input once "
                '(inputs without an acquisition clock are laid end to end in one session)'
            )
        seen[impact_id] = record.source
        ids.append(impact_id)
    return ids


def _inputs_in_hand(records: Sequence[ImpactRecord]) -> list[list[ImpactRecord]]:
    """Records in hand cut into the inputs `on_session_axis` places one after another.

    A new input starts at each clockless record that does not follow the last clockless one
    (`_follows`); a record with a clock joins the current input, which leaves it as it is.
    """
    inputs: list[list[ImpactRecord]] = [[]]
    last: ImpactRecord | None = None  # the last clockless record
    for record in records:
        if record.acquisition_origin_s is None:
            if last is not None and not _follows(record, last):
                inputs.append([])
            last = record
        inputs[-1].append(record)
    return inputs


def _follows(record: ImpactRecord, last: ImpactRecord) -> bool:
    """Whether record lies after last on one sample axis (one stream's capture)."""
    return (
        record.sample_rate_hz == last.sample_rate_hz
        and record.record_start_sample_index >= last.record_start_sample_index + last.force_n.size
    )


def select_records(
    records: Sequence[ImpactRecord],
    capture: CaptureConfig = DEFAULT_CAPTURE,
    analysis: AnalysisConfig | None = None,
    *,
    include_flagged: bool = False,
    decisions: Mapping[int, Decision] | None = None,
    progress: Progress | None = None,
) -> ImpactSelection:
    """The impacts of records a fit takes: `select_impacts` over their analysis.

    decisions: the newest recorded decision about each hit, by impact id (`read_inputs`).
    Raises FitError (reason 'no_hit') for a record without a hit, which has nothing to judge
    or fit, and `SelectionError` (a ValueError) naming the flagged records when none is clean.
    """
    for record in records:
        try:
            with_trigger(record, capture)
        except ValueError as error:
            raise FitError('no_hit', f'no hit: {error}', record.source) from None
    summary = analyse(records, capture, analysis, decisions=decisions, progress=progress)
    return select_impacts(summary, include_flagged=include_flagged, decisions=decisions)


def fit_impacts(
    records: Mapping[int, ImpactRecord],
    impact_ids: Sequence[int],
    options: FitOptions = DEFAULT_FIT,
    *,
    progress: Progress | None = None,
) -> FrictionResult:
    """One mu (and each impact's own) over records[i] for i in impact_ids, as the fitter does.

    records: the session's records by impact id (`SessionResult.records_by_id`).

    Raises FitError (a ValueError) when friction cannot explain them.
    """
    fit = fit_friction(
        [records[i] for i in impact_ids], options.spec(), rig=options.rig, progress=progress
    )
    return FrictionResult.from_fit(fit, impact_ids)


def diagnose_impacts(
    records: Mapping[int, ImpactRecord],
    impact_ids: Sequence[int],
    options: FitOptions = DEFAULT_FIT,
    *,
    progress: Progress | None = None,
) -> SessionDiagnosis:
    """The diagnose workflow over records[i] for i in impact_ids, as the fitter node runs it.

    records: the session's records by impact id (`SessionResult.records_by_id`).

    Raises FitError (a ValueError) when the base model cannot be fitted at all.
    """
    if progress:
        progress(f'diagnosing {len(impact_ids)} impacts (base fit, then each candidate effect)')
    return SessionDiagnosis(
        diagnose(
            [records[i] for i in impact_ids],
            rig=options.rig,
            fit_initial_position=options.fit_initial_position,
            chain_starts=options.chain_starts,
            friction_spec=options.spec(),
            progress=progress,
        ),
        tuple(impact_ids),
        options.rig,
    )


def process_records(
    records: Sequence[ImpactRecord],
    options: SessionOptions | None = None,
    *,
    friction: FrictionResult | None = None,
    fit_failure: str = '',
    inputs: Sequence[str] = (),
    problems: Sequence[str] = (),
    notes: Sequence[str] = (),
    decisions: Mapping[int, Decision] | None = None,
    session_info: Mapping[str, SessionInfo] | None = None,
    progress: Progress | None = None,
) -> SessionResult:
    """Analyse records, fit mu over the accepted ones (or take the fit given), diagnose.

    decisions: the newest decision about each hit, by impact id (recorded by the station): they
    overrule the flags in `select_impacts`. session_info: each bag's metadata, shown. friction:
    a fit made elsewhere (the fitter service's answer, under the same ids), drawn as it is
    instead of fitting; fit_failure: why that fit was refused. options.mu draws a given mu instead;
    options.fit = False draws no model. Fit and diagnosis take the impacts `select_impacts`
    takes (options.include_flagged), and the result's selection names those left out.
    """
    options = options or SessionOptions()
    records = list(records)
    if not records:
        raise BadInputError('a session needs at least one impact record')
    capture = options.inputs.capture
    summary = analyse(records, capture, options.analysis, decisions=decisions, progress=progress)
    by_id = _by_id(summary, records)
    selection, refusal = _selection_and_refusal(summary, options, decisions)
    if friction is None and not fit_failure and options.mu is None and options.fit:
        try:
            friction = fit_impacts(
                by_id, _chosen(selection, refusal), options.model, progress=progress
            )
        except ValueError as error:  # FitError is one: the result says why there is no fit
            fit_failure = str(error)
    diagnosis, diagnosis_failure = None, ''
    if options.diagnose:
        try:
            diagnosis = diagnose_impacts(
                by_id, _chosen(selection, refusal), options.model, progress=progress
            )
        except ValueError as error:
            diagnosis_failure = str(error)
    model = (
        ModelOverlay(options.mu, 'given', options.model.rig)
        if options.mu is not None
        else overlay_of(friction)
    )
    comparison = (
        compare_model(records, summary, model, capture, options.analysis, progress=progress)
        if model is not None and options.compare
        else None
    )
    return SessionResult(
        records,
        summary,
        capture,
        options.analysis,
        friction,
        fit_failure,
        diagnosis,
        diagnosis_failure,
        comparison,
        selection,
        list(inputs),
        list(problems),
        list(notes),
        dict(session_info or {}),
    )


def process_session(
    paths: Sequence[str | Path],
    options: SessionOptions | None = None,
    *,
    progress: Progress | None = None,
) -> SessionResult:
    """One session's input files (lab files, bags) through `process_records`."""
    options = options or SessionOptions()
    read = read_inputs(paths, options.inputs, progress=progress)
    return process_records(
        read.records,
        dataclasses.replace(options, analysis=read.grouped(options.analysis)),
        inputs=read.paths,
        problems=read.problems,
        notes=read.notes,
        decisions=read.decisions,
        session_info=read.session_info,
        progress=progress,
    )


def _selection_and_refusal(
    summary: Summary, options: SessionOptions, decisions: Mapping[int, Decision] | None
) -> tuple[ImpactSelection, str]:
    """The impacts `select_impacts` takes, and why none can be fitted ('' when they can).

    A refusal (no clean impact, or a chain the model cannot start) is kept rather than
    raised so the session result still shows the analysis and says why there is no fit.
    """
    try:
        selection = select_impacts(
            summary, include_flagged=options.include_flagged, decisions=decisions
        )
        refusal = ''
    except SelectionError as error:  # the result says why there is no fit, naming the hits
        selection, refusal = error.selection, str(error)
    if not refusal:
        try:
            selection.chained(options.model.chain_starts)
        except BadInputError as error:  # the result says why the chain cannot be fitted
            refusal = str(error)
    return selection, refusal


def _chosen(selection: ImpactSelection, refusal: str) -> tuple[int, ...]:
    """The impacts to fit, or the SelectionError that said none is clean."""
    if refusal:
        raise SelectionError(refusal, selection)
    return selection.chosen


def overlay_of(friction: FrictionResult | None) -> ModelOverlay | None:
    """The fitted model, each impact started where the fit started it and driven as scaled."""
    if friction is None or not math.isfinite(friction.mu):
        return None
    starts = friction.initial_positions_m or (0.0,) * len(friction.impact_ids)
    scales = friction.impulse_scales or (1.0,) * len(friction.impact_ids)
    return ModelOverlay(
        friction.mu,
        'fitted',
        friction.rig,
        friction.effects,
        dict(zip(friction.impact_ids, starts, strict=True)),
        dict(zip(friction.impact_ids, scales, strict=True)),
    )
