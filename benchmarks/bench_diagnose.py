"""Diagnose workflow: confusion tables per world (held-out worlds apart) and its time.

Run: .venv/bin/python benchmarks/bench_diagnose.py [--quick] [--cases N] [--world-cases W]
     [--heldout-cases H] [--seed S] [--repeats R] [--session-hits K] [--skip-sweep]
     [--kinds K,...] [--worlds W,...] [--role all|tuning|held-out] [--floors F,...]
     [--limit-multiples M,... [--limit-cases C]]

Generators of sessions, each with its role declared once in `test/heldout` (`ROLES`):
tuning worlds, which the diagnosis's thresholds were chosen on, and held-out worlds, never
used to choose one (a world looked at before a threshold changed becomes a tuning world).

Tuning: `ours` (`fmm_ros.sim.hidden_effects`, N sessions of each kind): one model term
hidden in three hits, sized 1-4x the velocity noise after the base fit; a pair of
distinct terms, 2-4x each; mu drifting over eight hits; a law outside the
vocabulary (answer 'unexplained'); clean sessions of three and eight hits. `worlds` (test/,
`world_cases.py`, W of each kind): its laws and effects, continuous-force hits, an
anti-alias filter, hum, drift and an ADC; run-in over eight hits of a continuous recording;
three laws outside the vocabulary.

The `test/heldout` worlds (H of each kind): `events` (event-located DOP853, half-sine and Hertzian
hits with sub-sample onsets, white noise, a Butterworth chain with a 0.22 N force offset), `steps`
(fixed-step RK4, Hertzian and two-exponential hits, white plus coloured noise, a Bessel chain, 60
Hz hum, random-walk drift; a tuning world since the calibration of 'unexplained' was designed
against it), `ivp` (LSODA phases of a stick-slip state machine, haversine and gamma pulses, a
sigma-delta FIR, white plus pink noise; a tuning world since the further refits were built after a
miss on it), `analytic` (closed-form slides and Radau, rubber-tip pulses with a rebound, 10, 10.24
or 12.8 kHz a session, a Chebyshev chain, 1/f^alpha noise, hits from rest in the friction band with
fitted starts; its table also counts right answers per sample rate; a tuning world since a
three-hit drift is told from a speed law by the hits' maps side by side, a change made after a
miss on it), `moreau` (Moreau-Jean time
stepping with the Coulomb law solved exactly each step, a hammer body striking through a Hertzian
tip, a DSA's delay-compensated FIR at 8, 10.24 or 25.6 kHz, white noise and mains hum, 16 bits,
continuous sessions with fitted starts), `bristle` (a LuGre bristle state by BDF,
double-exponential pulses, an AC-coupled force and a vibrometer decoder through an elliptic filter,
red noise, 10, 12 or 20 kHz, starts as `analytic`; a tuning world since a chained session's screen
follows the chain, a change made after looking at its misses) and `newmark` (implicit Newmark-beta
steps with Newton and the stop located within its step, a Kelvin-Voigt hammer tip, a prewarped
bilinear Chebyshev II chain at 10 or 16.384 kHz, a settling charge-amplifier zero, floor vibration
on the velocity, 24 bits, starts as `analytic`) and `karnopp` (explicit RK4 with Karnopp's
stick-slip window, a Hunt-Crossley hammer striking the moving rig, a Bessel chain by first-order
hold at 10 or 20.48 kHz, a vibrometer tracking filter, a multiplexed ADC's skew, random-walk
drift, 16 bits, starts as `analytic`): each of the seven effects alone, a pair, mu
drifting 4-7 % a hit over three hits, a wear track (answer 'unexplained'), clean sessions; and
continuous sessions whose starts the diagnosis chains (`asymmetric_chained`, `none_chained`: each
hit from where the one before left the rig, the first from the centre). Their roles are
`heldout.ROLES`.
The targets, on held-out worlds: single effects >= 15 of 16 per world, pairs >= 5 of
6, false alarms <= 5 %, drift >= 90 %, the gap at least halved whenever an effect is named.
Beside them, the single effects are also counted over the sessions the base model misses by at
least MIN_EXCESS (0.5x the noise), the floor the diagnosis names an effect from: the sizes are
drawn as effect parameters, and on a world with weak hits some leave a misfit the diagnosis is
built not to speak of. The targets are judged on every session.

Each table: rows what was hidden, columns the first effect named (`missing_effect`), how many
were exactly right (the named set is the hidden set; 'unexplained' first for a law outside
the vocabulary) and every miss. Then the time of one diagnosis of three 33 s impacts (hidden
Stribeck) and of a 30-hit session with each start fitted, against the closed-world
algorithm (`closed_world_diagnose.py`) in the same run, and a 30-hit Stribeck session (<= 2 s;
three hits <= 0.5 s; each line with its CPU time and the load average it was taken at).
A full run writes its sections of RESULTS.md (`results_file`: tuning worlds, held-out worlds
and time, each replaced only by a run that made it; --role sweeps one role; --kinds sweeps
only those kinds of every world that makes them, into a section of their own; --worlds
sweeps only the worlds named, into a section of their own too); --quick (one session of a
few kinds on the first world of each role, three-hit timing) writes nothing. --floors
measures what a lower whole-misfit floor (MIN_WHOLE_EXCESS) would answer: each session it
could change is diagnosed again at each floor, and each world's summary says what was
gained and lost.
--limit-multiples 1.5,1.2 reports instead, per kind on each held-out world, how often an effect
set at those multiples of the limit a clean session of C states is named (`bench_limits`: the
same hits, chain and noise diagnosed clean, then with the effect), against at least 90 % per
kind at 1.5x (1.2x aimed for) and at most 5 % clean sessions naming anything; a section each.
Pairs are also counted with each effect under its session's stated limit excused (not a miss).
"""

