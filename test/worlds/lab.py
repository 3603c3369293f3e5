"""Sessions and records: the arrays a lab would save, and the truth kept beside them.

- `record_session`: one continuous recording of many hits, 34-40 s apart by default; each hit
  finds the rig wherever friction stopped it after the previous one (off-centre starts), and
  `Session.records()` cuts the per-impact records (33 s from a pre-trigger before each hit)
  the way a capture would.
- `impact_record`: one isolated record, the rig at rest at a chosen or random position.

Every random choice draws from the numpy Generator passed in, so a seed reproduces the data.
The truth (`Truth`) holds the world, the DAQ chain and its realised hum, the rig's continuous
motion, and per hit (`HitTruth`): its pulses, exact impulse, mu, where it found and left the
rig, and its damage.
"""

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np

from worlds.damage import SPAN_LEAD_S, AnalogArrays, Damage, DigitalArrays
from worlds.daq import (
    DEFAULT_DAQ,
    ContinuousSignal,
    DaqChain,
    HumComponent,
    analog_channel,
    digitise,
)
from worlds.friction import FrictionLaw
from worlds.motion import (
    PlantState,
    Trajectory,
    linear_response,
    simulate_motion,
)
from worlds.pulses import PlacedPulse, Pulse, random_pulse
from worlds.world import World

RECORD_DURATION_S = 33.0
"""The paper's record length (frequency resolution 1/33 Hz)."""
PRETRIGGER_S = 0.05
"""Default time kept before first contact in a per-impact record."""
SPACING_S = (34.0, 40.0)
"""Default range of times between successive hits of a session."""
_MODE_SETTLED_M_S = 1e-12


@dataclass(frozen=True)
class RunIn:
    """Friction drifting from hit to hit as the contact runs in (or wears).

    Hit i's coefficients are the world's times 1 + (start_factor - 1) exp(-i / time_constant)
    + N(0, scatter): e.g. start_factor 1.3 starts 30 % high and settles over a few hits.
    """

    start_factor: float = 1.3
    time_constant_hits: float = 5.0
    scatter: float = 0.0

    def factors(self, count: int, rng: np.random.Generator) -> np.ndarray:
        """The per-hit multipliers of the friction law."""
        trend = 1.0 + (self.start_factor - 1.0) * np.exp(
            -np.arange(count) / self.time_constant_hits
        )
        factors = trend + (rng.normal(0.0, self.scatter, count) if self.scatter else 0.0)
        if np.any(factors <= 0):
            raise ValueError('run-in made a friction factor <= 0')
        return factors


@dataclass(frozen=True)
class HitTruth:
    """What one hit really was and did."""

    index: int
    time_s: float
    """First contact, on the clock of the arrays it belongs to (t = 0 at their first sample)."""
    sample_position: float
    """First contact as a fractional index into the arrays (dropped samples accounted)."""
    pulses: tuple[PlacedPulse, ...]
    impulse_n_s: float
    """Exact area of all the hit's pulses (a double hit counts both)."""
    peak_force_n: float
    """Peak of the (first) pulse's envelope."""
    mu: float
    """The friction law's nominal coefficient during this hit (see FrictionLaw.nominal_mu)."""
    friction: FrictionLaw
    start_position_m: float
    """Where the hit found the rig."""
    rest_position_m: float | None
    """Where the rig stopped before the next hit or the end (None: still moving)."""
    rest_time_s: float | None
    """When the rig stopped (None: still moving at the next hit or the end)."""
    damage: tuple[Damage, ...] = ()

    def on_clock(self, start_s: float, first_sample: int) -> 'HitTruth':
        """This hit seen from arrays that start `start_s` later, at sample `first_sample`."""
        return replace(
            self,
            time_s=self.time_s - start_s,
            sample_position=self.sample_position - first_sample,
            pulses=tuple(replace(p, start_s=p.start_s - start_s) for p in self.pulses),
            rest_time_s=None if self.rest_time_s is None else self.rest_time_s - start_s,
        )


