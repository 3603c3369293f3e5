"""What the station page shows, as JSON events: the rig's messages decimated for display.

`StationState` takes what the rig publishes (impact results, their records, level averages,
the running mu, /diagnostics, decisions, session metadata; duck-typed messages, so it needs
no ROS) and turns each into one event for the page (`emit(name, payload)`), keeping the
newest of each so a page that connects, or reconnects after the station or a source
restarted, starts from `snapshot()`. Traces are decimated for display (`envelope`: each
bucket's min and max, so a 10,000-sample pulse keeps its peak in 600 points); numbers are
shown in the report's units (N, mm/s, mm/(N*s), degrees). A hit's figures are kept for the
last `FIGURE_HITS` only, so memory stays flat over a session of any length.
"""

from __future__ import annotations

import math
import threading
from collections import OrderedDict
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from fmm_ros.constants import MM_PER_M
from fmm_ros.core import results_schema as schema
from fmm_ros.core.physics.rig import FMM_RIG, Rig
from fmm_ros.core.signal.judging import Decision, is_taken
from fmm_ros.core.signal.records import ImpactRecord
from fmm_ros.io.session_info import FIELDS, SessionInfo
from fmm_ros.workflows.model import ModelOverlay, decay_end_s

HIT_NUMBERS = (schema.PEAK_FORCE, schema.IMPULSE, schema.NATURAL_FREQUENCY)
"""The numbers of a hit's row, under their schema keys (the page reads them by key)."""
FIGURE_HITS = 12
"""Hits whose figures (pulse, decay, FRF) are kept for a page that connects [-]."""
SUMMARY_HITS = 500
"""Hits listed (one row each) [-]."""
TRACE_POINTS = 600
"""Buckets a trace is decimated to (each gives its min and max) [-]."""
PULSE_BEFORE_S = 0.002
PULSE_AFTER_S = 0.012
"""The zoomed pulse: this long before and after the trigger [s]."""

Emit = Callable[[str, dict], None]


@dataclass(frozen=True)
class Level:
    """A nominal force level: its name, peak force [N] and the tolerance around it [N]."""

    name: str
    peak_force_n: float
    tolerance_n: float


def envelope(values: np.ndarray, buckets: int = TRACE_POINTS) -> tuple[np.ndarray, np.ndarray]:
    """(sample positions, values) of a trace decimated to each bucket's min and max.

    A trace of at most 2 x buckets samples is returned whole. NaN (samples that never
    arrived) stays NaN where a whole bucket is missing, so a gap shows as a gap.
    """
    count = values.size
    if count <= 2 * buckets:
        return np.arange(count), values
    per = count // buckets
    used = per * buckets
    blocks = values[:used].reshape(buckets, per)
    lows, highs = np.fmin.reduce(blocks, axis=1), np.fmax.reduce(blocks, axis=1)
    centres = np.arange(buckets) * per + per // 2
    return np.repeat(centres, 2), np.column_stack((lows, highs)).ravel()


def numbers(values: Sequence[float] | np.ndarray, decimals: int) -> list[float | None]:
    """Values rounded for display, NaN and infinities as None (JSON null)."""
    rounded = np.round(np.asarray(values, dtype=float), decimals)
    return [value if math.isfinite(value) else None for value in rounded.tolist()]


