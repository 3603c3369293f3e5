"""A third held-out world, `ivp`: written after `steps` became a tuning world.

Other choices than `lab.EVENTS` and `lab.STEPS` at every stage, and none of their code:

- Hits: a haversine (1 - cos) and a gamma pulse (t^2 e^(-t/tau), a long tail), onset anywhere
  between samples, impulses exact in closed form (`Pulse`).
- Motion: one `scipy.integrate.solve_ivp` run (LSODA, dense output) per phase of a
  state machine: a slide ends at the velocity's zero (an event), a stick ends where the net
  force on the stuck mass leaves static friction (an event too, so a breakaway during the hit
  is located by the solver, not by bracketing), and phases are split at the hit's edges.
- Second mode: the hammer drives it through `scipy.signal.lsim` on a 1 MHz grid during the hit,
  free decay in closed form afterwards.
- Acquisition: a sigma-delta converter. Each channel is evaluated 16 times oversampled where it
  moves and decimated by a causal linear-phase FIR (513 taps, Kaiser window, 4.5 kHz), as a
  delta-sigma ADC's digital filter does (both channels delayed alike by 1.6 ms); then pink
  (1/f) noise beside white noise on both channels, a force zero offset, no mains hum, no
  rounding (24 bits).
"""

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.integrate
import scipy.signal
import scipy.special

from heldout.lab import Effects

RATE_HZ = 10_000.0
OVERSAMPLE = 16
TAPS = 513
PRETRIGGER_S = 0.2
MASS_KG, STIFFNESS_N_PER_M, DAMPING_N_S_PER_M = 10.391, 1982.0, 0.275
NORMAL_N = 0.680 * 9.81
GAMMA_TAIL = 24.0
"""A gamma pulse is cut this many time constants after its onset (its force there ~3e-7 of
the peak; the impulse counts the cut)."""


@dataclass(frozen=True)
class Pulse:
    """A hammer hit: 'haversine' (duration) or 'gamma' (time constant), peak [N], onset [s]."""

    shape: str
    peak_n: float
    time_s: float
    onset_s: float

    @property
    def end_s(self) -> float:
        """When the force is over [s]."""
        return self.onset_s + (
            self.time_s if self.shape == 'haversine' else GAMMA_TAIL * self.time_s
        )

    def force(self, t: np.ndarray | float) -> np.ndarray:
        """The force at any times [N]."""
        u = np.asarray(t, dtype=float) - self.onset_s
        inside = (u > 0.0) & (u < self.end_s - self.onset_s)
        v = np.where(inside, u, 0.0)
        if self.shape == 'haversine':
            shape = 0.5 * (1.0 - np.cos(2.0 * math.pi * v / self.time_s))
        else:
            shape = (v / (2.0 * self.time_s)) ** 2 * np.exp(2.0 - v / self.time_s)
        return np.where(inside, self.peak_n * shape, 0.0)

    @property
    def impulse_n_s(self) -> float:
        """Exact impulse [N s]."""
        if self.shape == 'haversine':
            return 0.5 * self.peak_n * self.time_s
        # P e^2 / (4 tau^2) * int_0^U u^2 e^(-u/tau) du = P e^2 tau / 2 * P(3, U / tau)
        return 0.5 * self.peak_n * math.e**2 * self.time_s * scipy.special.gammainc(3, GAMMA_TAIL)


def random_pulse(rng: np.random.Generator, level_n: float, onset_s: float) -> Pulse:
    """A haversine of 1.5-4 ms or a gamma pulse of 0.2-0.5 ms time constant, +-2 % of a level."""
    peak = level_n * rng.uniform(0.98, 1.02)
    if rng.uniform() < 0.5:
        return Pulse('haversine', peak, rng.uniform(1.5e-3, 4e-3), onset_s)
    return Pulse('gamma', peak, rng.uniform(0.2e-3, 0.5e-3), onset_s)


@dataclass(frozen=True)
class Law:
    """Friction: mu by sliding direction, speed (Stribeck) and position (a wear track)."""

    mu: float
    effects: Effects

    def kinetic(self, direction: float, speed: float, x: float) -> float:
        """The coefficient while sliding [-]."""
        e = self.effects
        stribeck = e.static_excess * math.exp(-((speed / e.stribeck_speed_m_s) ** 2))
        return self._base(direction, x) + stribeck

    def static(self, direction: float, x: float) -> float:
        """The coefficient a stuck mass holds against, pushed in a direction [-]."""
        return self._base(direction, x) + self.effects.static_excess

    def _base(self, direction: float, x: float) -> float:
        e = self.effects
        track = 1.0 + e.track_amplitude * math.sin(
            2.0 * math.pi * x / e.track_wavelength_m + e.track_phase
        )
        return (self.mu + 0.5 * e.asymmetry * direction) * track


