"""Across sessions: mu by condition, pairwise differences, trends, and the verdict in words.

Each session contributes its mu and the variance of it (`SessionOutcome.within_variance`:
the fitter's standard error squared, scaled up by the Birge ratio when its hits disagree
beyond their errors); sessions of one condition also scatter between themselves (tau^2). The
model is the random-effects meta-regression of `stats` (REML tau^2, Knapp-Hartung t
intervals), with one mean per condition, the condition being the combination of the `by`
columns' values:

- conditions: each condition's mean mu with its interval;
- differences: for each `by` column, every pair of its levels, within each combination of
  the other `by` columns (a simple effect) and, when there are several, averaged over them
  (the main effect, a lab's "does B lower mu?"); Holm's correction within each family (the
  pairs of one column in one stratum), so a campaign of many pairs does not find a
  difference by chance more often than the stated 5 %;
- trends: mu against a numeric or date column (days), one slope per group of the other
  `by` columns and a common slope across groups, each group with its own intercept.
"""

from __future__ import annotations

import datetime as dt
import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from fmm_ros.campaign.stats import CONFIDENCE, Contrast, MetaRegression, holm, meta_regression
from fmm_ros.campaign.table import DATE, NUMBER, Column, Value, format_value
from fmm_ros.core.results_schema import format_with_uncertainty
from fmm_ros.errors import BadInputError

ALPHA = 1.0 - CONFIDENCE
"""A difference or trend is declared when its (Holm-adjusted) p-value is below this."""
SECONDS_PER_DAY = 86_400.0
# Units read off a numeric column's name, for the trend's wording ('per N').
_NAME_UNITS = (
    ('_n', 'N'),
    ('_kg', 'kg'),
    ('_m', 'm'),
    ('_s', 's'),
    ('_hz', 'Hz'),
    ('_mm', 'mm'),
    ('_c', '°C'),
    ('_k', 'K'),
)


@dataclass(frozen=True)
class SessionMu:
    """One session's part in the comparison: its conditions, mu and mu's variance."""

    session_id: str
    conditions: Mapping[str, Value]
    mu: float
    variance: float
    hits: int = 0


@dataclass(frozen=True)
class ConditionEstimate:
    """A condition's mean mu (random-effects model) and its sessions."""

    label: str
    values: Mapping[str, Value]
    sessions: int
    hits: int
    mean_of_sessions: float
    """Plain mean of the sessions' mu (the model's estimate weights them)."""
    estimate: Contrast


@dataclass(frozen=True)
class Difference:
    """mu of one level of a column minus mu of another (`reference`)."""

    column: str
    level: str
    reference: str
    stratum: str
    """'' (the only one), 'averaged over ...' (main effect) or 'col = value, ...'."""
    estimate: Contrast
    p_adjusted: float
    """Holm-adjusted within its family (this column, this stratum)."""
    family_size: int
    different: bool

    @property
    def averaged(self) -> bool:
        """Whether this is a main effect (averaged over the other columns' levels)."""
        return self.stratum.startswith('averaged')


@dataclass(frozen=True)
class Trend:
    """The slope of mu against a column, in one group of sessions or common to all groups."""

    column: str
    unit: str
    """What the slope is per: 'N', 'day', ... ('unit of <column>' when unknown)."""
    group: str
    """The group's label, or 'all' for the common slope."""
    sessions: int
    slope: Contrast
    intercept_at: float
    """Where the line was centred (mean of the column in the group; days for dates)."""
    intercept: Contrast
    """mu at `intercept_at`."""
    line_covariance: np.ndarray
    """Covariance of (intercept, slope), for the line's confidence band."""
    origin: dt.datetime | None = None
    """For a date column: the day 0 of the x axis."""


@dataclass(frozen=True)
class CampaignComparison:
    """Everything compared across sessions, and the verdict in sentences."""

    by: tuple[str, ...]
    model: MetaRegression | None
    conditions: tuple[ConditionEstimate, ...]
    differences: tuple[Difference, ...]
    trends: tuple[Trend, ...]
    notes: tuple[str, ...]
    """What could not be compared, and why."""
    verdicts: tuple[str, ...]


