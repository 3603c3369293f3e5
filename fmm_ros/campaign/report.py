"""The campaign's HTML page: the verdict, mu by condition, differences, trends, every session.

Built with the session report's `Page` (sections, escaped text and tables, figures embedded
and written as PNG files beside the page) and its figure helpers (`plotting.new_figure`, the
level colours), so the two reports look alike. Every string that comes from a file or a user
(condition values, session ids, file names, notes, reasons) goes through the page's escaping;
in a figure, matplotlib's mathtext is switched off for it by escaping '$'.
"""

from __future__ import annotations

import datetime as dt
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from fmm_ros.campaign.compare import (
    SECONDS_PER_DAY,
    CampaignComparison,
    ConditionEstimate,
    Difference,
    Trend,
    condition_label,
    format_interval,
    format_p,
)
from fmm_ros.campaign.results import CampaignResult, named_effects, session_mus
from fmm_ros.campaign.stats import CONFIDENCE
from fmm_ros.campaign.table import DATE, format_value
from fmm_ros.constants import MM_PER_M, REPORT_DPI
from fmm_ros.core import results_schema as schema
from fmm_ros.core.distributions import t_ppf
from fmm_ros.core.identify.spec import CENTRE, CHAINED, FITTED
from fmm_ros.core.results_schema import format_with_uncertainty
from fmm_ros.report.html import Page
from fmm_ros.report.plotting import (
    MEAN_COLOUR,
    REJECTED_COLOUR,
    level_colour,
    new_figure,
)

# Figure height per row of a forest plot (a condition or a difference) [inches].
ROW_HEIGHT_IN = 0.32
# Beyond this many sessions the hit bars keep every n-th session's name on the axis.
MAX_SESSION_LABELS = 40


STARTS_SAID = {
    CENTRE: 'at rest at 0',
    FITTED: 'fitted',
    CHAINED: 'chained: each from where the model left the rig',
}
"""How the report names each way the fit starts a hit (`FitSpec.starts`)."""


def write_campaign_report(
    campaign: CampaignResult, out_dir: str | Path, *, title: str = '', dpi: float = REPORT_DPI
) -> Path:
    """Write out_dir/index.html (and the figures as PNG files); its path."""
    table = campaign.table
    comparison = campaign.comparison
    page = Page(out_dir, title or table.title or f'Campaign {table.path.name}', dpi=dpi)
    _overview(page, campaign)
    if comparison.conditions:
        _conditions(page, campaign)
    if comparison.differences:
        _differences(page, comparison.differences)
    if comparison.trends:
        _trends(page, campaign)
    _sessions(page, campaign)
    _levels(page, campaign)
    if any(result.diagnosis or result.diagnosis_failure for result in campaign.results):
        _diagnoses(page, campaign)
    _method(page, comparison)
    return page.write()


def _overview(page: Page, campaign: CampaignResult) -> None:
    """What was run, and the verdict in words."""
    comparison, results = campaign.comparison, campaign.results
    options = campaign.options
    page.section('Campaign and verdict', 'campaign')
    levels = ', '.join(f'{lv.name} {lv.peak_force_n:g} N' for lv in options.analysis.levels)
    model = options.model
    page.items(
        [
            f'table: {campaign.table.path}',
            f'sessions: {len(results)}, fitted {sum(r.ok for r in results)}, failed '
            f'{len(campaign.failed)}; {sum(r.cached for r in results)} taken from the cache',
            f'compared by: {", ".join(campaign.by)}'
            + (f'; trends against: {", ".join(campaign.trend)}' if campaign.trend else ''),
            f'hit levels: {levels or "clustered from the peak forces"}; capture window '
            f'{options.inputs.capture.window_s:g} s',
            "fit: one mu over each session's accepted hits, with the normal force of its row "
            f'(damping {"fitted" if model.fit_damping else "the rig constant"}, start '
            f'positions {STARTS_SAID[model.spec().starts]}); '
            f'diagnosis {"run" if options.diagnose else "not run"}',
            f'run time: {campaign.seconds:.1f} s',
        ]
    )
    page.subsection('Verdict')
    if comparison.verdicts:
        page.items(comparison.verdicts)
    for note in comparison.notes:
        page.text(note, note=True)
    if campaign.failed:
        page.subsection('Sessions that gave no mu')
        page.items([f'{session}: {reason}' for session, reason in campaign.failed])