import argparse
import contextlib
import math
import re
import statistics
import sys
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from closed_world_diagnose import diagnose_closed_world
from results_file import QUICK_HELP, write_section

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / 'test'))
from heldout import HELD_OUT, ROLES  # noqa: E402
from heldout.cases import KINDS as HELDOUT_KINDS  # noqa: E402
from heldout.cases import WORLDS as HELDOUT_WORLDS  # noqa: E402
from heldout.cases import case as heldout_case  # noqa: E402
from heldout.cases import drawn_effects  # noqa: E402
from world_cases import OUTSIDE_KINDS, VOCABULARY_KINDS, world_case  # noqa: E402

from fmm_ros.constants import MU_DRIFT
from fmm_ros.core.diagnose import workflow
from fmm_ros.core.diagnose.result import Candidate
from fmm_ros.core.diagnose.workflow import (
    MIN_EXCESS,
    MIN_WHOLE_EXCESS,
    NONE,
    UNEXPLAINED,
    WHOLE_MISFIT_SHARE,
    diagnose,
)
from fmm_ros.core.identify.conditioning import as_conditioned
from fmm_ros.core.identify.spec import CENTRE, FITTED, start_options
from fmm_ros.core.physics.terms import MODEL_TERMS
from fmm_ros.core.signal.capture import capture_impacts
from fmm_ros.sim.hidden_effects import (
    OUT_OF_VOCABULARY,
    hidden_effect_case,
    hidden_session,
)
from fmm_ros.sim.session import simulated_session
from fmm_ros.workflows.results import detection_limit_dict

DEFAULT_SEED = 2019
TARGET_FALSE_ALARMS = 0.05
TARGET_SESSION_S = 5.0
TARGET_THREE_S = 0.5
TARGET_STRIBECK_SESSION_S = 2.0
"""The 30-hit Stribeck session's diagnosis, each start fitted [s wall, on a quiet machine]."""
TARGET_SINGLES = 15 / 16
TARGET_PAIRS = 5 / 6
TARGET_DRIFT = 0.9
PAIR_RATIOS = (2.0, 4.0)
DRIFT_HITS = 8
QUICK_KINDS = ('stribeck', MU_DRIFT, 'none')

SHORT = {
    'viscous_damping': 'visc',
    'stribeck': 'strib',
    'asymmetric_friction': 'asym',
    'cubic_stiffness': 'cubic',
    'second_mode': 'mode2',
    'velocity_offset': 'offs',
    'sensor_delay': 'delay',
    MU_DRIFT: 'drift',
    'speed_regimes': 'speed',
    'wear_track': 'wear',
    'pair': 'pair',
    'wear_patch': 'patch',
    'none': 'none',
    'none8': 'none8',
    'asymmetric_chained': 'asym ch',
    'none_chained': 'none ch',
    UNEXPLAINED: 'unexpl',
}
OURS_ROWS = (*MODEL_TERMS, 'pair', MU_DRIFT, *OUT_OF_VOCABULARY, 'none', 'none8')
WORLD_ROWS = (*VOCABULARY_KINDS, 'pair', MU_DRIFT, *OUTSIDE_KINDS, 'none', 'none8')
COLUMNS = (*MODEL_TERMS, MU_DRIFT, UNEXPLAINED, NONE)
OUTSIDE = (*OUT_OF_VOCABULARY, *OUTSIDE_KINDS)
CLEAN = ('none', 'none8', 'none_chained')
SINGLES = (*MODEL_TERMS, 'asymmetric_chained')
"""Rows hiding one vocabulary effect (a chained session's asymmetry too)."""
SIZE_BANDS = (0.0, MIN_WHOLE_EXCESS, MIN_EXCESS, 1.0, math.inf)
"""Edges of the bands of the base model's miss [noise RMS] the single effects are counted in:
under the floor for a whole misfit, under the floor, to one noise RMS, beyond (a detection
rate by size, as a lab would quote a sensor's)."""
REFUSED_FOR_SIZE = re.compile(
    r'accounts for only ([.\d]+)x the noise RMS \((\d+) % of the squared gap\)'
)
"""How the selection log says a refit was refused for its size (`workflow._Session._choose`)."""


def draw_ours(kind: str, rng: np.random.Generator):
    """(records, hidden effects, drawn sizes, where the hits start) of a session of ours."""
    if kind in MODEL_TERMS or kind == 'none':
        drawn = hidden_effect_case(kind, rng)
        hidden = () if kind == 'none' else (kind,)
        return drawn.records, hidden, {kind: drawn.ratio}, CENTRE
    if kind == 'pair':
        pair = tuple(str(e) for e in rng.choice(list(MODEL_TERMS), size=2, replace=False))
        session = hidden_session(pair, rng, ratio_range=PAIR_RATIOS)
    elif kind == MU_DRIFT:
        session = hidden_session((MU_DRIFT,), rng, n_impacts=DRIFT_HITS)
    elif kind == 'none8':
        session = hidden_session((), rng, n_impacts=DRIFT_HITS)
    else:
        session = hidden_session((kind,), rng, ratio_range=PAIR_RATIOS)
    return session.records, session.effects, session.ratios, CENTRE


def draw_world(kind: str, rng: np.random.Generator):
    """A worlds session: (records, hidden, sizes unknown beforehand, where the hits start)."""
    records, hidden, fit_starts = world_case(kind, rng)
    return records, hidden, {}, FITTED if fit_starts else CENTRE


def draw_held_out(world) -> Callable:
    """The session drawer of a held-out world."""

    def draw(kind: str, rng: np.random.Generator):
        records, hidden, starts = heldout_case(world, kind, rng)
        return records, hidden, {}, starts

    return draw