def compare_sessions(
    sessions: Sequence[SessionMu],
    columns: Sequence[Column],
    by: Sequence[str],
    trend: Sequence[str] = (),
    *,
    tau2_method: str = 'reml',
) -> CampaignComparison:
    """The random-effects comparison of the sessions (see module)."""
    kinds = {column.name: column.kind for column in columns}
    for name in (*by, *trend):
        if name not in kinds:
            raise BadInputError(f'no condition column {name!r} (known: {", ".join(kinds)})')
    for name in trend:
        if kinds[name] not in (NUMBER, DATE):
            raise BadInputError(f'trend column {name!r} is text: a trend needs numbers or dates')
    by = tuple(by)
    notes: list[str] = []
    usable = [s for s in sessions if all(s.conditions.get(name) is not None for name in by)]
    if len(usable) < len(sessions):
        notes.append(
            f'{len(sessions) - len(usable)} session(s) lack a value of {", ".join(by)} '
            'and are left out of the comparison'
        )
    if not usable:
        notes.append('no session has a fitted mu to compare')
        return CampaignComparison(by, None, (), (), (), tuple(notes), ())
    levels = {name: _levels([s.conditions[name] for s in usable], kinds[name]) for name in by}
    cells = sorted(
        {tuple(s.conditions[name] for name in by) for s in usable},
        key=lambda cell: tuple(levels[name].index(v) for name, v in zip(by, cell, strict=True)),
    )
    cell_of = [cells.index(tuple(s.conditions[name] for name in by)) for s in usable]
    design = np.zeros((len(usable), len(cells)))
    design[np.arange(len(usable)), cell_of] = 1.0
    names = [condition_label(by, cell) for cell in cells]
    model = meta_regression(
        [s.mu for s in usable], [s.variance for s in usable], design, names, tau2_method=tau2_method
    )
    if model.dof < 1:
        notes.append(
            'every condition has a single session: the scatter between sessions cannot be '
            'estimated, so no interval or test is given (repeat some condition)'
        )
    conditions = tuple(
        ConditionEstimate(
            label=names[i],
            values=dict(zip(by, cell, strict=True)),
            sessions=int(design[:, i].sum()),
            hits=sum(s.hits for s, c in zip(usable, cell_of, strict=True) if c == i),
            mean_of_sessions=float(
                np.mean([s.mu for s, c in zip(usable, cell_of, strict=True) if c == i])
            ),
            estimate=model.coefficient(names[i]),
        )
        for i, cell in enumerate(cells)
    )
    differences = _differences(model, by, cells, levels)
    trends, trend_notes = _trends(usable, by, trend, kinds, tau2_method)
    notes += trend_notes
    verdicts = _verdicts(model, conditions, differences, trends)
    return CampaignComparison(
        by, model, conditions, differences, tuple(trends), tuple(notes), verdicts
    )


def _levels(values: Sequence[Value], kind: str) -> list[Value]:
    """A column's distinct values: numbers and dates ascending, text in order of appearance."""
    distinct = list(dict.fromkeys(values))
    return sorted(distinct) if kind in (NUMBER, DATE) else distinct


def condition_label(names: Sequence[str], values: Sequence[Value]) -> str:
    """'lubricant = B, normal_force_n = 9.81' ('B' for a single column)."""
    if len(names) == 1:
        return format_value(values[0])
    return ', '.join(
        f'{name} = {format_value(value)}' for name, value in zip(names, values, strict=True)
    )


def _differences(
    model: MetaRegression,
    by: tuple[str, ...],
    cells: list[tuple[Value, ...]],
    levels: Mapping[str, list[Value]],
) -> tuple[Difference, ...]:
    """Pairwise differences of each column's levels: per stratum and averaged (see module)."""
    differences: list[Difference] = []
    for position, column in enumerate(by):
        others = [name for name in by if name != column]
        strata = sorted(
            {cell[:position] + cell[position + 1 :] for cell in cells},
            key=lambda s: tuple(levels[name].index(v) for name, v in zip(others, s, strict=True)),
        )
        families: list[tuple[str, list[tuple[Value, Value, np.ndarray]]]] = []
        averaged: list[tuple[Value, Value, np.ndarray]] = []
        for stratum in strata:
            pairs = []
            for reference, level in itertools.combinations(levels[column], 2):
                cell_a = stratum[:position] + (reference,) + stratum[position:]
                cell_b = stratum[:position] + (level,) + stratum[position:]
                if cell_a in cells and cell_b in cells:
                    weights = np.zeros(len(cells))
                    weights[cells.index(cell_b)] += 1.0
                    weights[cells.index(cell_a)] -= 1.0
                    pairs.append((reference, level, weights))
            if pairs:
                where = ', '.join(
                    f'{name} = {format_value(value)}'
                    for name, value in zip(others, stratum, strict=True)
                )
                families.append((where, pairs))
        if len(strata) > 1:
            for reference, level in itertools.combinations(levels[column], 2):
                found = [
                    w for _, pairs in families for a, b, w in pairs if (a, b) == (reference, level)
                ]
                if len(found) > 1:
                    averaged.append((reference, level, np.mean(found, axis=0)))
            if averaged:
                families.insert(0, (f'averaged over {", ".join(others)}', averaged))
        for stratum_label, pairs in families:
            contrasts = [model.contrast(weights) for _, _, weights in pairs]
            adjusted = holm([c.p_value for c in contrasts])
            for (reference, level, _), contrast, p_adjusted in zip(
                pairs, contrasts, adjusted, strict=True
            ):
                differences.append(
                    Difference(
                        column=column,
                        level=format_value(level),
                        reference=format_value(reference),
                        stratum=stratum_label,
                        estimate=contrast,
                        p_adjusted=float(p_adjusted),
                        family_size=len(pairs),
                        different=bool(p_adjusted < ALPHA),
                    )
                )
    return tuple(differences)


