"""The report of one impact session: every hit with its flags, the paper's figures, the model.

`build_report(records, out_dir)` is what `fmm report`, the demo and anything else that holds a
session's impact records call: it analyses them with the signal core (or takes a `Summary`
already made from them), draws the figures of `session_figures`, and writes one HTML page with
the figures embedded plus each figure as a PNG. With a friction fit (`FrictionSummary`) or a
given `ModelOverlay`, the model (Eq. 3 at that mu) is driven by each hit's measured force, as
in the paper's Sec. 5, and drawn over the measured velocity and mobility.
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fmm_ros.core.physics.rig import FMM_RIG, Rig
from fmm_ros.core.signal.analysis import (
    DEFAULT_ANALYSIS,
    AnalysisConfig,
    ImpactResult,
    Summary,
    analyze_impact,
)
from fmm_ros.core.signal.capture import DEFAULT_CAPTURE, CaptureConfig
from fmm_ros.core.signal.records import ImpactRecord
from fmm_ros.report import diagnosis_figures
from fmm_ros.report import session_figures as figures
from fmm_ros.report.html import Markup, Page, escape, link
from fmm_ros.report.plotting import (
    DEFAULT_DPI,
    MM_PER_M,
    MS_PER_S,
    REJECTED_COLOUR,
    level_colour,
    value_with_error,
)
from fmm_ros.workflows.session import (
    FrictionSummary,
    ModelOverlay,
    SessionDiagnosis,
    analyse_records,
    diagnose_accepted_impacts,
    fit_accepted_impacts,
)

# What each quality flag means, for the legend under the hit table.
FLAG_MEANINGS: dict[str, str] = {
    'double_hit': 'the force reached the trigger level again shortly after the contact '
    '(a hammer bounce): two inputs in one FRF',
    'clipped': "a sample reached a sensor's full-scale range: peak and spectrum are wrong",
    'gap': 'samples never arrived (lost batch, end of stream): the DFT is undefined',
    'nan': 'a received sample is NaN or infinite',
    'unsettled': 'the rig moved before the hit or had not come to rest at the end of the '
    'record: not one whole transient, the DFT leaks',
    'overlap': 'the next impact triggers inside this record: two responses in one FRF',
    'out_of_tolerance': 'the peak force is not within tolerance of any nominal level',
}


def build_report(
    records: Sequence[ImpactRecord],
    out_dir: str | Path,
    *,
    summary: Summary | None = None,
    capture: CaptureConfig = DEFAULT_CAPTURE,
    analysis: AnalysisConfig = DEFAULT_ANALYSIS,
    friction: FrictionSummary | None = None,
    fit_failure: str = '',
    diagnosis: SessionDiagnosis | None = None,
    diagnosis_failure: str = '',
    model: ModelOverlay | None = None,
    title: str = 'Impact session report',
    inputs: Sequence[str] = (),
    problems: Sequence[str] = (),
    dpi: float = DEFAULT_DPI,
) -> Path:
    """Write the session report into out_dir (index.html and one PNG per figure); its path.

    records: the session's impact records, record i being impact i. summary: their analysis
    (`summarize` of `analyze_impact` results with impact_id = position), made here with
    capture and analysis when not given. friction: a fit of mu over (some of) the impacts,
    shown per impact and overall; its model is drawn over each hit and each level's FRF unless
    another model is given. fit_failure: why there is no fit, if one was tried. diagnosis: the
    diagnose workflow's verdict on (some of) the impacts, with the residual and mobility gap
    before and after; diagnosis_failure: why there is none, if it was tried. inputs: where
    the records came from (files, bag), listed on the page. problems: what went wrong reading
    them (a damaged bag), shown at the top so no one misses it.
    """
    records = list(records)
    if not records:
        raise ValueError('a report needs at least one impact record')
    if summary is None:
        summary = analyse_records(records, capture, analysis)
    by_id = _records_by_id(records, summary)
    for name, result in (('friction fit', friction), ('diagnosis', diagnosis)):
        unknown = sorted(set(result.impact_ids) - set(by_id)) if result is not None else []
        if unknown:
            raise ValueError(f'the {name} names impact(s) {unknown} the session lacks')
    if friction is not None and model is None:
        model = friction.overlay()
    page = Page(out_dir, title, dpi=dpi)
    colours = {level.level: level_colour(index) for index, level in enumerate(summary.levels)}
    model_hits = _model_hits(by_id, summary, model, capture, analysis)

    _session_section(page, summary, records, analysis, model, inputs, problems)
    _hit_table(page, summary, model_hits)
    _level_section(page, summary, analysis)
    _model_section(page, summary, model, model_hits, friction, fit_failure)
    _time_section(page, summary, by_id, colours, model, capture)
    _frf_section(page, summary, colours, model, model_hits)
    if diagnosis is not None or diagnosis_failure:
        _diagnosis_section(page, summary, by_id, diagnosis, diagnosis_failure)
    return page.write()


@dataclass(frozen=True)
class SessionReport:
    """What `report_session` wrote, and the fit it made (or why it could not)."""

    page: Path
    friction: FrictionSummary | None
    fit_failure: str
    diagnosis: SessionDiagnosis | None = None
    diagnosis_failure: str = ''


def report_session(
    records: Sequence[ImpactRecord],
    out_dir: str | Path,
    *,
    capture: CaptureConfig = DEFAULT_CAPTURE,
    analysis: AnalysisConfig = DEFAULT_ANALYSIS,
    rig: Rig = FMM_RIG,
    mu: float | None = None,
    fit: bool = True,
    fit_damping: bool = False,
    fit_initial_position: bool = False,
    diagnose: bool = False,
    include_flagged: bool = False,
    title: str = 'Impact session report',
    inputs: Sequence[str] = (),
    problems: Sequence[str] = (),
    dpi: float = DEFAULT_DPI,
) -> SessionReport:
    """Analyse a session's records, fit mu over the accepted ones, and write the report.

    What `fmm report` does with its inputs, for callers holding records (the demo, from its
    bag): mu given draws that model instead of fitting; fit=False draws none; diagnose runs
    the discrepancy workflow over the accepted impacts too. Fit and diagnosis leave flagged
    hits out (named on the page) unless include_flagged. A fit or diagnosis the data refuse
    does not stop the report: the page and the result say why.
    """
    records = list(records)
    summary = analyse_records(records, capture, analysis)
    friction, failure = None, ''
    model = ModelOverlay(mu, 'given', rig) if mu is not None else None
    if mu is None and fit:
        try:
            friction = fit_accepted_impacts(
                records,
                summary,
                rig=rig,
                fit_damping=fit_damping,
                fit_initial_position=fit_initial_position,
                include_flagged=include_flagged,
            )
        except ValueError as error:  # FitError is one: the page says why there is no fit
            failure = str(error)
    diagnosis, diagnosis_failure = None, ''
    if diagnose:
        try:
            diagnosis = diagnose_accepted_impacts(
                records,
                summary,
                rig=rig,
                fit_initial_position=fit_initial_position,
                include_flagged=include_flagged,
            )
        except ValueError as error:
            diagnosis_failure = str(error)
    page = build_report(
        records,
        out_dir,
        summary=summary,
        capture=capture,
        analysis=analysis,
        friction=friction,
        fit_failure=failure,
        diagnosis=diagnosis,
        diagnosis_failure=diagnosis_failure,
        model=model,
        title=title,
        inputs=inputs,
        problems=problems,
        dpi=dpi,
    )
    return SessionReport(page, friction, failure, diagnosis, diagnosis_failure)


def _records_by_id(records: list[ImpactRecord], summary: Summary) -> dict[int, ImpactRecord]:
    """Each impact's record, checked to be there."""
    missing = [
        impact.impact_id for impact in summary.impacts if not 0 <= impact.impact_id < len(records)
    ]
    if missing:
        raise ValueError(
            f'the summary names impact(s) {missing} but only {len(records)} '
            'record(s) were given (impact_id must be the record position)'
        )
    return {impact.impact_id: records[impact.impact_id] for impact in summary.impacts}