def _number(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


class StationState:
    """The newest of everything the page shows; each change also goes out as an event."""

    def __init__(
        self,
        levels: Sequence[Level],
        *,
        target_hits: int,
        mode: str,
        rig: Rig = FMM_RIG,
        rest_velocity_m_s: float = 1e-4,
        emit: Emit | None = None,
    ) -> None:
        self.levels = tuple(levels)
        self.target_hits = target_hits
        self.mode = mode
        self.rig = rig
        self.rest_velocity_m_s = rest_velocity_m_s
        self.emit: Emit = emit or (lambda name, payload: None)
        self._lock = threading.Lock()
        self.hits: OrderedDict[int, dict] = OrderedDict()
        self.figures: OrderedDict[int, dict] = OrderedDict()
        self.decisions: dict[int, Decision] = {}
        self.level_averages: dict[str, dict] = {}
        self.friction: dict | None = None
        self.diagnostics: dict[str, dict] = {}
        self.session: SessionInfo | None = None
        self.stream: dict | None = None
        self.mu: float | None = None

    # -- what the page starts from --------------------------------------------------------------

    def snapshot(self) -> dict:
        """Everything the page shows now (what a page gets when it (re)connects)."""
        with self._lock:
            return {
                'config': self._config(),
                'hits': list(self.hits.values()),
                'figures': list(self.figures.values()),
                'levels': list(self.level_averages.values()),
                'friction': self.friction,
                'diagnostics': list(self.diagnostics.values()),
                'progress': self._progress(),
                'session': self._session(),
                'stream': self.stream,
            }

    def _config(self) -> dict:
        return {
            'levels': [
                {'name': lv.name, 'peak_force_n': lv.peak_force_n, 'tolerance_n': lv.tolerance_n}
                for lv in self.levels
            ],
            'target_hits': self.target_hits,
            'columns': {field.name: schema.label(field, short=True) for field in HIT_NUMBERS},
            'mode': self.mode,
            'session_fields': [
                {
                    'name': f.name,
                    'label': f.label,
                    'unit': f.unit,
                    'numeric': f.numeric,
                    'max_chars': f.max_chars,
                }
                for f in FIELDS
            ],
        }

    def known(self, impact_id: int) -> dict | None:
        """The listed hit of impact_id (None: the station has not seen it)."""
        with self._lock:
            return self.hits.get(impact_id)

    # -- the rig's messages -----------------------------------------------------------------------

    def on_impact(self, msg: object) -> None:
        """An ImpactResult: its row, and its FRF at once (the record's figures follow)."""
        impact_id = int(msg.impact_id)
        mobility = np.asarray(msg.mobility_real) + 1j * np.asarray(msg.mobility_imag)
        row = {
            'id': impact_id,
            'trigger': int(msg.trigger_sample_index),
            schema.LEVEL.name: msg.level,
            schema.ACCEPTED.name: bool(msg.accepted),
            schema.FLAGS.name: list(msg.flags),
            **{field.name: _number(getattr(msg, field.name)) for field in HIT_NUMBERS},
        }
        figure = {
            'id': impact_id,
            'frf': {
                'f': numbers(msg.frequency_hz, 4),
                'magnitude': numbers(np.abs(mobility) * MM_PER_M, 5),
                'phase_deg': numbers(np.degrees(np.angle(mobility)), 2),
            },
        }
        with self._lock:
            self._list(impact_id, row)
            self.figures[impact_id] = figure
            while len(self.figures) > FIGURE_HITS:
                self.figures.popitem(last=False)
            progress = self._progress()
        self.emit('hit', row)
        self.emit('figure', figure)
        self.emit('progress', progress)

    def _list(self, impact_id: int, row: dict) -> None:
        row['taken'] = is_taken(impact_id, row['accepted'], self.decisions)
        decision = self.decisions.get(impact_id)
        row['decision'] = _decision(decision) if decision else None
        self.hits[impact_id] = row
        while len(self.hits) > SUMMARY_HITS:
            self.hits.popitem(last=False)

    def on_record(self, impact_id: int, record: ImpactRecord) -> None:
        """A hit's record: the zoomed pulse, and the decay with the model at the current mu."""
        offset = record.trigger_offset or 0
        rate = record.sample_rate_hz
        first = max(0, offset - round(PULSE_BEFORE_S * rate))
        pulse = record.force_n[first : offset + round(PULSE_AFTER_S * rate)]
        end = offset + round(
            decay_end_s([record.velocity_m_s], offset, rate, self.rest_velocity_m_s) * rate
        )
        velocity = record.velocity_m_s[:end]
        mu = self.mu
        model = (
            ModelOverlay(mu, 'live', self.rig).velocity_m_s(record, impact_id)
            if mu is not None
            else None
        )
        positions, measured = envelope(velocity)
        decay = {
            't': numbers((positions - offset) / rate, 4),
            'velocity': numbers(measured * MM_PER_M, 4),
            'model': numbers(model[:end][positions] * MM_PER_M, 4) if model is not None else None,
            'mu': mu,
        }
        update = {
            'id': impact_id,
            'pulse': {
                't': numbers((np.arange(first, first + pulse.size) - offset) / rate * 1e3, 3),
                'force': numbers(pulse, 1),
            },
            'decay': decay,
        }
        with self._lock:
            figure = self.figures.get(impact_id)
            if figure is None:  # older than the figures kept
                return
            figure.update(update)
        self.emit('figure', figure)

    def on_level(self, msg: object) -> None:
        """A FrfSummary: the level's coherence and mean FRF as its average builds."""
        mobility = np.asarray(msg.h1_mobility_real) + 1j * np.asarray(msg.h1_mobility_imag)
        level = {
            'name': msg.level,
            'count': int(msg.count),
            'impact_ids': [int(i) for i in msg.impact_ids],
            'f': numbers(msg.frequency_hz, 4),
            'coherence': numbers(msg.coherence, 4),
            'magnitude': numbers(np.abs(mobility) * MM_PER_M, 5),
            'linearity_r2': _number(msg.linearity_r2),
        }
        with self._lock:
            self.level_averages[msg.level] = level
        self.emit('level', level)

    def on_friction(self, msg: object) -> None:
        """A FrictionEstimate: the running mu, its band, the one-mu p-value, mu per level."""
        friction = {
            'impact_id': int(msg.impact_id),
            'impact_ids': [int(i) for i in msg.impact_ids],
            'count': int(msg.count),
            'mu': _number(msg.mu),
            'mu_stderr': _number(msg.mu_stderr),
            'p_value': _number(msg.consistency_p_value),
            'impact_mu': _number(msg.impact_mu),
            'levels': [
                {'name': name, 'count': int(count), 'mu': _number(mu), 'mu_stderr': _number(se)}
                for name, count, mu, se in zip(
                    msg.level_names,
                    msg.level_counts,
                    msg.level_mu,
                    msg.level_mu_stderr,
                    strict=True,
                )
            ],
        }
        with self._lock:
            self.friction = friction
            self.mu = friction['mu']
        self.emit('friction', friction)

    def on_decision(self, decision: Decision) -> None:
        """A decision about a hit: its row shows it and whether a fit takes it now."""
        with self._lock:
            self.decisions[decision.impact_id] = decision
            row = self.hits.get(decision.impact_id)
            if row is not None:
                self._list(decision.impact_id, row)
            progress = self._progress()
        if row is not None:
            self.emit('hit', row)
        self.emit('progress', progress)

    def on_diagnostics(self, statuses: Sequence[tuple[str, str, str]]) -> None:
        """/diagnostics statuses (name, level name, message): the health table."""
        rows = [
            {'name': name, 'level': level, 'message': message} for name, level, message in statuses
        ]
        with self._lock:
            for row in rows:
                self.diagnostics[row['name']] = row
        self.emit('diagnostics', {'rows': rows})

    def on_session(self, info: SessionInfo) -> None:
        """The session's metadata as published."""
        with self._lock:
            self.session = info
            session = self._session()
        self.emit('session', session)

    def on_stream(
        self, first_index: int, rate_hz: float, force: np.ndarray, velocity: np.ndarray
    ) -> None:
        """The streams' last seconds (both channels from first_index), decimated."""
        count = min(force.size, velocity.size)
        positions, force_shown = envelope(force[:count])
        _, velocity_shown = envelope(velocity[:count])
        stream = {
            't': numbers((first_index + positions) / rate_hz, 4),
            'force': numbers(force_shown, 1),
            'velocity': numbers(velocity_shown * MM_PER_M, 4),
        }
        with self._lock:
            self.stream = stream
        self.emit('stream', stream)

    # -- derived ----------------------------------------------------------------------------------

    def _session(self) -> dict | None:
        if self.session is None:
            return None
        return {
            name: None if isinstance(value, float) and math.isnan(value) else value
            for name, value in self.session.items()
        }

    def _progress(self) -> dict:
        """Per level: hits a fit takes of the target; the last hit's peak against its aim."""
        taken = {lv.name: 0 for lv in self.levels}
        for row in self.hits.values():
            if row['taken'] and row['level'] in taken:
                taken[row['level']] += 1
        aim = next((lv for lv in self.levels if taken[lv.name] < self.target_hits), None)
        last = next(reversed(self.hits.values()), None)
        advice = ''
        if last is not None and aim is not None and last['peak_force_n'] is not None:
            peak = last['peak_force_n']
            if peak > aim.peak_force_n + aim.tolerance_n:
                advice = 'softer'
            elif peak < aim.peak_force_n - aim.tolerance_n:
                advice = 'harder'
            else:
                advice = 'on target'
        return {
            'levels': [
                {
                    'name': lv.name,
                    'taken': taken[lv.name],
                    'target': self.target_hits,
                    'peak_force_n': lv.peak_force_n,
                    'tolerance_n': lv.tolerance_n,
                }
                for lv in self.levels
            ],
            'aim': aim.name if aim else None,
            'last_peak_force_n': last['peak_force_n'] if last else None,
            'last_id': last['id'] if last else None,
            'advice': advice,
        }


def _decision(decision: Decision) -> dict:
    return {
        'verdict': decision.verdict,
        'decided_by': decision.decided_by,
        'reason': decision.reason,
        'mode': decision.mode,
    }