def _trends(
    sessions: Sequence[SessionMu],
    by: tuple[str, ...],
    trend: Sequence[str],
    kinds: Mapping[str, str],
    tau2_method: str,
) -> tuple[list[Trend], list[str]]:
    """Per-group and common slopes of mu against each trend column."""
    trends: list[Trend] = []
    notes: list[str] = []
    for column in trend:
        groups_by = tuple(name for name in by if name != column)
        chosen = [s for s in sessions if s.conditions.get(column) is not None]
        if len(chosen) < len(sessions):
            missing = len(sessions) - len(chosen)
            notes.append(f'{missing} session(s) lack {column}: not in its trend')
        if not chosen:
            continue
        x, origin = _axis([s.conditions[column] for s in chosen], kinds[column])
        unit = 'day' if kinds[column] == DATE else _unit(column)
        group_keys = [tuple(s.conditions[name] for name in groups_by) for s in chosen]
        groups = list(dict.fromkeys(group_keys))
        member = np.array([[key == group for group in groups] for key in group_keys], dtype=float)
        y = [s.mu for s in chosen]
        v = [s.variance for s in chosen]
        labels = [condition_label(groups_by, g) if groups_by else 'all' for g in groups]
        # One slope a group, where the group has two values of the column or more.
        sloped = [g for g in range(len(groups)) if len(set(x[member[:, g] > 0])) > 1]
        for g in range(len(groups)):
            if g not in sloped:
                notes.append(f'{column}: sessions of {labels[g]} share one value, no slope there')
        centres = [float(np.mean(x[member[:, g] > 0])) for g in range(len(groups))]
        centred = x - member @ np.array(centres)
        design = np.column_stack([member, *(member[:, g] * centred for g in sloped)])
        if sloped and len(chosen) > design.shape[1]:
            fitted = meta_regression(y, v, design, tau2_method=tau2_method)
            for slot, g in enumerate(sloped):
                trends.append(
                    _trend(
                        column,
                        unit,
                        labels[g],
                        fitted,
                        g,
                        len(groups) + slot,
                        member,
                        centres,
                        origin,
                    )
                )
        elif sloped:
            notes.append(f'{column}: too few sessions for a slope per group and its scatter')
        if len(groups) > 1 and len(sloped) > 0 and len(chosen) > len(groups) + 1:
            common = meta_regression(
                y, v, np.column_stack([member, centred]), tau2_method=tau2_method
            )
            common_intercept = np.r_[member.mean(axis=0), 0.0]
            slope_weights = np.eye(len(groups) + 1)[-1]
            trends.append(
                Trend(
                    column=column,
                    unit=unit,
                    group='all',
                    sessions=len(chosen),
                    slope=common.contrast(slope_weights),
                    intercept_at=float(np.mean(x)),
                    intercept=common.contrast(common_intercept),
                    line_covariance=_pair_covariance(common, common_intercept, slope_weights),
                    origin=origin,
                )
            )
    return trends, notes


def _trend(
    column: str,
    unit: str,
    label: str,
    fitted: MetaRegression,
    group: int,
    slope_index: int,
    member: np.ndarray,
    centres: Sequence[float],
    origin: dt.datetime | None,
) -> Trend:
    """One group's slope and its line's centre."""
    intercept, slope = np.eye(fitted.coefficients.size)[[group, slope_index]]
    return Trend(
        column=column,
        unit=unit,
        group=label,
        sessions=int(member[:, group].sum()),
        slope=fitted.contrast(slope),
        intercept_at=centres[group],
        intercept=fitted.contrast(intercept),
        line_covariance=_pair_covariance(fitted, intercept, slope),
        origin=origin,
    )


def _pair_covariance(fitted: MetaRegression, first: np.ndarray, second: np.ndarray) -> np.ndarray:
    """Covariance of two contrasts of the fitted coefficients."""
    weights = np.vstack([first, second])
    return weights @ fitted.covariance @ weights.T


def _axis(values: Sequence[Value], kind: str) -> tuple[np.ndarray, dt.datetime | None]:
    """Numbers as they are; dates as days since the earliest (which is returned)."""
    if kind == DATE:
        origin = min(values)
        return np.array([(v - origin).total_seconds() / SECONDS_PER_DAY for v in values]), origin
    return np.array(values, dtype=float), None