def motion(
    law: Law, pulse: Pulse, x0_m: float, stop_s: float
) -> tuple[Callable[[np.ndarray], np.ndarray], float]:
    """(velocity at any times [m/s], where the mass came to rest [m]) from rest at x0_m."""
    e = law.effects
    damping = DAMPING_N_S_PER_M + e.added_damping_n_s_per_m

    def spring(x: float) -> float:
        return STIFFNESS_N_PER_M * x + e.cubic_n_per_m3 * x**3

    def force(t: float) -> float:
        return float(pulse.force(t))

    pieces: list[tuple[float, float, Callable | None]] = []
    t, x, v, phase = pulse.onset_s, x0_m, 0.0, 0.0
    while t < stop_s:
        if phase == 0.0:  # stuck at x

            def leaves(time, z, held=x):
                net = force(time) - spring(held)
                return abs(net) - NORMAL_N * law.static(math.copysign(1.0, net), held)

            if t >= pulse.end_s and leaves(t, None) <= 0.0:
                pieces.append((t, math.inf, None))
                return _evaluator(pieces, x0_m), x
            leaves.terminal, leaves.direction = True, 1.0
            end = pulse.end_s if t < pulse.end_s else t
            if leaves(t, None) > 0.0:
                found = t
            else:
                run = scipy.integrate.solve_ivp(
                    lambda time, z: (0.0,),
                    (t, end),
                    (x,),
                    events=leaves,
                    max_step=pulse.time_s / 50.0,
                )
                found = float(run.t_events[0][0]) if run.t_events[0].size else end
            pieces.append((t, found, None))
            t = found
            net = force(t + 1e-12) - spring(x)
            if abs(net) <= NORMAL_N * law.static(math.copysign(1.0, net), x):
                continue
            phase = math.copysign(1.0, net)
            continue

        def rhs(time, z, s=phase):
            friction = s * NORMAL_N * law.kinetic(s, abs(z[1]), z[0])
            return (z[1], (force(time) - damping * z[1] - spring(z[0]) - friction) / MASS_KG)

        def stops(time, z):
            return z[1]

        stops.terminal, stops.direction = True, -phase
        edge = pulse.end_s if t < pulse.end_s else stop_s
        run = scipy.integrate.solve_ivp(
            rhs,
            (t, edge),
            (x, v),
            method='LSODA',
            rtol=1e-10,
            atol=(1e-13, 1e-11),
            dense_output=True,
            events=stops,
            max_step=pulse.time_s / 40.0 if t < pulse.end_s else 2e-2,
        )
        pieces.append((t, float(run.t[-1]), run.sol))
        t, (x, v) = float(run.t[-1]), run.y[:, -1]
        x = float(x)
        if run.status == 1:
            phase, v = 0.0, 0.0
        elif t >= stop_s:
            return _evaluator(pieces, x0_m), math.nan
    return _evaluator(pieces, x0_m), math.nan


def _evaluator(pieces, x0_m: float) -> Callable[[np.ndarray], np.ndarray]:
    """Velocity at any times from the phases (zero while stuck and before the hit)."""

    def velocity(time_s: np.ndarray) -> np.ndarray:
        t = np.asarray(time_s, dtype=float)
        out = np.zeros(t.shape)
        for t0, t1, solution in pieces:
            if solution is None:
                continue
            inside = (t >= t0) & (t < t1)
            if inside.any():
                out[inside] = solution(t[inside])[1]
        return out

    return velocity


def mode_velocity(effects: Effects, pulse: Pulse) -> Callable[[np.ndarray], np.ndarray]:
    """The second mode's velocity at any times (zero without one)."""
    if not effects.mode_hz:
        return lambda t: np.zeros(np.shape(t))
    omega = 2.0 * math.pi * effects.mode_hz
    zeta, mass = effects.mode_damping_ratio, effects.mode_mass_kg
    system = scipy.signal.StateSpace(
        [[0.0, 1.0], [-(omega**2), -2.0 * zeta * omega]], [[0.0], [1.0 / mass]], [[0.0, 1.0]], 0.0
    )
    grid = np.linspace(
        pulse.onset_s, pulse.end_s, max(2000, int((pulse.end_s - pulse.onset_s) * 1e6))
    )
    _, during, states = scipy.signal.lsim(system, pulse.force(grid), grid - grid[0])
    x_end, v_end = states[-1]
    decay, damped = zeta * omega, omega * math.sqrt(1.0 - zeta * zeta)

    def velocity(time_s: np.ndarray) -> np.ndarray:
        t = np.asarray(time_s, dtype=float)
        out = np.interp(t, grid, during, left=0.0, right=0.0)
        late = t >= pulse.end_s
        tau = t[late] - pulse.end_s
        # x = e^(-d tau) (x_end cos w tau + b sin w tau); its derivative
        b = (v_end + decay * x_end) / damped
        out[late] = np.exp(-decay * tau) * (
            (b * damped - decay * x_end) * np.cos(damped * tau)
            - (x_end * damped + decay * b) * np.sin(damped * tau)
        )
        return out

    return velocity


