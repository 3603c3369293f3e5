"""The report of one impact session: every hit with its flags, the paper's figures, the model.

`build_report(session, out_dir)` draws a `SessionResult` (`fmm_ros.workflows.session`): the
analysis, the friction fit (made by `fmm report`, or the fitter service's answer in the demo),
the diagnosis and the model run for every hit, all computed there. It writes one HTML page
with the figures embedded plus each figure as a PNG, and computes nothing itself.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from fmm_ros.constants import MM_PER_M, REPORT_DPI
from fmm_ros.core import results_schema as schema
from fmm_ros.core.diagnose.result import Diagnosis
from fmm_ros.core.results_schema import format_with_uncertainty, label
from fmm_ros.core.signal import frf
from fmm_ros.core.signal.analysis import ImpactAnalysis, Summary
from fmm_ros.io.session_info import describe as describe_info
from fmm_ros.report import diagnosis_figures
from fmm_ros.report import session_figures as figures
from fmm_ros.report.html import Markup, Page, escape, link
from fmm_ros.report.plotting import (
    MS_PER_S,
    REJECTED_COLOUR,
    level_colour,
)
from fmm_ros.workflows.model import ModelComparison
from fmm_ros.workflows.results import (
    FrictionResult,
    detection_limit_dict,
    detection_limit_text,
)
from fmm_ros.workflows.session import SessionDiagnosis, SessionResult

# Lines of the lab files' import report shown on the page (a session of 30 files has 150).
NOTE_LINES = 12

# What each quality flag means, for the legend under the hit table.
FLAG_MEANINGS: dict[str, str] = {
    'double_hit': 'the force reached the trigger level again shortly after the contact '
    '(a hammer bounce): two inputs in one FRF',
    'clipped': "the force reached its sensor's full-scale range or has a flat top: peak "
    'and spectrum are wrong',
    'coarse': 'the hammer pulse spans too few samples: its impulse and peak are off by per '
    'cents, depending on where the samples fell',
    'saturated': "the velocity reached the vibrometer's range or has a flat top",
    'no_response': 'the velocity does not respond to the hit: a dead or disconnected vibrometer',
    'dropout': 'a channel holds one exact value too long: samples dropped and filled',
    'gap': 'samples never arrived (lost batch, end of stream): the DFT is undefined',
    'interrupted': 'the acquisition restarted before the record was complete (its tail is a gap)',
    'truncated_start': 'the acquisition began mid-hit or inside the pre-trigger (the record '
    'starts at its first sample)',
    'nan': 'a received sample is NaN or infinite',
    'unsettled': 'the rig moved before the hit or had not come to rest at the end of the '
    'record: not one whole transient, the DFT leaks',
    'overlap': 'the next impact triggers inside this record: two responses in one FRF',
    'undetermined': 'a headline number came out NaN: no impulse (the force never reached the '
    're-arm level), no f_n (too few strong velocity reversals and no peak in the response '
    'spectrum: a record that never rings) or no peak |X/F| (no excited bin in the peak band)',
    'out_of_tolerance': 'the peak force is not within tolerance of any nominal level',
}


def build_report(
    session: SessionResult,
    out_dir: str | Path,
    *,
    title: str = 'Impact session report',
    dpi: float = REPORT_DPI,
    progress: Callable[[str], None] | None = None,
) -> Path:
    """Write the session's report into out_dir (index.html and one PNG per figure); its path.

    Every hit is in the table and has its figure; a friction fit is shown per impact and
    overall, and its model (or a given one) is drawn over each hit and each level's FRF; a
    diagnosis (or why there is none) has its section; problems reading the inputs (a damaged
    bag) are shown at the top so no one misses them. progress is told of each figure.
    """
    summary = session.summary
    page = Page(out_dir, title, dpi=dpi, progress=progress)
    colours = {level.level: level_colour(index) for index, level in enumerate(summary.levels)}
    comparison = session.comparison
    _session_section(page, session)
    _hit_table(page, summary, comparison)
    _level_section(page, summary, session.analysis)
    _model_section(page, session)
    _time_section(page, session, colours)
    _frf_section(page, summary, colours, comparison)
    if session.diagnosis is not None or session.diagnosis_failure:
        _diagnosis_section(page, session, session.diagnosis, session.diagnosis_failure)
    return page.write()


def _session_section(page: Page, session: SessionResult) -> None:
    summary, records, analysis, model = (
        session.summary,
        session.records,
        session.analysis,
        session.model,
    )
    accepted = sum(impact.accepted for impact in summary.impacts)
    page.section('Session', 'session')
    if session.problems:
        page.text('Problems reading the inputs (what was readable is reported):')
        page.items(session.problems)
    station_header(page, session)
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
    inputs = session.inputs
    if inputs:
        shown = list(inputs[:12]) + (
            [f'... and {len(inputs) - 12} more'] if len(inputs) > 12 else []
        )
        page.text('inputs: ' + ', '.join(shown))
    if session.notes:
        shown = session.notes[:NOTE_LINES]
        more = len(session.notes) - len(shown)
        page.text('How the lab files were read:')
        page.items(shown + ([f'... and {more} more lines like these'] if more else []))


def station_header(page: Page, session: SessionResult) -> None:
    """What the station recorded: each bag's metadata, the decisions about hits."""
    for path, info in session.session_info.items():
        rows = describe_info(info)
        if rows:
            page.text(f'Session metadata of {Path(path).name}:')
            page.table(['field', 'value'], rows, text_columns=(0, 1), table_id='session-info')
    judged = session.selection.judged if session.selection is not None else ()
    if judged:
        page.text('Decisions about hits, which overrule the flags in the fit:')
        page.items([decision.describe() for decision in judged])