def _conditions(page: Page, campaign: CampaignResult) -> None:
    """The table and forest plot of mu by condition."""
    comparison = campaign.comparison
    page.section('mu by condition', 'conditions')
    page.table(
        ['condition', 'sessions', 'hits', 'mean of sessions', 'mu (model)', '95 % CI'],
        [
            [
                c.label,
                c.sessions,
                c.hits,
                f'{c.mean_of_sessions:.5f}',
                format_with_uncertainty(c.estimate.estimate, c.estimate.stderr),
                format_interval(c.estimate.ci_low, c.estimate.ci_high),
            ]
            for c in comparison.conditions
        ],
        text_columns=(0,),
    )
    page.figure(
        'conditions',
        conditions_figure(comparison.conditions, campaign),
        "Each session's mu (dots, ±2σ of its own fit, the Birge-scaled error the model uses) "
        "and each condition's mean with its 95 % interval (black), which includes the "
        'scatter between sessions.',
    )


def conditions_figure(conditions: Sequence[ConditionEstimate], campaign: CampaignResult) -> Figure:
    """Sessions' mu and the condition means with intervals, one row per condition."""
    figure, axes = new_figure(
        1,
        1,
        height_in=1.0 + ROW_HEIGHT_IN * max(len(conditions), 2),
        title='friction coefficient by condition',
    )
    ax = axes[0]
    labels = [c.label for c in conditions]
    points = session_mus(campaign.table, campaign.results)
    rows = {label: row for row, label in enumerate(labels)}
    by = campaign.comparison.by
    jitter = np.random.default_rng(0)
    for point in points:
        label = _condition_label(by, point.conditions)
        if label not in rows:
            continue
        row = rows[label]
        ax.errorbar(
            point.mu,
            row + jitter.uniform(-0.2, 0.2),
            xerr=2 * math.sqrt(point.variance),
            fmt='o',
            markersize=3,
            color=level_colour(row),
            alpha=0.7,
            capsize=0,
        )
    for row, condition in enumerate(conditions):
        c = condition.estimate
        if math.isfinite(c.ci_low):
            ax.plot([c.ci_low, c.ci_high], [row, row], color=MEAN_COLOUR, linewidth=2.5)
        ax.plot(c.estimate, row, 'D', color=MEAN_COLOUR, markersize=6)
    ax.set_yticks(range(len(labels)), [_plain(label) for label in labels])
    ax.set_ylim(len(labels) - 0.5, -0.5)
    ax.set_ylabel(_plain(', '.join(by)))
    ax.set_xlabel('μ [-]')
    ax.ticklabel_format(axis='x', style='plain', useOffset=False)
    return figure


def _condition_label(by: Sequence[str], conditions) -> str:
    """The label the comparison gives the condition of these values."""
    return condition_label(by, [conditions.get(name) for name in by])


def _differences(page: Page, differences: Sequence[Difference]) -> None:
    """The table and forest plot of pairwise differences."""
    page.section('Differences between conditions', 'differences')
    page.table(
        ['column', 'difference', 'where', 'estimate', '95 % CI', 'p', 'p (Holm)', 'verdict'],
        [
            [
                d.column,
                f'{d.level} − {d.reference}',
                d.stratum or 'all sessions',
                format_with_uncertainty(d.estimate.estimate, d.estimate.stderr),
                format_interval(d.estimate.ci_low, d.estimate.ci_high),
                format_p(d.estimate.p_value),
                format_p(d.p_adjusted),
                'different' if d.different else 'not shown different',
            ]
            for d in differences
        ],
        text_columns=(0, 1, 2, 7),
    )
    page.figure(
        'differences',
        differences_figure(differences),
        'Each pairwise difference of mu with its 95 % interval; filled: declared different '
        '(Holm-adjusted p below 0.05 within its column and stratum).',
    )