@dataclass(frozen=True, eq=False)
class _ModelHit:
    """One hit with the model's velocity in place of the measured one."""

    # Analysed by the same pipeline (windows, band, trigger) as the measurement, so the FRFs
    # compare bin for bin.
    result: ImpactResult
    # RMS of measured minus model velocity from the trigger until both are at rest, over
    # the samples that arrived [m/s].
    residual_rms_m_s: float


def _model_hits(
    by_id: dict[int, ImpactRecord],
    summary: Summary,
    model: ModelOverlay | None,
    capture: CaptureConfig,
    analysis: AnalysisConfig,
) -> dict[int, _ModelHit]:
    """Every hit whose force can drive the model (no gaps), simulated and analysed."""
    if model is None:
        return {}
    hits = {}
    for impact in summary.impacts:
        record = by_id[impact.impact_id]
        velocity = model.velocity_m_s(record, impact.impact_id)
        if velocity is None:
            continue
        simulated = dataclasses.replace(
            record,
            velocity_m_s=velocity,
            trigger_sample_index=impact.trigger_sample_index,
            record_start_sample_index=impact.record_start_sample_index,
        )
        trigger = figures.trigger_offset(impact)
        end = (
            trigger
            + int(
                figures.decay_end_s(
                    [record.velocity_m_s, velocity],
                    trigger,
                    record.sample_rate_hz,
                    capture.rest_velocity_m_s,
                )
                * record.sample_rate_hz
            )
            + 1
        )
        residual = record.velocity_m_s[trigger:end] - velocity[trigger:end]
        received = residual[np.isfinite(residual)]  # velocity samples lost in a gap are NaN
        hits[impact.impact_id] = _ModelHit(
            analyze_impact(simulated, capture, analysis, impact_id=impact.impact_id),
            float(np.sqrt(np.mean(received**2))) if received.size else float('nan'),
        )
    return hits