HIDDEN_SIZE = {
    'viscous_damping': 'added_damping_n_s_per_m',
    'stribeck': 'static_excess',
    'asymmetric_friction': 'asymmetry',
    'cubic_stiffness': 'cubic_n_per_m3',
    'second_mode': 'mode_mass_kg',
    'velocity_offset': 'velocity_offset_m_s',
    'sensor_delay': 'lag_s',
    MU_DRIFT: 'mu_step',
}
"""Each term's size parameter (`EFFECT_SIZE`) as the field of the held-out worlds' `Effects` it
is drawn into: the same quantity in the same unit (mu_drift's change a hit as a fraction of
mu, `drift.DRIFT_SIZE`: the worlds compound it, mu (1 + mu_step)^i)."""


def truth_held_out(world) -> Callable:
    """The true sizes of a held-out world's hidden effects.

    (kind, generator in the state the session was drawn from) -> {effect: (size, a magnitude
    in the term's size unit; the frequency it acts at [Hz], NaN but for a second mode)}.
    """

    def truth(kind: str, rng: np.random.Generator) -> dict[str, tuple[float, float]]:
        _, hidden, effects = drawn_effects(world, kind, rng)
        return {
            e: (
                abs(getattr(effects, HIDDEN_SIZE[e])),
                effects.mode_hz if e == 'second_mode' else math.nan,
            )
            for e in hidden
            if e in HIDDEN_SIZE
        }

    return truth


@dataclass(frozen=True)
class Source:
    """One generator of sessions: its name, rows (kinds) and drawer."""

    name: str
    rows: tuple[str, ...]
    draw: Callable
    truth: Callable | None = None
    """The true sizes of a session's hidden effects (`truth_held_out`), where known."""

    @property
    def role(self) -> str:
        """'tuning' or 'held out', as test/heldout declares it."""
        return ROLES[self.name]


SOURCES = (
    Source('ours', OURS_ROWS, draw_ours),
    Source('worlds', WORLD_ROWS, draw_world),
    *(
        Source(name, HELDOUT_KINDS, draw_held_out(world), truth_held_out(world))
        for name, world in HELDOUT_WORLDS.items()
    ),
)


def right(kind: str, hidden: tuple[str, ...], named: tuple[str, ...]) -> bool:
    """Whether a diagnosis answered a kind of session rightly."""
    if kind in OUTSIDE:
        return bool(named) and named[0] == UNEXPLAINED
    return set(named) == set(hidden) and len(named) == len(hidden)