def differences_figure(differences: Sequence[Difference]) -> Figure:
    """Forest plot of the differences, zero marked."""
    figure, axes = new_figure(
        1,
        1,
        height_in=1.0 + ROW_HEIGHT_IN * max(len(differences), 2),
        title='differences of μ between conditions (95 % intervals)',
    )
    ax = axes[0]
    ax.axvline(0.0, color=REJECTED_COLOUR, linewidth=1)
    names = sorted({d.column for d in differences}, key=[d.column for d in differences].index)
    for row, d in enumerate(differences):
        colour = level_colour(names.index(d.column))
        c = d.estimate
        if math.isfinite(c.ci_low):
            ax.plot([c.ci_low, c.ci_high], [row, row], color=colour, linewidth=2)
        ax.plot(
            c.estimate,
            row,
            'o',
            color=colour,
            markerfacecolor=colour if d.different else 'white',
            markersize=6,
        )
    labels = [
        f'{d.column}: {d.level} − {d.reference}' + (f' ({d.stratum})' if d.stratum else '')
        for d in differences
    ]
    ax.set_yticks(range(len(labels)), [_plain(label) for label in labels])
    ax.set_ylim(len(labels) - 0.5, -0.5)
    ax.set_xlabel('Δμ [-]')
    ax.ticklabel_format(axis='x', style='plain', useOffset=False)
    return figure


def _trends(page: Page, campaign: CampaignResult) -> None:
    """The slopes, and mu against each trend column."""
    trends = campaign.comparison.trends
    page.section('Trends', 'trends')
    page.table(
        ['against', 'group', 'sessions', 'slope', '95 % CI', 'p'],
        [
            [
                t.column,
                t.group,
                t.sessions,
                f'{format_with_uncertainty(t.slope.estimate, t.slope.stderr)} per {t.unit}',
                format_interval(t.slope.ci_low, t.slope.ci_high),
                format_p(t.slope.p_value),
            ]
            for t in trends
        ],
        text_columns=(0, 1, 3),
    )
    for number, column in enumerate(dict.fromkeys(t.column for t in trends), start=1):
        page.figure(
            f'trend_{number}',
            trend_figure(campaign, column, [t for t in trends if t.column == column]),
            f'mu of each session (±2σ) against {column}, with the fitted line of each group '
            'and its 95 % confidence band.',
        )


def trend_figure(campaign: CampaignResult, column: str, trends: Sequence[Trend]) -> Figure:
    """Sessions' mu against a column, coloured by group, with each group's line and band."""
    figure, axes = new_figure(1, 1, height_in=3.8, title=f'μ against {_plain(column)}')
    ax = axes[0]
    is_date = campaign.table.column(column).kind == DATE
    by = tuple(name for name in campaign.comparison.by if name != column)
    origin = next((t.origin for t in trends if t.origin is not None), None)
    points = [p for p in session_mus(campaign.table, campaign.results) if p.conditions.get(column)]
    groups = list(
        dict.fromkeys(_condition_label(by, p.conditions) if by else 'all' for p in points)
    )
    labelled: set[str] = set()
    for point in points:
        group = _condition_label(by, point.conditions) if by else 'all'
        first = group not in labelled
        labelled.add(group)
        ax.errorbar(
            _x(point.conditions[column], origin),
            point.mu,
            yerr=2 * math.sqrt(point.variance),
            fmt='o',
            markersize=3,
            color=level_colour(groups.index(group)),
            capsize=0,
            label=_plain(group) if first and len(groups) > 1 else None,
        )
    for trend in trends:
        if trend.group == 'all' and len(groups) > 1:
            continue  # the common slope has one intercept per group; each group draws its own
        colour = level_colour(groups.index(trend.group)) if trend.group in groups else MEAN_COLOUR
        xs = np.array(
            [
                _x(p.conditions[column], origin)
                for p in points
                if trend.group == 'all' or _condition_label(by, p.conditions) == trend.group
            ]
        )
        line_x = np.linspace(xs.min(), xs.max(), 50)
        offset = line_x - trend.intercept_at
        line = trend.intercept.estimate + trend.slope.estimate * offset
        cov = trend.line_covariance
        spread = np.sqrt(np.maximum(cov[0, 0] + 2 * offset * cov[0, 1] + offset**2 * cov[1, 1], 0))
        half = t_ppf(0.5 + CONFIDENCE / 2, max(trend.slope.dof, 1)) * spread
        ax.plot(line_x, line, color=colour, linewidth=1.2)
        ax.fill_between(line_x, line - half, line + half, color=colour, alpha=0.15, linewidth=0)
    ax.set_xlabel(
        f'days since {origin.date().isoformat()}'
        if is_date and origin
        else _plain(f'{column} [{trends[0].unit}]')
    )
    ax.set_ylabel('μ [-], ± 2σ')
    ax.ticklabel_format(axis='y', style='plain', useOffset=False)
    if len(groups) > 1:
        ax.legend(fontsize='small')
    return figure