def _session_section(
    page: Page,
    summary: Summary,
    records: list[ImpactRecord],
    analysis: AnalysisConfig,
    model: ModelOverlay | None,
    inputs: Sequence[str],
    problems: Sequence[str],
) -> None:
    accepted = sum(impact.accepted for impact in summary.impacts)
    page.section('Session', 'session')
    if problems:
        page.text('Problems reading the inputs (what was readable is reported):')
        page.items(problems)
    rate = records[0].sample_rate_hz
    lines = [
        f'{len(summary.impacts)} hit(s): {accepted} accepted, '
        f'{len(summary.impacts) - accepted} rejected',
        f'sampled at {rate:g} Hz, records of {records[0].window_samples / rate:g} s '
        f'(frequency step {rate / records[0].window_samples:.4g} Hz)',
        'force levels: '
        + (
            ', '.join(
                f'{level.name} {level.peak_force_n:g} ± {level.tolerance_n:g} N'
                for level in analysis.levels
            )
            or 'clustered from the peak forces (no nominal levels given)'
        ),
        'flags that reject a hit: ' + (', '.join(analysis.reject_flags) or 'none'),
    ]
    if analysis.force_window_s is not None:
        lines.append(f'force window {analysis.force_window_s:g} s after the trigger')
    if analysis.exponential_decay_s is not None:
        lines.append(f'exponential window, decay time {analysis.exponential_decay_s:g} s')
    if model is not None:
        rig = model.rig
        lines.append(
            f'model: m = {rig.mass_kg:g} kg, k = {rig.stiffness_n_per_m:g} N/m, '
            f'c = {rig.damping_n_s_per_m:g} N·s/m, N = {rig.normal_force_n:.4g} N, '
            f'{model.source} μ = {model.mu:.4g}'
            + ''.join(f', {term.name}' for term in model.effects)
        )
    page.items(lines)
    if inputs:
        shown = list(inputs[:12]) + (
            [f'... and {len(inputs) - 12} more'] if len(inputs) > 12 else []
        )
        page.text('inputs: ' + ', '.join(shown))


def _hit_table(page: Page, summary: Summary, model_hits: dict[int, _ModelHit]) -> None:
    """Every hit, accepted or rejected, with its flags and numbers (rejected rows shaded)."""
    page.section('Hits', 'hits')
    headers = [
        'hit',
        'source',
        'level',
        'verdict',
        'flags',
        'peak force [N]',
        'impulse [N·s]',
        'contact [ms]',
        'f_n [Hz]',
        'peak |X/F| [mm/N]',
    ]
    if model_hits:
        headers.append('rms(measured − model) [mm/s]')
    rows, classes = [], []
    for impact in summary.impacts:
        row = [
            link(f'#fig-{_hit_name(impact)}', impact.impact_id),
            figures.source_name(impact.source) or '-',
            impact.level or '-',
            'accepted' if impact.accepted else 'rejected',
            ', '.join(impact.flags) or '-',
            _number(impact.peak_force_n, '.5g'),
            _number(impact.impulse_n_s, '.4g'),
            _number(impact.contact_duration_s * MS_PER_S, '.3g'),
            _number(impact.natural_frequency_hz, '.4f'),
            _number(impact.peak_receptance_m_per_n * MM_PER_M, '.4g'),
        ]
        if model_hits:
            hit = model_hits.get(impact.impact_id)
            row.append('-' if hit is None else _number(hit.residual_rms_m_s * MM_PER_M, '.3g'))
        rows.append(row)
        classes.append('' if impact.accepted else 'rejected')
    page.table(headers, rows, text_columns=(1, 2, 3, 4), row_classes=classes, table_id='hit-table')
    raised = sorted(
        {flag for impact in summary.impacts for flag in impact.flags}, key=list(FLAG_MEANINGS).index
    )
    if raised:
        page.items(
            [Markup(f'<b>{escape(flag)}</b>: {escape(FLAG_MEANINGS[flag])}') for flag in raised]
        )
    else:
        page.text('No hit raised a quality flag.', note=True)