@dataclass
class Sweep:
    """What one source's sweep found."""

    source: Source
    cases: int
    rows: tuple[str, ...]
    confusion: dict = field(default_factory=dict)
    exact: Counter = field(default_factory=Counter)
    sizes: dict = field(default_factory=dict)
    misses: list = field(default_factory=list)
    seconds: list = field(default_factory=list)
    shrink: list = field(default_factory=list)
    not_halved: int = 0
    named_sessions: int = 0
    left: list = field(default_factory=list)
    rates: dict = field(default_factory=dict)
    """Sample rate [Hz] -> [right, sessions] (a world recording at more than one)."""
    crashes: list = field(default_factory=list)
    """Sessions whose diagnosis raised (each a miss): kind, case, the error."""
    visible: dict = field(default_factory=dict)
    """Single-effect row -> [right, sessions] over the sessions whose base misfit is at least
    MIN_EXCESS (the floor the diagnosis speaks from): how often an effect it can see is named."""
    by_size: dict = field(default_factory=dict)
    """Index into SIZE_BANDS -> [right, sessions] over the single-effect sessions."""
    by_limit: dict = field(default_factory=dict)
    """Single-effect or pair row -> {True: [right, sessions] whose hidden effects are each at
    least the size the diagnosis said the records show them from (`Candidate.detection_limit`),
    False: one under}."""
    excused: list = field(default_factory=lambda: [0, 0])
    """[right, sessions] over the pairs whose limits are known, effects under their stated
    limit excused (`right_excused`)."""
    slowest: tuple[float, str] = (0.0, '')
    """The longest diagnosis [s] and which session it was."""
    floors: dict = field(default_factory=dict)
    """A lower whole-misfit floor [noise RMS] -> Floor: what the sessions it could change said
    when diagnosed again with MIN_WHOLE_EXCESS at it (`--floors`)."""

    def rate(self, kinds, exact: Counter | None = None) -> tuple[int, int]:
        """(right, sessions) over some rows; by `exact` (kind -> right) instead of the sweep's."""
        kinds = [k for k in kinds if k in self.rows]
        exact = self.exact if exact is None else exact
        return sum(exact[k] for k in kinds), self.cases * len(kinds)

    def table(self) -> list[str]:
        """The confusion table as text lines (markdown-compatible)."""
        head = ['hidden', *(SHORT[c] for c in COLUMNS), 'right', 'size']
        lines = ['| ' + ' | '.join(head) + ' |', '|' + '---|' * len(head)]
        for row in self.rows:
            counts = [str(self.confusion[row][c]) for c in COLUMNS]
            size = f'{np.median(self.sizes[row]):.1f}' if self.sizes[row] else '-'
            cells = [SHORT[row], *counts, f'{self.exact[row]}/{self.cases}', size]
            lines.append('| ' + ' | '.join(cells) + ' |')
        return lines

    def summary(self) -> list[str]:
        """The figures under the table, one a line."""
        total, sessions = self.rate(self.rows)
        clean_right, clean = self.rate(CLEAN)
        singles = [k for k in self.rows if k in SINGLES]
        lines = [f'right: {total} of {sessions} sessions ({100 * total / sessions:.1f} %)']
        if singles:
            worst = min(self.exact[k] for k in singles)
            lines.append(f'single effects: worst kind {worst} of {self.cases} right')
        if clean:
            lines.append(f'false alarms on clean sessions: {clean - clean_right} of {clean}')
        if 'pair' in self.rows:
            lines.append(f'pairs: both named in {self.exact["pair"]} of {self.cases}')
        if MU_DRIFT in self.rows:
            lines.append(f'mu drift: named in {self.exact[MU_DRIFT]} of {self.cases}')
        if self.visible:
            seen = {k: n for k, n in self.visible.items() if n[1]}
            kind = min(seen, key=lambda k: seen[k][0] / seen[k][1], default=None)
            under = sum(self.cases - self.visible[k][1] for k in self.visible)
            under_right = sum(self.exact[k] - self.visible[k][0] for k in self.visible)
            lines.append(
                f'single effects the base model misses by at least {MIN_EXCESS}x the noise: '
                + (
                    f'worst kind {seen[kind][0]} of {seen[kind][1]} ({kind}), all '
                    f'{sum(n[0] for n in seen.values())} of {sum(n[1] for n in seen.values())}'
                    if kind
                    else 'none'
                )
                + f'; under it {under_right} of {under} named (below the floor by design)'
            )
        if self.by_size:
            lines.append(
                "single effects named by the base model's miss: "
                + '; '.join(
                    f'{_band(band)} {n[0]} of {n[1]}' for band, n in sorted(self.by_size.items())
                )
            )
        singles = {k: n for k, n in self.by_limit.items() if k in SINGLES}
        if singles:
            lines.append(_limit_line(singles))
        if 'pair' in self.by_limit:
            over, under = (self.by_limit['pair'].get(shown, [0, 0]) for shown in (True, False))
            lines.append(
                'pairs with both effects at least the size their session shows them from: '
                f'both named in {over[0]} of {over[1]}; with one under it: {under[0]} of '
                f'{under[1]}'
            )
        if self.excused[1]:
            lines.append(
                'pairs, each effect under the size its session shows it from excused: right in '
                f'{self.excused[0]} of {self.excused[1]}'
            )
        if MU_DRIFT in self.by_limit:
            over, under = (self.by_limit[MU_DRIFT].get(shown, [0, 0]) for shown in (True, False))
            lines.append(
                'mu drifts at least the change a hit their session shows them from: named '
                f'{over[0]} of {over[1]}; under it: {under[0]} of {under[1]}'
            )
        if self.named_sessions:
            lines.append(
                f'an effect named in {self.named_sessions} sessions; the gap not halved in '
                f'{self.not_halved} (median reduction where vocabulary effects were hidden: '
                f'{100 * np.median(self.shrink):.1f} %)'
            )
        if self.left:
            lines.append(
                'residual left beyond the noise by a right vocabulary answer: median '
                f'{np.median(self.left):.2f}, largest {max(self.left):.2f} noise RMS '
                f'(unexplained from {MIN_EXCESS})'
            )
        if len(self.rates) > 1:
            lines.append(
                'per sample rate: '
                + ', '.join(f'{r:g} Hz {n[0]} of {n[1]}' for r, n in sorted(self.rates.items()))
            )
        if self.crashes:
            lines.append(
                f'the diagnosis raised in {len(self.crashes)} sessions: ' + '; '.join(self.crashes)
            )
        lines += [self.floor_line(floor) for floor in sorted(self.floors)]
        lines.append(
            f'diagnosis time per session: median {statistics.median(self.seconds):.2f} s, '
            f'longest {self.slowest[0]:.2f} s ({self.slowest[1]})'
        )
        return lines

    def floor_line(self, floor: float) -> str:
        """What a whole-misfit floor lowered to `floor` would have answered, as a line."""
        changed = self.floors[floor]
        exact = Counter(self.exact)
        exact.update(changed.gained)
        exact.subtract(changed.lost)
        singles = [k for k in self.rows if k in (*SINGLES, *CLEAN)]
        clean_right, clean = self.rate(CLEAN, exact)

        def kinds(counts: Counter) -> str:
            return ', '.join(f'{SHORT[k]} {n}' for k, n in counts.items() if n) or 'none'

        line = (
            f'whole-misfit floor at {floor:g}x (not {MIN_WHOLE_EXCESS:g}x), the '
            f'{changed.rerun} sessions it could change diagnosed again: right gained '
            f'{sum(changed.gained.values())} ({kinds(changed.gained)}), lost '
            f'{sum(changed.lost.values())} ({kinds(changed.lost)})'
        )
        if singles:
            line += f'; single effects and none, worst kind {min(exact[k] for k in singles)} '
            line += f'of {self.cases}'
        if clean:
            line += f'; false alarms {clean - clean_right} of {clean}'
        return line

    def targets(self) -> list[str]:
        """The targets for a held-out world, each met or not: those its swept kinds judge."""
        singles = [k for k in self.rows if k in (*SINGLES, *CLEAN)]
        clean_right, clean = self.rate(CLEAN)
        checks = [('gap not halved where named', self.not_halved, 0, False)]
        if singles:
            worst = min(self.exact[k] / self.cases for k in singles)
            checks.insert(0, ('single effects and none, worst kind', worst, TARGET_SINGLES, True))
        if clean:
            checks.insert(
                -1, ('false alarms', (clean - clean_right) / clean, TARGET_FALSE_ALARMS, False)
            )
        over = {k: n[True] for k, n in self.by_limit.items() if True in n}
        if any(k in SINGLES for k in over):
            shown = min(n[0] / n[1] for k, n in over.items() if k in SINGLES)
            name = 'single effects at least the size their session shows them from, worst kind'
            checks.insert(1, (name, shown, TARGET_SINGLES, True))
        if 'pair' in self.rows:
            checks.append(('pairs', self.exact['pair'] / self.cases, TARGET_PAIRS, True))
        if 'pair' in over:
            name = 'pairs with both at least the size their session shows them from'
            checks.append((name, over['pair'][0] / over['pair'][1], TARGET_PAIRS, True))
        if self.excused[1]:
            name = 'pairs, effects under their stated size excused'
            checks.append((name, self.excused[0] / self.excused[1], TARGET_PAIRS, True))
        if MU_DRIFT in self.rows:
            checks.append(('mu drift', self.exact[MU_DRIFT] / self.cases, TARGET_DRIFT, True))
        return [
            f'{name}: {value:.2f} (target {"at least" if high else "at most"} {target:.2f}) '
            f'{"met" if (value >= target if high else value <= target) else "NOT met"}'
            for name, value, target, high in checks
        ]