def _hit_table(page: Page, summary: Summary, comparison: ModelComparison | None) -> None:
    """Every hit, accepted or rejected, with its flags and numbers (rejected rows shaded)."""
    page.section('Hits', 'hits')
    headers = [
        'hit',
        'source',
        'level',
        'verdict',
        'flags',
        label(schema.PEAK_FORCE),
        label(schema.IMPULSE),
        label(schema.CONTACT_DURATION),
        label(schema.NATURAL_FREQUENCY),
        label(schema.PEAK_RECEPTANCE),
    ]
    model_hits = comparison.hits if comparison else {}
    if comparison:
        headers.append('rms(measured − model) [mm/s]')
    rows, classes = [], []
    for position, impact in enumerate(summary.impacts):
        row = [
            link(f'#fig-{_hit_name(position)}', impact.impact_id),
            figures.source_name(impact.source) or '-',
            impact.level or '-',
            'accepted' if impact.accepted else 'rejected',
            ', '.join(impact.flags) or '-',
            _number(impact.peak_force_n, '.5g'),
            _number(impact.impulse_n_s, '.4g'),
            _number(impact.contact_duration_s * MS_PER_S, '.3g'),
            _natural_frequency(impact),
            _number(impact.peak_receptance_m_per_n * MM_PER_M, '.4g'),
        ]
        if comparison:
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
    if any(impact.natural_frequency_method == frf.DFT_PEAK for impact in summary.impacts):
        page.text(SHORT_RING_NOTE, note=True)


SHORT_RING_NOTE = (
    'f_n marked "DFT peak": the hit rang too briefly (one or two cycles) for its velocity '
    'reversals to be timed, and f_n is the peak of its response spectrum over the hammer '
    "pulse's. Its uncertainty bounds how far a ring this short moves its own peak (a friction "
    "ring's peak lies above f_n by about a fifth of it) with the noise's part."
)
"""The report's note under the hits table when a hit's f_n was read at its DFT peak."""


def _natural_frequency(impact: ImpactAnalysis) -> str:
    """A hit's f_n cell: the value, or for a DFT peak the value with its uncertainty."""
    if impact.natural_frequency_method != frf.DFT_PEAK:
        return _number(impact.natural_frequency_hz, '.4f')
    value = format_with_uncertainty(
        impact.natural_frequency_hz, impact.natural_frequency_uncertainty_hz
    )
    return f'{value} (DFT peak)'