def _level_section(page: Page, summary: Summary, analysis: AnalysisConfig) -> None:
    page.section('Force levels, impulse and linearity', 'levels')
    if not summary.levels:
        page.text('No level has an accepted hit: nothing to average.', note=True)
        return
    page.table(
        ['level', 'hits', 'mean peak force [N]', 'impulse [N·s]', 'f_n [Hz]', 'peak |X/F| [mm/N]'],
        [
            [
                level.level,
                level.count,
                _number(level.mean_peak_force_n, '.5g'),
                f'{level.mean_impulse_n_s:.4g} ± {_number(level.std_impulse_n_s, ".2g")}',
                _number(level.natural_frequency_hz, '.4f'),
                _number(level.peak_receptance_m_per_n * MM_PER_M, '.4g'),
            ]
            for level in summary.levels
        ],
        text_columns=(0,),
    )
    fit = summary.linearity
    if np.isfinite(fit.slope):
        r2 = f'R² = {fit.r2:.4f}' if np.isfinite(fit.r2) else 'R² needs 3 or more levels'
        page.text(
            f'peak |X/F| = {fit.slope * MM_PER_M:.4g} mm/(N²·s) × impulse + '
            f'{fit.intercept * MM_PER_M:.4g} mm/N over {fit.count} levels, {r2}'
        )
    page.figure(
        'impulses',
        figures.impulse_figure(summary.impacts, summary.levels, analysis.levels),
        'Fig. 13 of the paper: peak force of every hit (shaded: nominal level ± '
        'tolerance; x: rejected) and mean impulse per level with ±1σ error bars.',
    )
    page.figure(
        'linearity',
        figures.linearity_figure(summary),
        'Fig. 17: peak receptance magnitude against impulse; dots are hits, + the '
        'level means the line is fitted to. Coulomb friction makes it linear.',
    )
    page.figure(
        'levels_receptance',
        figures.level_magnitude_figure(summary.levels),
        'Fig. 16: mean receptance magnitude of each level (plain frequency-domain '
        'average of its accepted hits).',
    )


def _model_section(
    page: Page,
    summary: Summary,
    model: ModelOverlay | None,
    model_hits: dict[int, _ModelHit],
    friction: FrictionSummary | None,
    fit_failure: str,
) -> None:
    page.section('Friction coefficient and model', 'model')
    if friction is not None:
        _friction(page, summary, friction)
    elif fit_failure:
        page.text(f'No friction fit: {fit_failure}', note=True)
    if model is None:
        page.text('No model overlay: no friction coefficient was given or fitted.', note=True)
        return
    page.text(
        f'The model of Eq. 3 with {model.source} μ = {model.mu:.4g} is driven by each '
        "hit's measured force (baseline removed, zero outside the hit, as the fitter "
        "drives it; the paper's Sec. 5) and drawn over the measured velocity and "
        f'mobility. {len(model_hits)} of {len(summary.impacts)} hits could drive it (a '
        'record with gaps cannot).'
    )


