"""A campaign run end to end, and its results as tidy tables and JSON.

`run_campaign` runs every session of a table (`tasks.run_sessions`), pairs each result with
its row's conditions and compares the fitted sessions (`compare.compare_sessions`). The tidy
tables are one row per observation of one kind: `sessions` (a session: its conditions, hits,
mu, consistency, diagnosis, FRF linearity), `hits` (an impact), `levels` (a force level of a
session), `estimates` (a condition's mu, a difference, a slope). They are written as CSV and
as Parquet through Apache Arrow (pyarrow), whose tables keep each column's type (numbers,
booleans, timestamps for date columns) for the next program; `to_json` is the same rows.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import time
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from fmm_ros.campaign.compare import (
    CampaignComparison,
    Difference,
    SessionMu,
    Trend,
    compare_sessions,
)
from fmm_ros.campaign.session import SessionOutcome, options_dict
from fmm_ros.campaign.stats import Contrast
from fmm_ros.campaign.table import CampaignTable
from fmm_ros.campaign.tasks import run_sessions
from fmm_ros.workflows.results import json_safe
from fmm_ros.workflows.session import SessionOptions

INTERNAL_ERROR = 'internal error (a fault in fmm_ros, not the data: the traceback is in the log)'


@dataclass(frozen=True)
class CampaignResult:
    """A campaign's sessions (in table order) with their results, and the comparison."""

    table: CampaignTable
    options: SessionOptions
    results: tuple[SessionOutcome, ...]
    comparison: CampaignComparison
    by: tuple[str, ...]
    trend: tuple[str, ...]
    seconds: float
    """Wall time of running the sessions [s]."""

    @property
    def failed(self) -> list[tuple[str, str]]:
        """(session id, reason) of each session without a mu.

        A session that failed through a bug, not its data, says so first ('internal error').
        """
        return [
            (
                session.session_id,
                f'{INTERNAL_ERROR}: {result.reason}' if result.internal_error else result.reason,
            )
            for session, result in zip(self.table.sessions, self.results, strict=True)
            if not result.ok
        ]


def run_campaign(
    table: CampaignTable,
    options: SessionOptions,
    *,
    by: Sequence[str] | None = None,
    trend: Sequence[str] | None = None,
    scheduler: str | None = None,
    workers: int | None = None,
    cache_dir: str | os.PathLike | None = None,
    on_result: Callable[[int, SessionOutcome], None] | None = None,
) -> CampaignResult:
    """Run and compare a campaign: `by` and `trend` default to the table's (see `table`)."""
    by = tuple(by) if by else table.default_by()
    trend = tuple(trend) if trend is not None else table.trend
    for name in (*by, *trend):
        table.column(name)  # a misspelt column fails before hours of work
    clock = time.perf_counter()
    results = run_sessions(
        [session.spec for session in table.sessions],
        options,
        cache_dir=cache_dir,
        scheduler=scheduler,
        workers=workers,
        on_result=on_result,
    )
    seconds = time.perf_counter() - clock
    comparison = compare_sessions(session_mus(table, results), table.columns, by, trend)
    return CampaignResult(table, options, tuple(results), comparison, by, trend, seconds)


def session_mus(table: CampaignTable, results: Sequence[SessionOutcome]) -> list[SessionMu]:
    """The fitted sessions as the comparison takes them (failed ones left out)."""
    return [
        SessionMu(
            session.session_id,
            session.conditions,
            result.mu,
            result.within_variance,
            result.accepted_hits,
        )
        for session, result in zip(table.sessions, results, strict=True)
        if result.ok and math.isfinite(result.mu) and result.within_variance > 0
    ]


# -- tidy tables ----------------------------------------------------------------------------------


def tidy_tables(campaign: CampaignResult) -> dict[str, list[dict]]:
    """The four tables (see module) as lists of rows."""
    sessions, hits, levels = [], [], []
    names = [column.name for column in campaign.table.columns]
    for session, result in zip(campaign.table.sessions, campaign.results, strict=True):
        key = {'session_id': session.session_id}
        sessions.append({**key, **_conditions(session.conditions, names), **_session_row(result)})
        sessions[-1]['notes'] = session.notes
        sessions[-1]['source'] = str(session.spec.source)
        hits += [
            {**key, **dataclasses.asdict(hit), 'flags': ','.join(hit.flags)} for hit in result.hits
        ]
        levels += [{**key, **dataclasses.asdict(level)} for level in result.levels]
    return {
        'sessions': sessions,
        'hits': hits,
        'levels': levels,
        'estimates': estimate_rows(campaign.comparison),
    }


def _conditions(conditions: dict, names: Sequence[str]) -> dict:
    """Condition values under their column names (prefixed where a result column has it)."""
    taken = {field.name for field in dataclasses.fields(SessionOutcome)} | {
        'session_id',
        'accepted_hits',
        'rejected_hits',
        'notes',
        'source',
    }
    return {(f'condition_{name}' if name in taken else name): conditions[name] for name in names}


def _session_row(result: SessionOutcome) -> dict:
    """A session's scalars."""
    rejected = Counter(flag for hit in result.hits if not hit.accepted for flag in hit.flags)
    diagnosis = result.diagnosis or {}
    return {
        'status': result.status,
        'reason': result.reason,
        'cached': result.cached,
        'hits': len(result.hits),
        'accepted_hits': result.accepted_hits,
        'rejected_hits': len(result.hits) - result.accepted_hits,
        'rejection_flags': ','.join(f'{flag}:{count}' for flag, count in sorted(rejected.items())),
        'normal_force_n': result.normal_force_n,
        'mu': result.mu,
        'mu_stderr': result.mu_stderr,
        'consistency_chi2': result.consistency_chi2,
        'consistency_p_value': result.consistency_p_value,
        'birge_ratio': result.birge_ratio if result.ok else math.nan,
        'mu_stderr_campaign': math.sqrt(result.within_variance) if result.ok else math.nan,
        'damping_n_s_per_m': result.damping_n_s_per_m,
        'residual_rms_m_s': result.residual_rms_m_s,
        'linearity_slope': result.linearity_slope,
        'linearity_r2': result.linearity_r2,
        'missing_effects': named_effects(diagnosis),
        'diagnosis_verdict': diagnosis.get('verdict', '') or result.diagnosis_failure,
        'problems': '; '.join(result.problems),
        **{f'seconds_{step}': value for step, value in result.seconds.items()},
    }