def _x(value, origin: dt.datetime | None) -> float:
    """A trend column's value on the figure's axis (days since origin for dates)."""
    if isinstance(value, dt.datetime):
        return (value - origin).total_seconds() / SECONDS_PER_DAY
    return float(value)


def _sessions(page: Page, campaign: CampaignResult) -> None:
    """Every session in a table (failed rows shaded), and the hits each kept."""
    page.section('Sessions', 'sessions')
    columns = [column.name for column in campaign.table.columns]
    rows, classes = [], []
    for session, result in zip(campaign.table.sessions, campaign.results, strict=True):
        rows.append(
            [
                session.session_id,
                *(format_value(session.conditions[name]) for name in columns),
                f'{result.accepted_hits} / {len(result.hits)}',
                format_with_uncertainty(result.mu, result.mu_stderr) if result.ok else '-',
                format_p(result.consistency_p_value),
                f'{result.birge_ratio:.2g}' if result.ok else '-',
                'cached' if result.cached else f'{sum(result.seconds.values()):.1f} s',
                '; '.join(filter(None, (result.reason, *result.problems, session.notes))),
            ]
        )
        classes.append('' if result.ok else 'rejected')
    page.table(
        [
            'session',
            *columns,
            'accepted / hits',
            'mu (fit)',
            'one mu fits all hits: p',
            'Birge ratio',
            'time',
            'notes, problems',
        ],
        rows,
        text_columns=(0, *range(1, len(columns) + 1), len(columns) + 6),
        row_classes=classes,
    )
    page.text(
        "Shaded: no mu (the reason is given). p: the chance that the hits' own mu scatter "
        "this much about the session's if one mu served them all; the Birge ratio (chi^2 per "
        "degree of freedom) scales the session's error when above 1.",
        note=True,
    )
    page.figure(
        'hits',
        hits_figure(campaign),
        'Accepted and rejected hits of every session (a cross: no mu from the session).',
    )


def hits_figure(campaign: CampaignResult) -> Figure:
    """Stacked bars: accepted and rejected hits a session; failed sessions crossed."""
    figure, axes = new_figure(1, 1, height_in=3.4, title='hits per session')
    ax = axes[0]
    ids = [session.session_id for session in campaign.table.sessions]
    accepted = np.array([result.accepted_hits for result in campaign.results])
    total = np.array([len(result.hits) for result in campaign.results])
    positions = np.arange(len(ids))
    ax.bar(positions, accepted, color=level_colour(2), label='accepted')
    ax.bar(positions, total - accepted, bottom=accepted, color=REJECTED_COLOUR, label='rejected')
    failed = [i for i, result in enumerate(campaign.results) if not result.ok]
    if failed:
        ax.plot(failed, total[failed], 'x', color='tab:red', markersize=8, label='no mu')
    step = max(1, math.ceil(len(ids) / MAX_SESSION_LABELS))
    ax.set_xticks(positions[::step], [_plain(i) for i in ids[::step]], rotation=90)
    ax.set_ylabel('hits')
    ax.legend(fontsize='small')
    return figure


def _levels(page: Page, campaign: CampaignResult) -> None:
    """The FRF level summaries of every session."""
    rows = [
        [
            session.session_id,
            level.level,
            level.count,
            f'{level.mean_impulse_n_s:.4g}',
            f'{level.peak_receptance_m_per_n * MM_PER_M:.4g}',
            f'{level.natural_frequency_hz:.4g}',
            f'{level.coherence_at_peak:.3f}',
        ]
        for session, result in zip(campaign.table.sessions, campaign.results, strict=True)
        for level in result.levels
    ]
    if not rows:
        return
    page.section('FRF levels', 'levels')
    page.figure(
        'levels',
        levels_figure(campaign),
        "Peak receptance of each session's force levels against their mean impulse, by "
        'condition: lower friction lets the same impulse move the rig further.',
    )
    page.table(
        [
            'session',
            'level',
            'hits',
            schema.label(schema.MEAN_IMPULSE),
            schema.label(schema.LEVEL_PEAK_RECEPTANCE),
            schema.label(schema.LEVEL_NATURAL_FREQUENCY),
            'coherence at f_n',
        ],
        rows,
        text_columns=(0, 1),
    )