@dataclass
class Floor:
    """The sessions one lower whole-misfit floor could change, diagnosed again at it."""

    rerun: int = 0
    gained: Counter = field(default_factory=Counter)
    """Kind -> sessions right at the lower floor that were not."""
    lost: Counter = field(default_factory=Counter)
    """Kind -> sessions no longer right at the lower floor."""
    changes: list = field(default_factory=list)
    """Each session whose answer changed, in words."""


def could_change_below(result, base_size: float, floor: float) -> bool:
    """Whether a whole-misfit floor lowered to `floor` could change a diagnosis.

    It could where a refit was refused for its size (the selection log) though it removed
    WHOLE_MISFIT_SHARE of its step's gap and accounts for `floor` or more, or, at the first
    step, where a refitted candidate of the table would qualify so (its share and size from
    its gap and the base model's miss, `base_size` in noise RMS) though another was chosen.
    Rounding in the log is taken generously: a session that cannot change is only diagnosed
    once more.
    """
    for size, percent in REFUSED_FOR_SIZE.findall(' '.join(result.selection)):
        if float(size) + 0.005 >= floor and float(percent) + 0.5 >= 100 * WHOLE_MISFIT_SHARE:
            return True
    if result.gap_before <= 0.0:
        return False
    for candidate in result.candidates:
        if not math.isfinite(candidate.frf_gap_after) or candidate.score > result.required_score:
            continue
        share = 1.0 - (candidate.gap_after / result.gap_before) ** 2
        size = base_size * math.sqrt(max(share, 0.0))
        if share >= WHOLE_MISFIT_SHARE and floor <= size < MIN_EXCESS:
            return True
    return False


@contextlib.contextmanager
def whole_misfit_floor(floor: float):
    """Diagnose with MIN_WHOLE_EXCESS at `floor` inside the block (the workflow reads it)."""
    kept = workflow.MIN_WHOLE_EXCESS
    workflow.MIN_WHOLE_EXCESS = floor
    try:
        yield
    finally:
        workflow.MIN_WHOLE_EXCESS = kept


def against_limit(
    hidden: tuple[str, ...], truth: dict[str, tuple[float, float]], result
) -> tuple[bool, str] | None:
    """Whether every hidden effect is as large as the diagnosis said the records show it from.

    (each at least that size, the sizes in words); None where any is unknown. A second mode is
    held to the limit at its own frequency (`limit_at`), not to the band's least.
    """
    over, words = True, []
    for effect in hidden:
        judged = shown_by_limit(effect, truth, result)
        if judged is None:
            return None
        over &= judged[0]
        words.append(judged[1])
    return over, '; ' + '; '.join(words)


def shown_by_limit(effect: str, truth: dict, result) -> tuple[bool, str] | None:
    """Whether a hidden effect is at least the size its session said it shows from, in words.

    None where its true size or its stated limit is unknown.
    """
    candidate = next((c for c in result.candidates if c.effect == effect), None)
    if effect not in truth or candidate is None:
        return None
    size, frequency_hz = truth[effect]
    limit = limit_at(candidate, frequency_hz)
    if not math.isfinite(limit):
        return None
    below = detection_limit_dict(effect, limit)['shows'] == 'below'
    return (size <= limit if below else size >= limit), (
        f'{SHORT[effect]} {size:.2g}, shows from {limit:.2g}'
    )


def right_excused(hidden: tuple[str, ...], truth: dict, result) -> bool | None:
    """Whether a diagnosis is right once effects under their stated limit are excused.

    An effect smaller than the size its session says it shows from is not a miss (the verdict
    states that limit): right when nothing outside the hidden set is named and every hidden
    effect at least its limit is. None where a limit or a true size is unknown.
    """
    named = set(result.named_effects)
    if not named <= set(hidden):
        return False
    for effect in hidden:
        judged = shown_by_limit(effect, truth, result)
        if judged is None:
            return None
        if judged[0] and effect not in named:
            return False
    return True


def limit_at(candidate: Candidate, frequency_hz: float) -> float:
    """A candidate's detection limit at a frequency.

    A second mode's log-log between the frequencies its band was probed at (NaN outside the
    band); any other term's own.
    """
    curve = candidate.detection_limit_by_frequency
    if not curve or not math.isfinite(frequency_hz):
        return candidate.detection_limit
    frequencies, limits = np.log(np.array(curve)).T
    if not frequencies[0] <= math.log(frequency_hz) <= frequencies[-1]:
        return math.nan
    return float(np.exp(np.interp(math.log(frequency_hz), frequencies, limits)))


def _limit_line(by_limit: dict) -> str:
    """How the stated detection limits held: single effects at or over theirs, and under."""

    def total(shown: bool) -> tuple[int, int]:
        counts = [n[shown] for n in by_limit.values() if shown in n]
        return sum(c[0] for c in counts), sum(c[1] for c in counts)

    over = {k: n[True] for k, n in by_limit.items() if True in n}
    kind = min(over, key=lambda k: over[k][0] / over[k][1], default=None)
    worst = f', worst kind {over[kind][0]} of {over[kind][1]} ({kind})' if kind else ''
    (named_over, over_total), (named_under, under_total) = total(True), total(False)
    return (
        'single effects at least the size their diagnosis said the records show them from: '
        f'named {named_over} of {over_total}{worst}; under it: named {named_under} of '
        f'{under_total}'
    )


def _band(index: int) -> str:
    """A SIZE_BANDS band as text, in noise RMS."""
    low, high = SIZE_BANDS[index], SIZE_BANDS[index + 1]
    return f'from {low:g}x' if math.isinf(high) else f'{low:g}-{high:g}x'