def _friction(page: Page, summary: Summary, friction: FrictionSummary) -> None:
    """The fitted mu overall and per impact: text, table and figure."""
    rig = friction.rig
    damping = (
        f'c = {rig.damping_n_s_per_m:.4g} ± {friction.damping_stderr_n_s_per_m:.2g} N·s/m fitted'
        if np.isfinite(friction.damping_stderr_n_s_per_m)
        else f'c = {rig.damping_n_s_per_m:.4g} N·s/m held'
    )
    consistency = (
        f'; one μ serves every impact with p = {friction.consistency_p_value:.3g} '
        '(χ² test of the per-impact values)'
        if np.isfinite(friction.consistency_p_value)
        else ''
    )
    page.text(
        f'μ = {value_with_error(friction.mu, friction.mu_stderr)} fitted to '
        f'{len(friction.impact_ids)} impacts at once ({damping}){consistency}.'
    )
    if friction.selection is not None and friction.selection.note:
        page.text(friction.selection.note, note=True)
    impacts = {impact.impact_id: impact for impact in summary.impacts}
    starts = friction.initial_positions_m or (0.0,) * len(friction.impact_ids)
    page.table(
        ['hit', 'level', 'impulse [N·s]', 'μ alone ± 1σ', 'start [mm]'],
        [
            [
                link(f'#fig-{_hit_name(impacts[i])}', i),
                impacts[i].level or '-',
                _number(impacts[i].impulse_n_s, '.4g'),
                value_with_error(mu, error),
                f'{start * MM_PER_M:.3f}',
            ]
            for i, mu, error, start in zip(
                friction.impact_ids,
                friction.per_impact_mu,
                friction.per_impact_mu_stderr,
                starts,
                strict=True,
            )
        ],
        text_columns=(1,),
    )
    page.figure(
        'friction',
        figures.friction_figure(
            [impacts[i].impulse_n_s for i in friction.impact_ids],
            friction.per_impact_mu,
            friction.per_impact_mu_stderr,
            [impacts[i].level for i in friction.impact_ids],
            friction.mu,
            friction.mu_stderr,
            level_order=[level.level for level in summary.levels],
        ),
        "Each impact's own μ (± 1σ) against its impulse, and the one μ fitted to all of "
        'them (line, ± 1σ shaded): the paper found one μ for all three levels.',
    )


def _time_section(
    page: Page,
    summary: Summary,
    by_id: dict[int, ImpactRecord],
    colours: dict[str, str],
    model: ModelOverlay | None,
    capture: CaptureConfig,
) -> None:
    page.section('Force and velocity', 'time')
    for level in summary.levels:
        members = [
            impact for impact in summary.impacts if impact.accepted and impact.level == level.level
        ]
        page.figure(
            f'trials_{_safe(level.level)}',
            figures.level_trials_figure(
                level.level,
                [by_id[impact.impact_id] for impact in members],
                members,
                colour=colours[level.level],
                capture=capture,
            ),
            f'Fig. 12: force pulses (top, ms) and velocity decays (bottom, s) of the '
            f'{level.count} accepted hits of level {level.level}.',
        )
    page.subsection('Every hit')
    hit_figures = figures.HitFigures()
    for impact in summary.impacts:
        record = by_id[impact.impact_id]
        velocity = model.velocity_m_s(record, impact.impact_id) if model is not None else None
        page.figure(
            _hit_name(impact),
            hit_figures.draw(
                record,
                impact,
                capture=capture,
                model_velocity_m_s=velocity,
                model_label=model.label if model is not None else '',
                colour=colours.get(impact.level, REJECTED_COLOUR)
                if impact.accepted
                else REJECTED_COLOUR,
            ),
            f'Figs. 18/20/22: hit {impact.impact_id} '
            + ('' if impact.accepted else f'(rejected: {", ".join(impact.flags)}) ')
            + (
                'with the model driven by its measured force.'
                if velocity is not None
                else 'as measured.'
            ),
            keep=True,
        )


def _frf_section(
    page: Page,
    summary: Summary,
    colours: dict[str, str],
    model: ModelOverlay | None,
    model_hits: dict[int, _ModelHit],
) -> None:
    page.section('Frequency response functions', 'frf')
    if not summary.levels:
        page.text('No level has an accepted hit: no FRF to show.', note=True)
        return
    model_mobility = _model_level_mobility(summary, model_hits)
    for level in summary.levels:
        page.subsection(f'level {level.level}')
        members = [
            impact for impact in summary.impacts if impact.accepted and impact.level == level.level
        ]
        for quantity, number in (('mobility', 14), ('receptance', 15)):
            page.figure(
                f'{quantity}_{_safe(level.level)}',
                figures.frf_trials_figure(level, members, quantity, colour=colours[level.level]),
                f'Fig. {number}: real and imaginary {quantity} of the {level.count} accepted '
                f'hits of level {level.level} and their mean.',
            )
        if level.level in model_mobility:
            page.figure(
                f'model_mobility_{_safe(level.level)}',
                figures.frf_overlay_figure(
                    level,
                    model_mobility[level.level],
                    model_label=model.label,
                    colour=colours[level.level],
                ),
                'Figs. 19/21/23: measured mean mobility against the model driven by the '
                'same measured forces (mean over the same hits).',
            )
    page.subsection('odd harmonics')
    page.figure(
        'harmonics',
        figures.harmonics_figure(
            summary.levels, model_mobility, model_label=model.label if model else 'model'
        ),
        'Fig. 24: mean mobility magnitude to 20 Hz, odd multiples of the natural frequency '
        'marked: the sliding contact, not a second mode, puts response there.',
    )