def _unit(column: str) -> str:
    """The unit a column's name ends in ('normal_force_n' -> 'N')."""
    lowered = column.lower()
    for suffix, unit in _NAME_UNITS:
        if lowered.endswith(suffix):
            return unit
    return f'unit of {column}'


# -- words ------------------------------------------------------------------------------------


def _verdicts(
    model: MetaRegression,
    conditions: Sequence[ConditionEstimate],
    differences: Sequence[Difference],
    trends: Sequence[Trend],
) -> tuple[str, ...]:
    """Plain-language sentences: main effects (or the only ones), trends, the scatter."""
    lines = []
    columns_with_average = {d.column for d in differences if d.averaged}
    for difference in differences:
        if difference.averaged or difference.column not in columns_with_average:
            if not difference.stratum or difference.averaged:
                lines.append(difference_sentence(difference))
    for trend in trends:
        if trend.group == 'all' or not any(
            t.group == 'all' and t.column == trend.column for t in trends
        ):
            lines.append(trend_sentence(trend))
    if model.dof >= 1 and len(conditions):
        lines.append(
            f'Sessions of one condition scatter by tau = {model.tau:.2g} in mu between '
            f'themselves (I^2 = {100 * model.i2:.0f} % of the variance is that scatter, the rest '
            "the fits' own errors); intervals are 95 % Knapp-Hartung intervals with "
            f'{model.dof} degrees of freedom.'
        )
    return tuple(lines)


def difference_sentence(difference: Difference) -> str:
    """'lubricant B lowers mu by 0.0126 ± 0.0010 against A (95 % CI ...)', or no difference."""
    c = difference.estimate
    name = f'{difference.column} {difference.level}'
    where = f'; {difference.stratum}' if difference.stratum else ''
    value = format_with_uncertainty(c.estimate, c.stderr)
    signed = f'{difference.level} - {difference.reference} = {value}'
    if not math.isfinite(c.p_value):
        return f'{name} against {difference.reference}: {signed}, no test possible{where}.'
    adjusted = (
        f', Holm-adjusted {_p_phrase(difference.p_adjusted)} over {difference.family_size} pairs'
        if difference.family_size > 1
        else ''
    )
    if difference.different:
        verb = 'raises' if c.estimate > 0 else 'lowers'
        low, high = sorted((abs(c.ci_low), abs(c.ci_high)))
        return (
            f'{name} {verb} mu by {format_with_uncertainty(abs(c.estimate), c.stderr)} against '
            f'{difference.reference} (95 % CI {format_interval(low, high)}, '
            f'{_p_phrase(c.p_value)}{adjusted}{where}).'
        )
    return (
        f'{name} and {difference.reference}: no detectable difference, {signed} (95 % CI '
        f'{format_interval(c.ci_low, c.ci_high)}, {_p_phrase(c.p_value)}{adjusted}{where}).'
    )


def trend_sentence(trend: Trend) -> str:
    """'mu rises with normal_force_n by ... per N (95 % CI ...)', or no detectable trend."""
    c = trend.slope
    group = ' (one slope for all groups)' if trend.group == 'all' else f' for {trend.group}'
    slope = f'{format_with_uncertainty(c.estimate, c.stderr)} per {trend.unit}'
    if not math.isfinite(c.p_value):
        return f'mu against {trend.column}{group}: slope {slope}, no test possible.'
    detail = f'95 % CI {format_interval(c.ci_low, c.ci_high)}, {_p_phrase(c.p_value)}'
    if c.p_value < ALPHA:
        verb = 'rises' if c.estimate > 0 else 'falls'
        return f'mu {verb} with {trend.column}{group}: slope {slope} ({detail}).'
    return f'No detectable trend of mu with {trend.column}{group}: slope {slope} ({detail}).'


def format_interval(low: float, high: float) -> str:
    """'0.0112 to 0.0144': both ends to the decimal that gives the width three digits."""
    if not (math.isfinite(low) and math.isfinite(high)):
        return '-'
    width = high - low
    decimals = max(0, 2 - math.floor(math.log10(width))) if width > 0 else 6
    return f'{low:.{decimals}f} to {high:.{decimals}f}'


def format_p(p_value: float) -> str:
    """A p-value to two significant digits; '< 0.0001' below that, '-' when undefined."""
    if not math.isfinite(p_value):
        return '-'
    return '< 0.0001' if p_value < 1e-4 else f'{p_value:.2g}'


def _p_phrase(p_value: float) -> str:
    """'p = 0.65' or 'p < 0.0001'."""
    text = format_p(p_value)
    return f'p {text}' if text.startswith('<') else f'p = {text}'