def named_effects(diagnosis: dict) -> str:
    """The effects a diagnosis named ('unexplained' and 'mu_drift' among them), or 'none'."""
    if not diagnosis:
        return ''
    names = [entry['effect'] for entry in diagnosis.get('missing_effects', ())]
    return ', '.join(names) or diagnosis.get('missing_effect', '')


def estimate_rows(comparison: CampaignComparison) -> list[dict]:
    """Condition means, differences and slopes, one row each, in one set of columns."""
    rows = []
    for condition in comparison.conditions:
        rows.append(
            _estimate_row(
                'condition',
                condition.estimate,
                column=', '.join(comparison.by),
                label=condition.label,
                sessions=condition.sessions,
                hits=condition.hits,
            )
        )
    for difference in comparison.differences:
        rows.append(_difference_row(difference))
    for trend in comparison.trends:
        rows.append(_trend_row(trend))
    return rows


def _difference_row(difference: Difference) -> dict:
    return _estimate_row(
        'difference',
        difference.estimate,
        column=difference.column,
        label=difference.level,
        reference=difference.reference,
        stratum=difference.stratum,
        p_adjusted=difference.p_adjusted,
        significant=difference.different,
    )


def _trend_row(trend: Trend) -> dict:
    return _estimate_row(
        'slope',
        trend.slope,
        column=trend.column,
        label=f'per {trend.unit}',
        stratum=trend.group,
        sessions=trend.sessions,
        significant=bool(trend.slope.p_value < 0.05),
    )


def _estimate_row(kind: str, estimate: Contrast, **fields) -> dict:
    """One row of the estimates table (missing fields empty or NaN)."""
    return {
        'kind': kind,
        'column': fields.get('column', ''),
        'label': fields.get('label', ''),
        'reference': fields.get('reference', ''),
        'stratum': fields.get('stratum', ''),
        'estimate': estimate.estimate,
        'stderr': estimate.stderr,
        'ci_low': estimate.ci_low,
        'ci_high': estimate.ci_high,
        'dof': estimate.dof,
        't_value': estimate.t_value,
        'p_value': estimate.p_value,
        'p_adjusted': fields.get('p_adjusted', estimate.p_value),
        'significant': fields.get('significant'),
        'sessions': fields.get('sessions'),
        'hits': fields.get('hits'),
    }


def write_tables(campaign: CampaignResult, out_dir: str | Path) -> list[Path]:
    """Each tidy table as `<name>.csv` and `<name>.parquet` in out_dir; the paths written."""
    import pyarrow as pa
    import pyarrow.csv as pa_csv
    import pyarrow.parquet as pq

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    for name, rows in tidy_tables(campaign).items():
        table = pa.Table.from_pylist([_arrow_row(row) for row in rows])
        for path in (out_dir / f'{name}.csv', out_dir / f'{name}.parquet'):
            if path.suffix == '.csv':
                pa_csv.write_csv(table, path)
            else:
                pq.write_table(table, path)
            written.append(path)
    return written


def _arrow_row(row: dict) -> dict:
    """NaN as a missing value (null), as Arrow and CSV readers expect."""
    return {
        k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in row.items()
    }


# -- JSON -----------------------------------------------------------------------------------------


def to_json(campaign: CampaignResult) -> dict:
    """The campaign as one JSON-ready object (undefined numbers as null, dates as ISO text)."""
    comparison = campaign.comparison
    model = comparison.model
    tables = tidy_tables(campaign)
    document = {
        'table': str(campaign.table.path),
        'by': list(campaign.by),
        'trend': list(campaign.trend),
        'sessions_total': len(campaign.results),
        'sessions_fitted': sum(result.ok for result in campaign.results),
        'sessions_cached': sum(result.cached for result in campaign.results),
        'failed': [{'session_id': i, 'reason': why} for i, why in campaign.failed],
        'seconds': campaign.seconds,
        'options': options_dict(campaign.options),
        'model': None
        if model is None
        else {
            'method': f'random-effects meta-regression, {model.tau2_method.upper()} tau^2, '
            'Knapp-Hartung t intervals',
            'tau': model.tau,
            'tau2': model.tau2,
            'tau2_stderr': model.tau2_stderr,
            'i2': model.i2,
            'dof': model.dof,
            'knapp_hartung_scale': model.scale,
            'heterogeneity_q': model.heterogeneity_q,
            'heterogeneity_p': model.heterogeneity_p,
        },
        'verdicts': list(comparison.verdicts),
        'notes': list(comparison.notes),
        'estimates': tables['estimates'],
        'sessions': tables['sessions'],
        'hits': tables['hits'],
        'levels': tables['levels'],
        'diagnoses': {
            session.session_id: result.diagnosis
            for session, result in zip(campaign.table.sessions, campaign.results, strict=True)
            if result.diagnosis is not None
        },
    }
    return json_safe(document)


def write_json(campaign: CampaignResult, path: str | Path) -> Path:
    """`to_json` written to path."""
    path = Path(path)
    path.write_text(json.dumps(to_json(campaign), indent=1, allow_nan=False), encoding='utf-8')
    return path