def sweep(
    source: Source,
    cases: int,
    seed: int,
    rows: tuple[str, ...] | None = None,
    floors: tuple[float, ...] = (),
) -> Sweep:
    """Diagnose `cases` sessions of each kind of a source; print its table as it goes.

    floors: lower whole-misfit floors [noise RMS]; each session one of them could change is
    diagnosed again at it (`Sweep.floors`).
    """
    rows = rows or source.rows
    found = Sweep(source, cases, rows)
    found.floors = {floor: Floor() for floor in floors}
    for kind in rows:
        found.confusion[kind], found.sizes[kind] = Counter(), []
        for number in range(cases):
            key = [seed, source.rows.index(kind), number]
            rng = np.random.default_rng(key)
            records, hidden, ratios, starts = source.draw(kind, rng)
            start = time.perf_counter()
            try:
                result = diagnose(records, **start_options(starts))
            except Exception as error:  # a crash is a finding: counted and named, not fatal
                found.seconds.append(time.perf_counter() - start)
                found.rates.setdefault(records[0].sample_rate_hz, [0, 0])[1] += 1
                found.crashes.append(f'{kind} case {number}: {type(error).__name__}: {error}')
                found.misses.append(f'{kind} case {number}: raised {type(error).__name__}')
                continue
            found.seconds.append(time.perf_counter() - start)
            found.slowest = max(found.slowest, (found.seconds[-1], f'{kind} case {number}'))
            peak = max(float(np.max(np.abs(r.velocity_m_s))) for r in records)
            found.sizes[kind].append(result.gap_before * peak / result.noise_std_m_s)
            named = result.named_effects
            found.confusion[kind][result.missing_effect] += 1
            vocabulary = kind not in OUTSIDE and bool(hidden)
            correct = right(kind, hidden, named)
            if vocabulary and correct:
                found.left.append(result.residual_where.excess_to_noise)
            tally = found.rates.setdefault(records[0].sample_rate_hz, [0, 0])
            tally[1] += 1
            if kind in SINGLES:
                band = int(np.searchsorted(SIZE_BANDS, found.sizes[kind][-1], side='right')) - 1
                counted = found.by_size.setdefault(band, [0, 0])
                counted[0] += correct
                counted[1] += 1
                above = found.sizes[kind][-1] >= MIN_EXCESS
                visible = found.visible.setdefault(kind, [0, 0])
                visible[0] += above and correct
                visible[1] += above
            shown = ''
            if (kind in (*SINGLES, 'pair', MU_DRIFT)) and source.truth is not None:
                truth = source.truth(kind, np.random.default_rng(key))
                judged = against_limit(hidden, truth, result)
                if judged is not None:
                    over, shown = judged
                    counted = found.by_limit.setdefault(kind, {}).setdefault(over, [0, 0])
                    counted[0] += correct
                    counted[1] += 1
                excused = right_excused(hidden, truth, result) if kind == 'pair' else None
                if excused is not None:
                    found.excused[0] += excused
                    found.excused[1] += 1
            for floor, changed in found.floors.items():
                if not could_change_below(result, found.sizes[kind][-1], floor):
                    continue
                changed.rerun += 1
                with whole_misfit_floor(floor):
                    try:
                        named_then = diagnose(records, **start_options(starts)).named_effects
                    except Exception as error:  # counted as wrong, named in the changes
                        named_then = (f'raised {type(error).__name__}',)
                now = right(kind, hidden, named_then)
                changed.gained[kind] += now and not correct
                changed.lost[kind] += correct and not now
                if named_then != named:
                    changed.changes.append(
                        f'{floor:g}x: {kind} case {number}: {", ".join(named) or "none"} -> '
                        f'{", ".join(named_then) or "none"}'
                    )
            if correct:
                found.exact[kind] += 1
                tally[0] += 1
            else:
                drawn = ', '.join(f'{SHORT[e]} {r:.1f}x' for e, r in ratios.items())
                found.misses.append(
                    f'{kind} [{drawn or f"{found.sizes[kind][-1]:.1f}x"}{shown}] '
                    f'case {number}: named '
                    f'{", ".join(named) or "none"}; {result.verdict[:160]}'
                )
            if vocabulary and result.gap_before > 0.0:
                found.shrink.append(1.0 - result.gap_after / result.gap_before)
            if any(n != UNEXPLAINED for n in named):
                found.named_sessions += 1
                found.not_halved += result.gap_after > 0.5 * result.gap_before
        print(f'  {source.name} {kind}: {found.exact[kind]}/{cases} right', flush=True)
    print(f'\nconfusion table, {source.name} ({source.role} world)')
    print('\n'.join(found.table()))
    print('\n'.join(found.summary()))
    if source.role == HELD_OUT:
        print('\n'.join(found.targets()))
    print('misses:' if found.misses else 'misses: none')
    for miss in found.misses:
        print(f'  {miss}')
    for changed in found.floors.values():
        for change in changed.changes:
            print(f'  lower floor {change}')
    return found


@dataclass(frozen=True)
class Timed:
    """Median wall and process CPU seconds of some calls, and the last call's result."""

    wall_s: float
    cpu_s: float
    result: object

    def __str__(self) -> str:
        return f'{self.wall_s:.2f} s wall, {self.cpu_s:.2f} s CPU'


def timed(function, *args, repeats: int = 1, **kwargs) -> Timed:
    """Median wall and process CPU time of repeats calls, and the last result.

    CPU time beside wall time: the machine's two cores are shared, and other jobs' load
    changes wall times twofold within minutes; the diagnosis runs on one thread.
    """
    wall, cpu, result = [], [], None
    for _ in range(repeats):
        start, start_cpu = time.perf_counter(), time.process_time()
        result = function(*args, **kwargs)
        wall.append(time.perf_counter() - start)
        cpu.append(time.process_time() - start_cpu)
    return Timed(statistics.median(wall), statistics.median(cpu), result)