@dataclass(frozen=True)
class Truth:
    """Everything that made a recording; times on the recording's own clock."""

    world: World
    daq: DaqChain
    hits: tuple[HitTruth, ...]
    force_hum: tuple[HumComponent, ...]
    velocity_hum: tuple[HumComponent, ...]
    motion: Trajectory
    """The rig's continuous motion, on the session's clock."""
    start_time_s: float = 0.0
    """Session time of this recording's first sample (0 for a session)."""

    def true_velocity_m_s(self, time_s: np.ndarray) -> np.ndarray:
        """The rig's velocity (no mode, lag or offset) at times on this recording's clock."""
        return self.motion.evaluate(np.asarray(time_s, dtype=float) + self.start_time_s)[1]


@dataclass(frozen=True)
class LabRecord:
    """Two sample-aligned channels as saved by the DAQ, their sample times, and the truth."""

    force_n: np.ndarray
    velocity_m_s: np.ndarray
    sample_rate_hz: float
    time_s: np.ndarray
    """Sample times from the first sample; uniform unless samples were dropped."""
    truth: Truth


@dataclass(frozen=True)
class Session(LabRecord):
    """A continuous recording of many hits."""

    def records(
        self, duration_s: float = RECORD_DURATION_S, pretrigger_s: float = PRETRIGGER_S
    ) -> list[LabRecord]:
        """Per-impact records: `duration_s` from `pretrigger_s` before each first contact.

        The window starts on the sample grid, at the first sample after the contact minus the
        pre-trigger; a record running past the session's end is shorter.
        """
        return [self.record_at(hit.time_s, duration_s, pretrigger_s) for hit in self.truth.hits]

    def record_at(
        self,
        contact_time_s: float,
        duration_s: float = RECORD_DURATION_S,
        pretrigger_s: float = PRETRIGGER_S,
    ) -> LabRecord:
        """The record around one contact time (see `records`)."""
        rate = self.sample_rate_hz
        start = (math.ceil(contact_time_s * rate) - round(pretrigger_s * rate)) / rate
        first, stop = np.searchsorted(
            self.time_s, [start - 0.5 / rate, start + duration_s - 0.5 / rate]
        )
        time_s = self.time_s[first:stop]
        hits = tuple(
            hit.on_clock(start, first)
            for hit in self.truth.hits
            if start <= hit.time_s < start + duration_s
        )
        truth = replace(self.truth, hits=hits, start_time_s=self.truth.start_time_s + start)
        return LabRecord(
            self.force_n[first:stop], self.velocity_m_s[first:stop], rate, time_s - start, truth
        )


def _sample_position(time_s: np.ndarray, t: float, rate: float) -> float:
    index = min(int(np.searchsorted(time_s, t)), time_s.size - 1)
    return index - (time_s[index] - t) * rate


def _velocity_signal(world: World, motion: Trajectory, modes: list[Trajectory]) -> ContinuousSignal:
    lag = world.vibrometer_lag_s
    windows = list(motion.active_windows())
    for mode in modes:
        windows += mode.active_windows(_MODE_SETTLED_M_S)

    def deviation(t_s: np.ndarray) -> np.ndarray:
        lagged = t_s - lag
        velocity = motion.evaluate(lagged)[1]
        for mode in modes:
            velocity = velocity + mode.evaluate(lagged)[1]
        return velocity

    return ContinuousSignal(
        tuple((a + lag, b + lag) for a, b in windows), deviation, world.velocity_offset_m_s
    )


def _force_signal(pulses: list[PlacedPulse]) -> ContinuousSignal:
    def deviation(t_s: np.ndarray) -> np.ndarray:
        return sum((p.force_n(t_s) for p in pulses), np.zeros(t_s.shape))

    return ContinuousSignal(tuple((p.start_s, p.stop_s) for p in pulses), deviation)