def levels_figure(campaign: CampaignResult) -> Figure:
    """Peak receptance against mean impulse, one point per session level, by condition."""
    figure, axes = new_figure(
        1, 1, height_in=3.8, title='peak receptance against impulse, by condition'
    )
    ax = axes[0]
    by = campaign.comparison.by
    labels = [c.label for c in campaign.comparison.conditions]
    drawn = set()
    for session, result in zip(campaign.table.sessions, campaign.results, strict=True):
        label = _condition_label(by, session.conditions)
        row = labels.index(label) if label in labels else -1
        colour = level_colour(row) if row >= 0 else REJECTED_COLOUR
        for level in result.levels:
            ax.plot(
                level.mean_impulse_n_s,
                level.peak_receptance_m_per_n * MM_PER_M,
                'o',
                color=colour,
                markersize=4,
                label=_plain(label) if label not in drawn else None,
            )
            drawn.add(label)
    ax.set_xlabel(schema.label(schema.MEAN_IMPULSE))
    ax.set_ylabel(schema.label(schema.LEVEL_PEAK_RECEPTANCE))
    if drawn:
        ax.legend(fontsize='small')
    return figure


def _diagnoses(page: Page, campaign: CampaignResult) -> None:
    """What each diagnosed session's model misses."""
    page.section('Diagnosis per session', 'diagnosis')
    rows = []
    for session, result in zip(campaign.table.sessions, campaign.results, strict=True):
        diagnosis = result.diagnosis
        if diagnosis is None:
            if result.diagnosis_failure:
                rows.append([session.session_id, '-', '-', '-', result.diagnosis_failure])
            continue
        rows.append(
            [
                session.session_id,
                named_effects(diagnosis),
                _number(diagnosis.get('gap_before')),
                _number(diagnosis.get('gap_after')),
                diagnosis.get('verdict', ''),
            ]
        )
    page.table(
        ['session', 'missing effects', 'gap before', 'gap after', 'verdict'],
        rows,
        text_columns=(0, 1, 4),
    )


def _method(page: Page, comparison: CampaignComparison) -> None:
    """The statistics, in words, with the fitted scatter."""
    page.section('How the comparison is made', 'method')
    model = comparison.model
    page.text(
        "Each session gives one mu, fitted to all its accepted hits, with the fitter's "
        'standard error (scaled up by the Birge ratio when its hits disagree beyond their '
        'errors). Sessions of one condition scatter more than that: the contact changes from '
        'session to session. The comparison is a random-effects meta-regression of the '
        "sessions' mu (one mean per condition, one between-session variance tau^2 for all, "
        'estimated by restricted maximum likelihood); intervals and tests use the '
        "Knapp-Hartung t distribution, never narrower than the model's own errors. Pairwise "
        'differences are Holm-adjusted within each column and stratum.'
    )
    if model is not None:
        page.items(
            [
                f'sessions in the model: {model.count}; conditions: {len(comparison.conditions)}; '
                f'degrees of freedom: {model.dof}',
                f'between-session scatter tau = {model.tau:.3g} (tau^2 = {model.tau2:.3g}); '
                f'I^2 = {100 * model.i2:.1f} %'
                if math.isfinite(model.i2)
                else 'tau: undefined',
                f'Cochran Q = {model.heterogeneity_q:.4g}, p = {format_p(model.heterogeneity_p)} '
                "(against no scatter beyond the fits' errors)",
            ]
        )


def _number(value) -> str:
    return f'{value:.3g}' if isinstance(value, int | float) and math.isfinite(value) else '-'


def _plain(text: object) -> str:
    """Text for a figure as it is: '$' escaped, so matplotlib draws no mathtext from it."""
    return str(text).replace('$', r'\$')