def _level_section(page: Page, summary: Summary, analysis) -> None:
    page.section('Force levels, impulse and linearity', 'levels')
    if not summary.levels:
        page.text('No level has an accepted hit: nothing to average.', note=True)
        return
    page.table(
        [
            'level',
            'hits',
            label(schema.MEAN_PEAK_FORCE),
            label(schema.IMPULSE),
            label(schema.LEVEL_NATURAL_FREQUENCY),
            label(schema.LEVEL_PEAK_RECEPTANCE),
        ],
        [
            [
                level.level,
                level.count,
                _number(level.mean_peak_force_n, '.5g'),
                f'{level.mean_impulse_n_s:.4g} ± {_number(level.std_impulse_n_s, ".2g")}',
                _number(level.natural_frequency_hz, '.4f')
                + (' (DFT peak)' if level.natural_frequency_method == frf.DFT_PEAK else ''),
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
        'average of its accepted hits), on a linear axis as the paper (left) and a log '
        'axis (right).',
    )


def _model_section(page: Page, session: SessionResult) -> None:
    summary, comparison, friction = session.summary, session.comparison, session.friction
    page.section('Friction coefficient and model', 'model')
    if friction is not None:
        _friction(page, summary, friction)
        if session.selection is not None and session.selection.note:
            page.text(session.selection.note, note=True)
    elif session.fit_failure:
        page.text(f'No friction fit: {session.fit_failure}', note=True)
    if comparison is None:
        page.text('No model overlay: no friction coefficient was given or fitted.', note=True)
        return
    model = comparison.model
    page.text(
        f'The model of Eq. 3 with {model.source} μ = {model.mu:.4g} is driven by each '
        "hit's measured force (baseline removed, zero outside the hit, as the fitter "
        "drives it; the paper's Sec. 5) and drawn over the measured velocity and "
        f'mobility. {len(comparison.hits)} of {len(summary.impacts)} hits could drive it (a '
        'record with gaps cannot).'
    )


def _friction(page: Page, summary: Summary, friction: FrictionResult) -> None:
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
        f'μ = {format_with_uncertainty(friction.mu, friction.mu_stderr)} fitted to '
        f'{len(friction.impact_ids)} impacts at once ({damping}){consistency}.'
    )
    impacts = {impact.impact_id: impact for impact in summary.impacts}
    positions = {impact.impact_id: k for k, impact in enumerate(summary.impacts)}
    starts = friction.initial_positions_m or (0.0,) * len(friction.impact_ids)
    page.table(
        ['hit', 'level', label(schema.IMPULSE), 'μ alone ± 1σ', label(schema.INITIAL_POSITION)],
        [
            [
                link(f'#fig-{_hit_name(positions[i])}', i),
                impacts[i].level or '-',
                _number(impacts[i].impulse_n_s, '.4g'),
                format_with_uncertainty(mu, error),
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
    running = friction.running([impacts[i].level for i in friction.impact_ids])
    page.figure(
        'running_mu',
        figures.running_mu_figure(
            [e.mu for e in running],
            [e.mu_stderr for e in running],
            friction.per_impact_mu,
            friction.per_impact_mu_stderr,
        ),
        "The running μ after each accepted hit, in the order they came (the hits' own μ, "
        'inverse-variance weighted, as the fitter node publishes it live): it settles as the '
        'hits add up, and a hit that disagrees stands out beside it.',
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


def _time_section(page: Page, session: SessionResult, colours: dict[str, str]) -> None:
    summary, records, model, capture = (
        session.summary,
        session.records_by_id,
        session.model,
        session.capture,
    )
    page.section('Force and velocity', 'time')
    for level in summary.levels:
        members = [
            impact for impact in summary.impacts if impact.accepted and impact.level == level.level
        ]
        page.figure(
            f'trials_{_safe(level.level)}',
            figures.level_trials_figure(
                level.level,
                [records[impact.impact_id] for impact in members],
                members,
                colour=colours[level.level],
                capture=capture,
            ),
            f'Fig. 12: force pulses (top, ms) and velocity decays (bottom, s) of the '
            f'{level.count} accepted hits of level {level.level}.',
        )
    page.subsection('Every hit')
    page.text('Each hit is folded: open one to see its force, decay and model.', note=True)
    hit_figures = figures.HitFigures()
    for position, impact in enumerate(summary.impacts):
        record = records[impact.impact_id]
        velocity = model.velocity_m_s(record, impact.impact_id) if model is not None else None
        verdict = 'accepted' if impact.accepted else f'rejected: {", ".join(impact.flags)}'
        with page.collapsed(
            f'hit {impact.impact_id} · {impact.level or "no level"} · {verdict} · peak '
            f'{impact.peak_force_n:.4g} N, impulse {impact.impulse_n_s:.4g} N·s'
        ):
            page.figure(
                _hit_name(position),
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
                + ('' if impact.accepted else f'({verdict}) ')
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
    comparison: ModelComparison | None,
) -> None:
    page.section('Frequency response functions', 'frf')
    if not summary.levels:
        page.text('No level has an accepted hit: no FRF to show.', note=True)
        return
    model = comparison.model if comparison else None
    model_mobility = comparison.level_mobility if comparison else {}
    for level in summary.levels:
        page.subsection(f'level {level.level}')
        members = [
            impact for impact in summary.impacts if impact.accepted and impact.level == level.level
        ]
        for quantity, number in (('mobility', 14), ('receptance', 15)):
            page.figure(
                f'{quantity}_{_safe(level.level)}',
                figures.frf_trials_figure(level, members, quantity, colour=colours[level.level]),
                f'Fig. {number}: {quantity} of the {level.count} accepted hits of level '
                f"{level.level} and their mean, as real and imaginary parts (the paper's view) "
                'and as log magnitude and phase (Bode).',
            )
        page.figure(
            f'coherence_{_safe(level.level)}',
            figures.coherence_figure(level, members, colour=colours[level.level]),
            (
                f'Coherence of force and velocity over the {level.count} hits of level '
                f'{level.level} (1: every hit saw the same linear FRF)'
                if level.count >= 2
                else f'Coherence is not drawn: level {level.level} has one hit, and of one hit '
                'it is 1 by definition (it needs two)'
            )
            + ', and the spread of their |mobility| about the mean: where the hits disagree, '
            'the mean is less certain.',
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


AT_BOUND = ' (at its bound)'
"""What a parameter's value cell adds when its fit ended on a bound of its range (a limit,
not an estimate), as `fmm diagnose`'s table does."""


def _diagnosis_section(
    page: Page,
    session: SessionResult,
    found: SessionDiagnosis | None,
    failure: str,
) -> None:
    """The named effects, the gap before and after, every candidate, and the figures."""
    page.section('Model diagnosis', 'diagnosis')
    if found is None:
        page.text(f'No diagnosis: {failure}', note=True)
        return
    result = found.diagnosis
    page.text(
        f'Missing effects: {", ".join(result.named_effects) or "none"}. Gap (RMS velocity '
        'residual beyond the noise over the motion, over the peak speed) '
        f'{result.gap_before:.3g} → '
        f'{result.gap_after:.3g}; mobility misfit {result.frf_gap_before:.3g} → '
        f'{result.frf_gap_after:.3g}, over {len(found.impact_ids)} accepted hits, '
        f'starts {result.starts} '
        f'(velocity noise {result.noise_std_m_s * MM_PER_M:.3g} mm/s from the data, '
        f'{result.residual_noise_std_m_s * MM_PER_M:.3g} mm/s where the rig rests, which the '
        'gap is beyond).'
    )
    page.text(f'Verdict: {result.verdict}')
    if session.selection is not None and session.selection.note:
        page.text(session.selection.note, note=True)
    page.text(f'Where the base model misses: {result.where.summary}.')
    _candidate_tables(page, result)
    _diagnosis_figures(page, session, found)


def _candidate_tables(page: Page, result: Diagnosis) -> None:
    """The named model's parameters, every candidate's score and gap, and how to read them."""
    page.table(
        ['parameter of the named model', 'value ± 1σ', 'unit'],
        [
            [
                p.name,
                format_with_uncertainty(p.value, p.stderr) + (AT_BOUND if p.at_bound else ''),
                '-' if p.unit == '1' else p.unit,
            ]
            for p in result.parameters
        ],
        text_columns=(0, 2),
    )
    page.table(
        [
            'candidate effect',
            'score ΔBIC',
            'gap after',
            'mobility misfit after',
            'shows from',
            'note',
        ],
        [
            [
                c.effect,
                _number(c.score, '.0f'),
                _number(c.gap_after, '.3g'),
                _number(c.frf_gap_after, '.3g'),
                detection_limit_text(
                    detection_limit_dict(
                        c.effect, c.detection_limit, c.detection_limit_by_frequency
                    )
                ),
                'named'
                if c.effect in result.named_effects
                else '; '.join(n for n in (c.message, c.unobservable) if n) or '-',
            ]
            for c in result.candidates
        ],
        text_columns=(0, 4, 5),
    )
    page.text(
        f'Effects are added one at a time while the best scores at most '
        f'{result.required_score:.0f} (BIC lower by 10 plus three times what the force noise '
        'alone explains) and removes a quarter of the squared gap left; together they must '
        'halve the gap. "unexplained" means what is left stays well above the noise. "Shows '
        'from": the size at which these records would show an effect (its response beyond '
        'what mu and the starts take up reaching half the noise RMS); a smaller one can hide '
        'here, so "none" does not rule it out.'
    )


def _diagnosis_figures(page: Page, session: SessionResult, found: SessionDiagnosis) -> None:
    """Residuals and mobility gaps of the first hit of each level, and the friction map."""
    result = found.diagnosis
    summary = session.summary
    by_id = session.records_by_id
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
    page.figure(
        'diagnosis_friction_map',
        diagnosis_figures.friction_map_figure(result),
        'μ the records show against sliding speed and position over every diagnosed hit, '
        'from the equation of motion integrated over short runs (inverse dynamics): a '
        'Coulomb contact lies on the dashed line, a Stribeck contact rises towards low speed, '
        'a wear track varies with position.',
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


def _hit_name(position: int) -> str:
    """A hit's figure (and anchor) by its position in the session: short, and the same each run."""
    return f'hit_{position:03d}'


def _safe(name: str) -> str:
    """A level name as a file-name part."""
    return re.sub(r'[^A-Za-z0-9_.-]', '_', name) or 'unnamed'


def _number(value: float, spec: str) -> str:
    return format(value, spec) if np.isfinite(value) else '-'