def _record(
    world: World,
    rng: np.random.Generator,
    main_pulses: Sequence[PlacedPulse],
    n_samples: int,
    start_position_m: float | None,
    rest_before_s: float,
    laws: Sequence[FrictionLaw],
    daq: DaqChain,
    damage: Mapping[int, Sequence[Damage]],
    method: str,
) -> tuple:
    """Simulate, acquire and damage one recording of the given hits."""
    rate = daq.sample_rate_hz
    duration_s = n_samples / rate
    hit_damage = [tuple(damage.get(i, ())) for i in range(len(main_pulses))]
    pulses_of_hit = [
        (main, *(extra for d in hit_damage[i] for extra in d.extra_pulses(main)))
        for i, main in enumerate(main_pulses)
    ]
    all_pulses = [p for pulses in pulses_of_hit for p in pulses]
    if start_position_m is None:
        band = world.with_friction(laws[0]).static_band_m()
        start_position_m = float(rng.uniform(-0.95, 0.95) * band)
    # The plant, hit by hit: each interval runs with that hit's friction law.
    motion = Trajectory(0.0, duration_s)
    state = PlantState(start_position_m, 0.0, -rest_before_s)
    starts = [p.start_s for p in main_pulses]
    bounds = [0.0, *starts[1:], duration_s]
    hit_states = []
    for i, (a, b) in enumerate(zip(bounds[:-1], bounds[1:], strict=True)):
        piece, end = simulate_motion(
            world.with_friction(laws[i]), pulses_of_hit[i], a, b, state, method=method
        )
        hit_states.append((state, end))
        motion.segments += piece.segments
        motion.events += piece.events
        state = end
    modes = [linear_response(*mode.constants, all_pulses, 0.0, duration_s) for mode in world.modes]
    force = analog_channel(_force_signal(all_pulses), daq.force, daq, n_samples, rng)
    velocity = analog_channel(
        _velocity_signal(world, motion, modes), daq.velocity, daq, n_samples, rng
    )
    arrays = AnalogArrays(force.total, velocity.total, force.signal, velocity.interference)
    spans = [
        slice(
            max(math.ceil((t - SPAN_LEAD_S) * rate), 0),
            min(math.ceil((t_next - SPAN_LEAD_S) * rate), n_samples),
        )
        for t, t_next in zip(starts, [*starts[1:], duration_s + SPAN_LEAD_S], strict=True)
    ]
    for kinds, span in zip(hit_damage, spans, strict=True):
        for kind in kinds:
            kind.apply_analog(arrays, span)
    force_n, velocity_m_s = (
        digitise(arrays.force, daq.force),
        digitise(arrays.velocity, daq.velocity),
    )
    digital = DigitalArrays(force_n, velocity_m_s, np.ones(n_samples, dtype=bool), rate)
    for kinds, t in zip(hit_damage, starts, strict=True):
        for kind in kinds:
            kind.apply_digital(digital, t)
    keep = digital.keep
    time_s = np.arange(n_samples) / rate
    if not keep.all():
        time_s, force_n, velocity_m_s = time_s[keep], force_n[keep], velocity_m_s[keep]
    hits = []
    for i, (pulses, (before, after)) in enumerate(zip(pulses_of_hit, hit_states, strict=True)):
        main = pulses[0]
        hits.append(
            HitTruth(
                index=i,
                time_s=main.start_s,
                sample_position=_sample_position(time_s, main.start_s, rate),
                pulses=pulses,
                impulse_n_s=sum(p.pulse.impulse_n_s for p in pulses),
                peak_force_n=main.pulse.peak_force_n,
                mu=laws[i].nominal_mu,
                friction=laws[i],
                start_position_m=before.position_m,
                rest_position_m=after.position_m if after.stuck_since_s is not None else None,
                rest_time_s=after.stuck_since_s,
                damage=hit_damage[i],
            )
        )
    truth = Truth(world, daq, tuple(hits), force.hum, velocity.hum, motion)
    return force_n, velocity_m_s, time_s, truth