def sigma_delta(
    signal: Callable[[np.ndarray], np.ndarray], samples: int, active: tuple[float, float]
) -> np.ndarray:
    """A channel through a delta-sigma ADC's decimating FIR, `samples` samples from t = 0."""
    fir = scipy.signal.firwin(TAPS, 4500.0, window=('kaiser', 8.0), fs=RATE_HZ * OVERSAMPLE)
    first = max(0, math.floor(active[0] * RATE_HZ) - 2)
    last = min(samples, math.ceil(active[1] * RATE_HZ) + TAPS // OVERSAMPLE + 2)
    before, after = (float(v) for v in signal(np.array([-1.0, active[1] + 1e3])))
    out = np.full(samples, before)
    out[last:] = after
    fine = first * OVERSAMPLE - (TAPS - 1) + np.arange((last - first) * OVERSAMPLE + TAPS - 1)
    filtered = scipy.signal.oaconvolve(signal(fine / (RATE_HZ * OVERSAMPLE)), fir, mode='valid')
    out[first:last] = filtered[::OVERSAMPLE]
    return out


def pink(rng: np.random.Generator, samples: int, std: float) -> np.ndarray:
    """1/f noise of a given standard deviation (its spectrum flat below 0.05 Hz)."""
    spectrum = np.fft.rfft(rng.normal(size=samples))
    frequency = np.fft.rfftfreq(samples, 1.0 / RATE_HZ)
    spectrum /= np.sqrt(np.maximum(frequency, 0.05))
    spectrum[0] = 0.0
    noise = np.fft.irfft(spectrum, samples)
    return std * noise / noise.std()


@dataclass(frozen=True)
class IvpRecord:
    """One hit's record as the ADC delivered it, and its truth."""

    force_n: np.ndarray
    velocity_m_s: np.ndarray
    sample_rate_hz: float
    pulse: Pulse
    mu: float
    start_m: float
    rest_m: float
    source: str = ''


@dataclass(frozen=True)
class IvpWorld:
    """The `ivp` world: its noise levels (white and pink, force and velocity) and offset."""

    name: str = 'ivp'
    sensor: str = 'velocity'
    """What the response sensor measures (as `lab.World.sensor`): a vibrometer."""
    force_white_n: float = 0.15
    force_pink_n: float = 0.1
    force_offset_n: float = 0.1
    velocity_white_m_s: float = 1.0e-4
    velocity_pink_m_s: float = 0.4e-4
    duration_s: float = 12.0

    def record(
        self, effects: Effects, mu: float, pulse: Pulse, start_m: float, rng, source: str
    ) -> IvpRecord:
        """One hit's record from rest at start_m."""
        velocity, rest = motion(Law(mu, effects), pulse, start_m, self.duration_s)
        mode = mode_velocity(effects, pulse)
        lag = effects.lag_s
        samples = round(self.duration_s * RATE_HZ)
        ring = (
            3.0 / (effects.mode_damping_ratio * 2 * math.pi * effects.mode_hz)
            if effects.mode_hz
            else 0.0
        )
        moving_until = min(self.duration_s, _last_motion(velocity, pulse, self.duration_s) + ring)
        force = sigma_delta(pulse.force, samples, (pulse.onset_s, pulse.end_s))
        speed = sigma_delta(
            lambda t: velocity(t - lag) + mode(t - lag),
            samples,
            (pulse.onset_s, moving_until + lag),
        )
        force += self.force_offset_n + rng.normal(0.0, self.force_white_n, samples)
        force += pink(rng, samples, self.force_pink_n)
        speed += effects.velocity_offset_m_s + rng.normal(0.0, self.velocity_white_m_s, samples)
        speed += pink(rng, samples, self.velocity_pink_m_s)
        return IvpRecord(force, speed, RATE_HZ, pulse, mu, start_m, rest, source)

    def session(
        self,
        effects: Effects,
        mu: float,
        rng: np.random.Generator,
        levels_n: Sequence[float],
        *,
        chained: bool = False,
    ) -> list[IvpRecord]:
        """One record a level; mu changes by effects.mu_step a hit; chained: starts at rests."""
        records, start = [], 0.0
        for index, level in enumerate(levels_n):
            onset = PRETRIGGER_S + rng.uniform(0.0, 1.0) / RATE_HZ
            pulse = random_pulse(rng, float(level), onset)
            hit_mu = mu * (1.0 + effects.mu_step) ** index
            made = self.record(effects, hit_mu, pulse, start, rng, f'{self.name} hit {index}')
            records.append(made)
            if chained and math.isfinite(made.rest_m):
                start = made.rest_m
        return records


def _last_motion(velocity: Callable, pulse: Pulse, stop_s: float) -> float:
    """The last time the mass moves (on a 1 ms grid), plus 10 ms [s]."""
    grid = np.arange(pulse.onset_s, stop_s, 1e-3)
    moving = np.flatnonzero(velocity(grid) != 0.0)
    return float(grid[moving[-1]]) + 0.01 if moving.size else pulse.end_s


IVP = IvpWorld()
"""The `ivp` world (module doc)."""