def _diagnosis_section(
    page: Page,
    summary: Summary,
    by_id: dict[int, ImpactRecord],
    found: SessionDiagnosis | None,
    failure: str,
) -> None:
    """The named effect, the gap before and after, every candidate, and the two figures."""
    page.section('Model diagnosis', 'diagnosis')
    if found is None:
        page.text(f'No diagnosis: {failure}', note=True)
        return
    result = found.diagnosis
    page.text(
        f'Missing effect: {result.missing_effect}. Gap (RMS velocity residual beyond the '
        f'noise over the motion, over the peak speed) {result.gap_before:.3g} → '
        f'{result.gap_after:.3g}; mobility misfit {result.frf_gap_before:.3g} → '
        f'{result.frf_gap_after:.3g}, over {len(found.impact_ids)} accepted hits '
        f'(velocity noise {result.noise_std_m_s * MM_PER_M:.3g} mm/s from the data).'
    )
    page.text(f'Verdict: {result.verdict}')
    if found.selection is not None and found.selection.note:
        page.text(found.selection.note, note=True)
    page.text(f'Where the base model misses: {result.where.summary}.')
    page.table(
        ['parameter of the named model', 'value ± 1σ', 'unit'],
        [
            [p.name, value_with_error(p.value, p.stderr), '-' if p.unit == '1' else p.unit]
            for p in result.parameters
        ],
        text_columns=(0, 2),
    )
    page.table(
        ['candidate effect', 'score ΔBIC', 'gap after', 'mobility misfit after', 'note'],
        [
            [
                c.effect,
                _number(c.score, '.0f'),
                _number(c.gap_after, '.3g'),
                _number(c.frf_gap_after, '.3g'),
                'named' if c.effect == result.missing_effect else c.message or '-',
            ]
            for c in result.candidates
        ],
        text_columns=(0, 4),
    )
    page.text(
        f'A candidate is named when its score is at most {result.required_score:.0f} '
        '(BIC lower than the base model by 10 plus three times what the force noise '
        'alone explains) and it at least halves the gap.'
    )
    records = [by_id[i] for i in found.impact_ids]
    rows = _one_per_level(summary, found.impact_ids)
    shown = ', '.join(str(found.impact_ids[row]) for row in rows)
    if len(rows) < len(found.impact_ids):
        shown += ' (the first of each level)'
    page.figure(
        'diagnosis_residuals',
        diagnosis_figures.residual_figure(result, records, rows),
        f'Measured minus model velocity for hits {shown}: the base '
        'model (Eq. 3, μ fitted) and the model with the named effect.',
    )
    page.figure(
        'diagnosis_mobility',
        diagnosis_figures.mobility_gap_figure(
            result, records, found.rig.natural_frequency_hz, rows
        ),
        f'|mobility| of measurement and models to 20 Hz for hits {shown}, and beside it '
        '|measured − model|: where the gap is, and whether the named effect closes it.',
    )


def _one_per_level(summary: Summary, impact_ids: Sequence[int]) -> list[int]:
    """Positions in impact_ids of the first impact of each level (all of them if few)."""
    if len(impact_ids) <= 3:
        return list(range(len(impact_ids)))
    level = {impact.impact_id: impact.level for impact in summary.impacts}
    first: dict[str, int] = {}
    for position, impact_id in enumerate(impact_ids):
        first.setdefault(level[impact_id], position)
    return sorted(first.values())


def _model_level_mobility(
    summary: Summary, model_hits: dict[int, _ModelHit]
) -> dict[str, np.ndarray]:
    """Each level's plain-mean model mobility over the hits its measured mean used."""
    mobility = {}
    for level in summary.levels:
        members = [model_hits[i].result for i in level.impact_ids if i in model_hits]
        if len(members) == level.count:
            mobility[level.level] = np.mean([result.mobility for result in members], axis=0)
    return mobility


def _hit_name(impact: ImpactResult) -> str:
    return f'hit_{impact.impact_id:03d}'


def _safe(name: str) -> str:
    """A level name as a file-name part."""
    return re.sub(r'[^A-Za-z0-9_.-]', '_', name) or 'unnamed'


def _number(value: float, spec: str) -> str:
    return format(value, spec) if np.isfinite(value) else '-'