def timing(repeats: int, seed: int, hits_per_level: int) -> list[str]:
    """The time of a three-hit and a many-hit diagnosis, and the closed-world one's beside it."""
    lines = []

    def say(line: str) -> None:
        line += f' [load {load_average()}]'
        print(line, flush=True)
        lines.append(line)

    case = hidden_effect_case('stribeck', seed)
    diagnose(case.records)  # JIT and caches warm
    new = timed(diagnose, case.records, repeats=repeats)
    old = timed(diagnose_closed_world, case.records, repeats=max(1, repeats // 2))
    say(
        f'three 33 s impacts, hidden stribeck: {new} median of {repeats} (named '
        f'{", ".join(new.result.named_effects)}); closed world: {old} (named {old.result}); '
        f'{old.cpu_s / new.cpu_s:.1f}x less CPU (target <= {TARGET_THREE_S} s)'
    )
    session = simulated_session(
        hits_per_level, seed=3, force_noise_std_n=0.2, velocity_noise_std_m_s=1e-4
    )
    impacts = [
        as_conditioned(record)
        for record in capture_impacts(session.force_n, session.velocity_m_s, session.sample_rate_hz)
    ]
    new = timed(diagnose, impacts, fit_initial_position=True)
    old = timed(diagnose_closed_world, impacts, fit_initial_position=True)
    say(
        f'a {len(impacts)}-hit session, each start fitted: {new} (named '
        f'{", ".join(new.result.named_effects) or "none"}); closed world: {old} (named '
        f'{old.result}); {old.cpu_s / new.cpu_s:.1f}x less CPU (target <= {TARGET_SESSION_S} s)'
    )
    stribeck = hidden_session(
        ('stribeck',), np.random.default_rng([seed, 99]), n_impacts=len(impacts)
    )
    new = timed(diagnose, stribeck.records, fit_initial_position=True)
    say(
        f'a {len(impacts)}-hit session with a Stribeck contact ({stribeck.ratios["stribeck"]:.1f}x '
        f'the noise), each start fitted: {new} (named '
        f'{", ".join(new.result.named_effects) or "none"}; target <= '
        f'{TARGET_STRIBECK_SESSION_S} s)'
    )
    return lines


def load_average() -> str:
    """The 1-minute load average as /proc/loadavg gives it ('?' where there is none).

    Beside each time: the two cores are shared, and the wall time of a line taken at a load
    of 6 says little of a quiet machine's (its CPU time still does).
    """
    try:
        return Path('/proc/loadavg').read_text(encoding='ascii').split()[0]
    except OSError:
        return '?'


SILVERBOX = Path(__file__).resolve().parents[2] / 'shared' / 'realdata' / 'silverbox'
TARGET_WHOLE_RECORD_S = 5.0
"""The 131,072-sample Silverbox record, diagnosed whole, in at most this long."""


def whole_record_timing(repeats: int, seed: int) -> list[str]:
    """The whole-record diagnosis of Silverbox SNLS80mV, and three hits' diagnosis beside it.

    The three 33 s impacts hold more samples than the record; both are timed in the same run,
    so the machine's load is the same for both.
    """
    import scipy.io

    from fmm_ros.core.identify.whole_record import diagnose_whole_record

    data = scipy.io.loadmat(SILVERBOX / 'SNLS80mV.mat')
    force, displacement = data['V1'].ravel(), data['V2'].ravel()
    rate = 1e7 / 2**14
    diagnose_whole_record(force[:4096], displacement[:4096], rate)  # JIT warm
    new = timed(diagnose_whole_record, force, displacement, rate, repeats=repeats)
    case = hidden_effect_case('stribeck', seed)
    diagnose(case.records)
    hits = timed(diagnose, case.records, repeats=repeats)
    samples = sum(record.force_n.size for record in case.records)
    fit = new.result.final
    line = (
        f'Silverbox SNLS80mV whole record ({force.size} samples at {rate:g} Hz): {new} median '
        f'of {repeats} (named {", ".join(new.result.named) or "none"}, gap '
        f'{new.result.base.gap:.3g} -> {fit.gap:.3g}, sqrt(k/m)/2pi '
        f'{fit.natural_frequency_hz:.2f} Hz, k3/k '
        f'{fit.values["cubic_stiffness"] / fit.values["stiffness"]:.3g} V^-2); three hits '
        f'({samples} samples) in the same run: {hits} (target <= {TARGET_WHOLE_RECORD_S} s)'
    )
    print(line, flush=True)
    return [line]


def markdown(sweeps: list[Sweep]) -> str:
    """A RESULTS.md section: the tables and figures of some sweeps."""
    parts = []
    for found in sweeps:
        parts.append(f'**{found.source.name}** ({found.cases} sessions a kind)\n')
        parts.append('\n'.join(found.table()) + '\n')
        figures = found.summary() + (found.targets() if found.source.role == HELD_OUT else [])
        parts.append('\n'.join(f'- {line}' for line in figures) + '\n')
    return '\n'.join(parts)


def limit_rates(
    worlds: tuple[str, ...], cases: int, seed: int, multiples: tuple[float, ...], *, quick: bool
) -> None:
    """Per kind on the held-out worlds, how often an effect at `multiples` of a limit is named.

    The limit is the one a clean session stated (`bench_limits.check`); the rates stand against
    the targets, in a RESULTS.md section of their own. The limits' benchmark holds the sessions
    and the counting; this reports its rates per kind beside the sweeps.
    """
    import bench_limits  # noqa: PLC0415 (it imports this script's tables: no cycle at load)

    held_out = [name for name in HELDOUT_WORLDS if ROLES[name] == HELD_OUT]
    chosen = [w for w in held_out if w in (worlds or held_out)][: 1 if quick else None]
    effects = bench_limits.QUICK_EFFECTS[:1] if quick else None
    checks = [
        bench_limits.check(name, 1 if quick else cases, seed, effects, multiples) for name in chosen
    ]
    named = f' [{", ".join(worlds)}]' if worlds else ''
    at = ', '.join(f'{m:g}x' for m in multiples)
    write_section(
        f'bench_diagnose, held out limits at {at}{named}'
        + (f', seed {seed}' if seed != DEFAULT_SEED else ''),
        bench_limits.markdown(checks, cases),
        quick=quick,
    )


def lower_floors(text: str) -> tuple[float, ...]:
    """--floors' values: comma-separated numbers between 0 and MIN_WHOLE_EXCESS [noise RMS]."""
    try:
        floors = tuple(float(value) for value in text.split(','))
    except ValueError:
        floors = ()
    if not floors or not all(0.0 < floor < MIN_WHOLE_EXCESS for floor in floors):
        raise argparse.ArgumentTypeError(
            f'{text!r}: give comma-separated floors between 0 and MIN_WHOLE_EXCESS '
            f'({MIN_WHOLE_EXCESS:g}x the noise RMS), e.g. 0.1,0.2'
        )
    return floors


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--quick', action='store_true', help=QUICK_HELP)
    parser.add_argument('--cases', type=int, default=10, help='sessions per kind of ours')
    parser.add_argument(
        '--world-cases', type=int, default=10, help='sessions per kind from worlds (0: skip)'
    )
    parser.add_argument(
        '--heldout-cases', type=int, default=16, help='sessions per kind, held out (0: skip)'
    )
    parser.add_argument(
        '--seed',
        type=int,
        default=DEFAULT_SEED,
        help='draws the sessions; another seed sweeps sessions never seen, into a section of '
        'its own',
    )
    parser.add_argument('--repeats', type=int, default=5, help='timing repeats')
    parser.add_argument(
        '--session-hits', type=int, default=10, help='hits per level of the timed session'
    )
    parser.add_argument('--skip-sweep', action='store_true', help='time only')
    parser.add_argument(
        '--whole-record',
        action='store_true',
        help='time only the Silverbox whole-record diagnosis against three hits (no sweeps)',
    )
    parser.add_argument('--skip-timing', action='store_true', help='sweeps only')
    parser.add_argument(
        '--kinds',
        type=lambda text: tuple(text.split(',')),
        default=(),
        help='sweep only these kinds (comma-separated) of every world that makes them, into '
        'a RESULTS.md section of their own',
    )
    parser.add_argument(
        '--worlds',
        type=lambda text: tuple(text.split(',')),
        default=(),
        help='sweep only these worlds (comma-separated names of heldout.ROLES)',
    )
    parser.add_argument(
        '--floors',
        type=lower_floors,
        default=(),
        help='also diagnose again, with the whole-misfit floor (MIN_WHOLE_EXCESS) at each of '
        'these lower values [noise RMS], every session it could change, and say what changed',
    )
    parser.add_argument(
        '--limit-multiples',
        type=lambda text: tuple(float(m) for m in text.split(',')),
        default=(),
        help='only report, per kind on the held-out worlds, how often an effect set at these '
        'multiples of the limit its clean session states is named (e.g. 1.5,1.2; no sweeps, '
        'no timing)',
    )
    parser.add_argument(
        '--limit-cases', type=int, default=20, help='sessions a world for --limit-multiples'
    )
    parser.add_argument(
        '--role',
        choices=('all', 'tuning', 'held-out'),
        default='all',
        help='which worlds to sweep (each role writes its own section)',
    )
    args = parser.parse_args()
    if args.whole_record:
        lines = whole_record_timing(1 if args.quick else args.repeats, args.seed)
        write_section('bench_diagnose, whole record', '\n'.join(lines), quick=args.quick)
        return
    unknown = sorted(set(args.worlds) - {source.name for source in SOURCES})
    if unknown:
        parser.error(
            f'unknown world(s) {", ".join(unknown)}; known: '
            + ', '.join(source.name for source in SOURCES)
        )
    if args.limit_multiples:
        tuning = sorted(w for w in args.worlds if ROLES[w] != HELD_OUT)
        if tuning:
            parser.error(f'--limit-multiples reports held-out worlds only, not {", ".join(tuning)}')
        limit_rates(
            args.worlds, args.limit_cases, args.seed, args.limit_multiples, quick=args.quick
        )
        return
    counts = {'ours': args.cases, 'worlds': args.world_cases}
    for role in ('tuning', HELD_OUT) if args.role == 'all' else (args.role.replace('-', ' '),):
        sweeps = []
        chosen = [s for s in SOURCES if s.role == role and s.name in (args.worlds or ROLES)]
        if args.quick:  # a smoke run: each world's generator has tests of its own
            chosen = chosen[:1]
        for source in chosen if not args.skip_sweep else ():
            cases = 1 if args.quick else counts.get(source.name, args.heldout_cases)
            if not cases:
                continue
            rows = None
            if args.kinds or args.quick:
                rows = tuple(k for k in source.rows if k in (args.kinds or QUICK_KINDS))
                if not rows:
                    continue
            print(f'\nsweep: {cases} sessions a kind, {source.name} ({source.role} world)')
            sweeps.append(sweep(source, cases, args.seed, rows, args.floors))
        if sweeps:
            kinds = f' ({", ".join(args.kinds)})' if args.kinds else ''
            worlds = f' [{", ".join(args.worlds)}]' if args.worlds else ''
            seed = f', seed {args.seed}' if args.seed != DEFAULT_SEED else ''
            write_section(
                f'bench_diagnose, {role} worlds{worlds}{kinds}{seed}',
                markdown(sweeps),
                quick=args.quick,
            )
    if not args.skip_timing:
        times = timing(
            1 if args.quick else args.repeats, args.seed, 1 if args.quick else args.session_hits
        )
        write_section(
            'bench_diagnose, time', '\n'.join(f'- {line}' for line in times), quick=args.quick
        )


if __name__ == '__main__':
    main()