def _pulses(hits: int | Sequence[Pulse], rng: np.random.Generator) -> list[Pulse]:
    if isinstance(hits, int):
        if hits < 1:
            raise ValueError(f'a session needs at least one hit, got {hits}')
        return [random_pulse(rng) for _ in range(hits)]
    if not hits:
        raise ValueError('a session needs at least one hit')
    return list(hits)


def record_session(
    world: World,
    rng: np.random.Generator,
    *,
    hits: int | Sequence[Pulse] = 10,
    spacing_s: tuple[float, float] = SPACING_S,
    lead_in_s: float = 1.0,
    tail_s: float = RECORD_DURATION_S,
    start_position_m: float | None = None,
    run_in: RunIn | None = None,
    daq: DaqChain = DEFAULT_DAQ,
    damage: Mapping[int, Sequence[Damage]] | None = None,
    method: str = 'auto',
) -> Session:
    """A continuous recording of many hits (see module).

    `hits`: a count of random paper-level hits, or the pulses themselves. Hit 0 comes
    `lead_in_s` plus a random fraction of a sample after the first sample, each next one a
    uniform draw from `spacing_s` later; the recording ends `tail_s` after the last. The rig
    starts at rest at `start_position_m` (random inside 95 % of the static band when None),
    having rested there one spacing already. `damage` maps hit indices to their damage.
    `method`: the plant solver's ('auto', or 'general' for DOP853 throughout).
    """
    pulses = _pulses(hits, rng)
    rate = daq.sample_rate_hz
    times = [lead_in_s + rng.uniform(0.0, 1.0) / rate]
    for _ in pulses[1:]:
        times.append(times[-1] + rng.uniform(*spacing_s))
    n_samples = math.ceil((times[-1] + tail_s) * rate)
    factors = run_in.factors(len(pulses), rng) if run_in else np.ones(len(pulses))
    laws = [world.friction.scaled(float(f)) for f in factors]
    force_n, velocity_m_s, time_s, truth = _record(
        world,
        rng,
        [PlacedPulse(p, t) for p, t in zip(pulses, times, strict=True)],
        n_samples,
        start_position_m,
        min(spacing_s),
        laws,
        daq,
        damage or {},
        method,
    )
    return Session(force_n, velocity_m_s, rate, time_s, truth)


def impact_record(
    world: World,
    rng: np.random.Generator,
    *,
    pulse: Pulse | None = None,
    start_position_m: float | None = None,
    duration_s: float = RECORD_DURATION_S,
    pretrigger_s: float = PRETRIGGER_S,
    daq: DaqChain = DEFAULT_DAQ,
    damage: Sequence[Damage] = (),
    method: str = 'auto',
) -> LabRecord:
    """One isolated impact record: `duration_s` long, first contact less than a sample before
    `pretrigger_s` (a random fraction), as in records cut from a session, the rig at rest at
    `start_position_m` (random inside 95 % of the static band when None; outside the band it
    is released at the first sample).

    `pulse`: the hit (a random paper-level hit when None); `method` as in `record_session`.
    """
    rate = daq.sample_rate_hz
    hit = pulse if pulse is not None else random_pulse(rng)
    start = pretrigger_s - rng.uniform(0.0, 1.0) / rate
    n_samples = round(duration_s * rate)
    if not 0.0 < start < duration_s:
        raise ValueError(
            f'pre-trigger {pretrigger_s} s must lie inside the record of '
            f'{duration_s} s, after its first sample'
        )
    force_n, velocity_m_s, time_s, truth = _record(
        world,
        rng,
        [PlacedPulse(hit, start)],
        n_samples,
        start_position_m,
        SPACING_S[0],
        [world.friction],
        daq,
        {0: tuple(damage)},
        method,
    )
    return LabRecord(force_n, velocity_m_s, rate, time_s, truth)
