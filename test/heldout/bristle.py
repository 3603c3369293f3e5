"""A fifth held-out world, `bristle`: a tribology lab's simulator, friction as a state.

Written when `events` and `analytic` were about to become tuning worlds, before
any diagnosis was run on it (never tuned on). It shares only `lab.Effects` (the effect
vocabulary and its parameters) with the other worlds and makes other choices at every stage:

- Friction: a LuGre bristle state z (Canudas de Wit et al. 1995),
  dz/dt = v - sigma0 |v| z / g(v, x), F = sigma0 z + sigma1 dz/dt, whose steady state is the
  Coulomb law with g(v, x) = N (mu_dir(sign v) track(x) + static_excess e^(-(v/vs)^2)): Stribeck
  through g, direction-dependent friction through mu_dir, a wear track through track(x), a mu
  drifting hit to hit through mu. There is no stick rule: sticking is the bristles holding
  the spring. sigma0 = `BRISTLE_N_PER_M` (1e12 N/m) puts the largest pre-sliding displacement
  g / sigma0 at 2e-12 m (a vibrometer resolves about 1e-8 m over a sample); the bristle
  damping sigma1 = 2 sqrt(sigma0 m) makes the stuck rig a critically damped mode at
  sqrt(sigma0 / m) / 2 pi = 49 kHz, so a stuck state is stable (its linearisation has
  stiffness sigma0 (1 -+ sigma0 z / g) > 0 and positive damping inside the band) and creeps
  below 1e-7 m/s, 1e-3 of the noise (test). How far a LuGre rig strays from the Coulomb
  motion scales as sigma0^(-1/2) (friction reverses over a displacement g / sigma0): 2.5e-4
  m/s at 1e8 N/m, 2.5e-5 at 1e10, 2.5e-6 at 1e12 (against lab's DOP853); real contacts are
  softer, and their pre-sliding is left out on purpose (no name in the vocabulary). Viscous
  damping, a cubic spring and the rig's constants are the plant's; a second structural mode,
  driven by the hammer and seen by the vibrometer, is linear and exact (partial fractions).
- Integrator: one stiff implicit `solve_ivp` BDF run over each record (rtol 1e-9, per-state
  atol down to 1e-17 m on the bristle, analytic Jacobian, dense output): the bristle's
  relaxation rate sigma0 |v| / g reaches 1e11 1/s, which only an implicit method steps over.
- Hits: a double-exponential pulse A (e^(-u/tau_f) - e^(-u/tau_r)), never cut off (its tail
  and its exact area A (tau_f - tau_r) are closed form), peak within 2.5 % of a level, one hit
  a level per session, onset anywhere between samples.
- Acquisition, an IEPE chain: the force channel AC-coupled (a first-order high-pass whose
  discharge time constant is drawn log-uniform 50-2000 s a session: a quartz hammer's sensor
  discharge time constant, hundreds to thousands of seconds on hammer datasheets, in series
  with a DC-coupled conditioner), then the ADC's anti-alias filter, a 5th-order elliptic
  (0.1 dB ripple, 70 dB stopband, passband edge 0.4 of the rate): both computed exactly, the
  pulse being a sum of exponentials, by the filters' partial fractions. The velocity through
  the vibrometer's decoder low-pass (2nd-order Bessel, -3 dB at 5, 10 or 20 kHz, the decoder's
  settings, drawn a session), its stated group delay (11, 22 or 43 us) taken off as a
  vibrometer's acquisition does, and the same elliptic filter (65-131 us, on both channels
  alike), both discretised exactly for a piecewise-linear input (first-order hold) on a grid
  8 times the sample rate. (The decoder's delay was first left in: the first look at the
  diagnosis on this world, 3 sessions a kind, named `sensor_delay` in 4 of 6 clean sessions
  and beside most right answers, rightly: every session hid a delay its labels did not
  carry. Taking it off made the labels true; no other change followed that look.)
  Sample rates 10, 12 or 20 kHz, drawn a session. Noise on each channel: white plus
  Ornstein-Uhlenbeck (red, a first-order low-pass of white noise with its corner drawn
  0.2-2 Hz); a small ADC zero offset on the force; 20-bit rounding over +-5000 N and +-1 m/s.
- Starts: as `analytic` hands them to the diagnosis: each hit of an isolated session from rest
  somewhere in the friction band (the bristle holding the spring there), diagnosed with fitted
  starts; re-centred when the session hides direction-dependent friction; chained sessions
  start each hit from the state (position and bristle) the one before left.
"""

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np
import scipy.integrate
import scipy.signal

from heldout.lab import Effects

MASS_KG, STIFFNESS_N_PER_M, DAMPING_N_S_PER_M = 10.391, 1982.0, 0.275
NORMAL_N = 0.680 * 9.81
BRISTLE_N_PER_M = 1e12
"""sigma0: the bristles' stiffness [N/m] (pre-sliding displacement g / sigma0 <= 2e-12 m)."""
BRISTLE_DAMPING_N_S_PER_M = 2.0 * math.sqrt(BRISTLE_N_PER_M * MASS_KG)
"""sigma1: critical damping of the rig stuck on its bristles [N s/m]."""
RATES_HZ = (10_000.0, 12_000.0, 20_000.0)
DECODER_HZ = (5_000.0, 10_000.0, 20_000.0)
"""The vibrometer decoder's low-pass settings (-3 dB) [Hz]."""
AC_TIME_CONSTANT_S = (50.0, 2000.0)
"""Range of the force channel's discharge time constant (drawn log-uniform) [s]."""
ELLIPTIC_ORDER, ELLIPTIC_RIPPLE_DB, ELLIPTIC_STOP_DB, ELLIPTIC_EDGE = 5, 0.1, 70.0, 0.4
OVERSAMPLE = 8
PRETRIGGER_S = 0.25
DURATION_S = 12.0
FORCE_RANGE_N, VELOCITY_RANGE_M_S, BITS = 5000.0, 1.0, 20
RTOL = 1e-9
ATOL = (1e-13, 1e-11, 1e-17)
"""BDF's absolute tolerances: position, velocity, bristle deflection [m, m/s, m]."""
STILL_M_S = 1e-9
"""Below this the rig counts as at rest (its motion's end) [m/s]."""


@dataclass(frozen=True)
class Pulse:
    """A double-exponential hammer pulse: peak [N], fall and rise time constants, onset [s]."""

    peak_n: float
    fall_s: float
    rise_s: float
    onset_s: float

    @cached_property
    def amplitude_n(self) -> float:
        """A, such that A (e^(-u/tau_f) - e^(-u/tau_r)) peaks at peak_n."""
        fall, rise = self.fall_s, self.rise_s
        at = math.log(fall / rise) * fall * rise / (fall - rise)
        return self.peak_n / (math.exp(-at / fall) - math.exp(-at / rise))

    @property
    def exponentials(self) -> tuple[tuple[float, float], ...]:
        """The force as sum c e^(-a u), u = t - onset >= 0: (c [N], a [1/s]) pairs."""
        a = self.amplitude_n
        return ((a, 1.0 / self.fall_s), (-a, 1.0 / self.rise_s))

    def force_at(self, time_s: float) -> float:
        """The force at one time [N] (the integrator's scalar path)."""
        u = time_s - self.onset_s
        if u <= 0.0:
            return 0.0
        return self.amplitude_n * (math.exp(-u / self.fall_s) - math.exp(-u / self.rise_s))

    def force(self, time_s: np.ndarray | float) -> np.ndarray:
        """The force at any times [N]."""
        u = np.asarray(time_s, dtype=float) - self.onset_s
        after = np.maximum(u, 0.0)
        value = sum(c * np.exp(-a * after) for c, a in self.exponentials)
        return np.where(u > 0.0, value, 0.0)

    @property
    def impulse_n_s(self) -> float:
        """The exact impulse, A (tau_f - tau_r) [N s]."""
        return self.amplitude_n * (self.fall_s - self.rise_s)


def random_pulse(rng: np.random.Generator, level_n: float, onset_s: float) -> Pulse:
    """A pulse within 2.5 % of a level, fall 0.3-1 ms, rise 10-45 % of the fall."""
    fall = rng.uniform(0.3e-3, 1.0e-3)
    return Pulse(level_n * rng.uniform(0.975, 1.025), fall, fall * rng.uniform(0.1, 0.45), onset_s)


@dataclass(frozen=True)
class Bristles:
    """The LuGre contact: its steady-state law g(v, x) and the bristle's state equation."""

    mu: float
    effects: Effects

    def _base(self, v: float) -> float:
        return self.mu + 0.5 * self.effects.asymmetry * (1.0 if v >= 0.0 else -1.0)

    def _track(self, x: float) -> tuple[float, float]:
        """track(x) and its slope [1/m]."""
        e = self.effects
        if not e.track_amplitude:
            return 1.0, 0.0
        phase = 2.0 * math.pi * x / e.track_wavelength_m + e.track_phase
        slope = e.track_amplitude * 2.0 * math.pi / e.track_wavelength_m * math.cos(phase)
        return 1.0 + e.track_amplitude * math.sin(phase), slope

    def law(self, v: float, x: float) -> tuple[float, float, float]:
        """(g [N], dg/dv, dg/dx): the sliding friction at steady state."""
        e = self.effects
        track, slope = self._track(x)
        base = self._base(v)
        excess, dexcess = 0.0, 0.0
        if e.static_excess:
            excess = e.static_excess * math.exp(-((v / e.stribeck_speed_m_s) ** 2))
            dexcess = -2.0 * v / e.stribeck_speed_m_s**2 * excess
        return (
            NORMAL_N * (base * track + excess),
            NORMAL_N * dexcess,
            NORMAL_N * base * slope,
        )

    def holding_n(self, direction: float, x: float) -> float:
        """The most the bristles hold a stuck rig at x against, pushed in a direction [N]."""
        track, _ = self._track(x)
        return NORMAL_N * (self._base(direction) * track + self.effects.static_excess)


@dataclass(frozen=True)
class Rig:
    """The plant with its hidden mechanical effects: the ODE in x, v and z (the bristle)."""

    bristles: Bristles
    pulse: Pulse

    @property
    def effects(self) -> Effects:
        """What the session hides."""
        return self.bristles.effects

    def _bristle(self, x: float, v: float, z: float) -> tuple[float, float, float, float]:
        """dz/dt and its partial derivatives by x, v, z."""
        g, g_v, g_x = self.bristles.law(v, x)
        speed = abs(v)
        sign = 1.0 if v >= 0.0 else -1.0
        rate = BRISTLE_N_PER_M * speed / g
        zdot = v - rate * z
        d_x = BRISTLE_N_PER_M * speed * z * g_x / g**2
        d_v = 1.0 - BRISTLE_N_PER_M * z * (sign * g - speed * g_v) / g**2
        return zdot, d_x, d_v, -rate

    def rhs(self, t: float, s: np.ndarray) -> np.ndarray:
        """ds/dt."""
        e = self.effects
        x, v, z = s
        zdot = self._bristle(x, v, z)[0]
        friction = BRISTLE_N_PER_M * z + BRISTLE_DAMPING_N_S_PER_M * zdot
        damping = DAMPING_N_S_PER_M + e.added_damping_n_s_per_m
        spring = STIFFNESS_N_PER_M * x + e.cubic_n_per_m3 * x**3
        push = self.pulse.force_at(t)
        return np.array([v, (push - damping * v - spring - friction) / MASS_KG, zdot])

    def jacobian(self, t: float, s: np.ndarray) -> np.ndarray:
        """d(ds/dt)/ds."""
        e = self.effects
        x, v, z = s
        _, d_x, d_v, d_z = self._bristle(x, v, z)
        sigma1 = BRISTLE_DAMPING_N_S_PER_M
        damping = DAMPING_N_S_PER_M + e.added_damping_n_s_per_m
        stiffness = STIFFNESS_N_PER_M + 3.0 * e.cubic_n_per_m3 * x**2
        return np.array(
            [
                [0.0, 1.0, 0.0],
                [
                    (-stiffness - sigma1 * d_x) / MASS_KG,
                    (-damping - sigma1 * d_v) / MASS_KG,
                    (-BRISTLE_N_PER_M - sigma1 * d_z) / MASS_KG,
                ],
                [d_x, d_v, d_z],
            ]
        )


@dataclass(frozen=True)
class Motion:
    """A record's motion: the BDF dense solution from the onset, and where it ended."""

    start: tuple[float, float]
    """Position [m] and bristle deflection [m] at rest before the hit."""
    onset_s: float
    solution: scipy.integrate.OdeSolution
    end: tuple[float, float]
    """Position [m] and bristle deflection [m] at the record's end."""
    still_s: float
    """From when the rig moves slower than STILL_M_S [s]."""

    def state(self, time_s: np.ndarray) -> np.ndarray:
        """x, v, z at any times (at rest at the start before the onset), shape (3, n)."""
        t = np.asarray(time_s, dtype=float)
        out = np.zeros((3, t.size))
        out[0], out[2] = self.start
        after = t > self.onset_s
        if after.any():
            out[:, after] = self.solution(np.minimum(t[after], self.solution.t_max))
        return out

    @property
    def rest_m(self) -> float:
        """Where the rig rests at the record's end [m]."""
        return self.end[0]


def move(rig: Rig, start: tuple[float, float], stop_s: float) -> Motion:
    """The motion from rest at (x, z) = start, hit at the pulse's onset, to stop_s: one BDF run."""
    run = scipy.integrate.solve_ivp(
        rig.rhs,
        (rig.pulse.onset_s, stop_s),
        np.array([start[0], 0.0, start[1]]),
        method='BDF',
        rtol=RTOL,
        atol=np.array(ATOL),
        jac=rig.jacobian,
        dense_output=True,
        first_step=rig.pulse.rise_s / 100.0,
    )
    if not run.success:
        raise RuntimeError(f'BDF failed: {run.message}')
    moving = np.flatnonzero(np.abs(run.y[1]) >= STILL_M_S)
    still = float(run.t[min(moving[-1] + 1, run.t.size - 1)]) if moving.size else rig.pulse.onset_s
    end = (float(run.y[0, -1]), float(run.y[2, -1]))
    return Motion(start, rig.pulse.onset_s, run.sol, end, still)


def mode(effects: Effects) -> tuple[np.ndarray, np.ndarray, float]:
    """The second mode's velocity per force, s / (m2 s^2 + c2 s + k2), as (zeros, poles, gain)."""
    omega = 2.0 * math.pi * effects.mode_hz
    zeta = effects.mode_damping_ratio
    pole = omega * complex(-zeta, math.sqrt(1.0 - zeta * zeta))
    return np.array([0.0]), np.array([pole, pole.conjugate()]), 1.0 / effects.mode_mass_kg


def mode_ring_s(effects: Effects) -> float:
    """How long the second mode rings above 1e-9 of its start (0 without one) [s]."""
    if not effects.mode_hz:
        return 0.0
    return math.log(1e9) / (effects.mode_damping_ratio * 2.0 * math.pi * effects.mode_hz)


def resting_bristle(effects: Effects, x: float) -> float:
    """The bristle deflection holding the spring at rest at x [m]."""
    return -(STIFFNESS_N_PER_M * x + effects.cubic_n_per_m3 * x**3) / BRISTLE_N_PER_M


def in_band(bristles: Bristles, rng: np.random.Generator) -> float:
    """A rest position drawn uniformly within 95 % of the friction band's half width [m]."""
    lowest = min(bristles.holding_n(1.0, 0.0), bristles.holding_n(-1.0, 0.0))
    lowest *= 1.0 - bristles.effects.track_amplitude
    return float(rng.uniform(-0.95, 0.95) * lowest / STIFFNESS_N_PER_M)


# --- acquisition ------------------------------------------------------------------------


def elliptic(rate_hz: float) -> tuple[np.ndarray, np.ndarray, float]:
    """The ADC's analog anti-alias filter (zeros, poles [rad/s], gain; DC gain 1)."""
    zeros, poles, gain = scipy.signal.ellip(
        ELLIPTIC_ORDER,
        ELLIPTIC_RIPPLE_DB,
        ELLIPTIC_STOP_DB,
        2.0 * math.pi * ELLIPTIC_EDGE * rate_hz,
        analog=True,
        output='zpk',
    )
    dc = gain * np.prod(-zeros) / np.prod(-poles)
    return zeros, poles, float(gain / dc.real)


def decoder(cutoff_hz: float) -> tuple[np.ndarray, np.ndarray, float]:
    """The vibrometer decoder's 2nd-order Bessel low-pass, -3 dB at cutoff_hz (DC gain 1)."""
    zeros, poles, gain = scipy.signal.bessel(
        2, 2.0 * math.pi * cutoff_hz, analog=True, output='zpk', norm='mag'
    )
    return zeros, poles, float(gain)


def ac_coupling(time_constant_s: float) -> tuple[np.ndarray, np.ndarray, float]:
    """The first-order high-pass s tau / (1 + s tau) of an IEPE channel."""
    return np.array([0.0]), np.array([-1.0 / time_constant_s]), 1.0


def cascade(*filters) -> tuple[np.ndarray, np.ndarray, float]:
    """Filters in series, as one (zeros, poles, gain)."""
    zeros = np.concatenate([f[0] for f in filters])
    poles = np.concatenate([f[1] for f in filters])
    return zeros, poles, float(np.prod([f[2] for f in filters]))


def exponential_response(
    filt: tuple[np.ndarray, np.ndarray, float],
    exponentials: Sequence[tuple[float, float]],
    u: np.ndarray,
) -> np.ndarray:
    """The exact output of a strictly proper filter with distinct poles, at times u >= 0 after
    the input sum c e^(-a u) (zero before u = 0) began, by partial fractions:
    y = sum_j c_j [H(-a_j) e^(-a_j u) + sum_i r_i e^(p_i u) / (p_i + a_j)]."""
    zeros, poles, gain = filt
    u = np.asarray(u, dtype=float)
    after = np.maximum(u, 0.0)
    out = np.zeros(u.shape, dtype=complex)
    residues = [
        gain * np.prod(p - zeros) / np.prod(np.delete(p - poles, i)) for i, p in enumerate(poles)
    ]
    for c, a in exponentials:
        at = gain * np.prod(-a - zeros) / np.prod(-a - poles)
        out += c * at * np.exp(-a * after)
        for p, r in zip(poles, residues, strict=True):
            out += c * r / (p + a) * np.exp(p * after)
    return np.where(u >= 0.0, out.real, 0.0)


def held_filter(filt: tuple[np.ndarray, np.ndarray, float], step_s: float) -> np.ndarray:
    """An analog filter discretised exactly for an input linear between grid points (first-order
    hold), as second-order sections.

    The zeros and poles of the held system are computed from its state space (`ss2zpk`),
    whose rounding misstates the gain by about 2e-7; the gain is set so the discrete DC gain
    is the analog one, which the hold keeps exactly.
    """
    a, b, c, d = scipy.signal.zpk2ss(*filt)
    ad, bd, cd, dd, _ = scipy.signal.cont2discrete((a, b, c, d), step_s, method='foh')
    zeros, poles, gain = scipy.signal.ss2zpk(ad, bd, cd, dd)
    analog_dc = filt[2] * np.prod(-filt[0]) / np.prod(-filt[1])
    held_dc = gain * np.prod(1.0 - zeros) / np.prod(1.0 - poles)
    return scipy.signal.zpk2sos(zeros, poles, gain * (analog_dc / held_dc).real)


def red_noise(rng: np.random.Generator, samples: int, rate_hz: float, std: float) -> np.ndarray:
    """Ornstein-Uhlenbeck noise of a standard deviation, its corner drawn 0.2-2 Hz, started in
    its stationary state."""
    pole = math.exp(-2.0 * math.pi * rng.uniform(0.2, 2.0) / rate_hz)
    drive = rng.normal(0.0, std * math.sqrt(1.0 - pole * pole), samples)
    drive[0] = rng.normal(0.0, std)
    return scipy.signal.lfilter([1.0], [1.0, -pole], drive)


def quantised(values: np.ndarray, full_scale: float) -> np.ndarray:
    """Rounded to a BITS converter's step over +-full_scale, clipped there."""
    step = 2.0 * full_scale / 2**BITS
    return np.clip(np.round(values / step) * step, -full_scale, full_scale)


@dataclass(frozen=True)
class Chain:
    """One session's acquisition settings (drawn a session)."""

    rate_hz: float
    decoder_hz: float
    ac_time_constant_s: float
    force_offset_n: float

    def force(self, pulse: Pulse, samples: int) -> np.ndarray:
        """The force channel's samples, exact through AC coupling and the anti-alias filter."""
        filt = cascade(ac_coupling(self.ac_time_constant_s), elliptic(self.rate_hz))
        times = np.arange(samples) / self.rate_hz
        return exponential_response(filt, pulse.exponentials, times - pulse.onset_s)

    @property
    def decoder_delay_s(self) -> float:
        """The decoder's group delay at DC, sum of -1/p over its poles [s]."""
        return float(np.sum(-1.0 / decoder(self.decoder_hz)[1]).real)

    def velocity(self, seen, samples: int, active: tuple[float, float]) -> np.ndarray:
        """The velocity channel's samples: `seen` (a function of time, zero before active[0]
        and constant after active[1]) through the decoder and the anti-alias filter, the
        decoder's stated delay taken off, as a vibrometer's acquisition does, so the channels
        are not delayed against each other (the elliptic filter delays both alike)."""
        step = 1.0 / (self.rate_hz * OVERSAMPLE)
        first = max(0, math.floor(active[0] * self.rate_hz) - 2)
        last = min(samples, math.ceil(active[1] * self.rate_hz) + 1)
        fine = (first + np.arange((last - first) * OVERSAMPLE + 1) / OVERSAMPLE) / self.rate_hz
        sos = held_filter(cascade(decoder(self.decoder_hz), elliptic(self.rate_hz)), step)
        values = seen(fine + self.decoder_delay_s)
        out = np.zeros(samples)
        out[first:last] = scipy.signal.sosfilt(sos, values)[:-1:OVERSAMPLE]
        if last < samples:
            # past `active` the input is constant: the filter settles to it (DC gain 1)
            out[last:] = values[-1]
        return out


@dataclass(frozen=True)
class BristleRecord:
    """One hit's record as the DAQ delivered it, and its truth."""

    force_n: np.ndarray
    velocity_m_s: np.ndarray
    sample_rate_hz: float
    pulse: Pulse
    mu: float
    start_m: float
    rest_m: float
    chain: Chain
    end_state: tuple[float, float]
    """Position and bristle deflection at the record's end [m]."""
    source: str = ''


@dataclass(frozen=True)
class BristleWorld:
    """The `bristle` world (module doc): its noise levels and record length."""

    name: str = 'bristle'
    sensor: str = 'velocity'
    """What the response sensor measures (as `lab.World.sensor`): a vibrometer."""
    force_white_n: float = 0.15
    force_red_n: float = 0.08
    force_offset_n: float = 0.1
    """The largest ADC zero offset of the force channel (drawn a session, either sign) [N]."""
    velocity_white_m_s: float = 1.0e-4
    velocity_red_m_s: float = 0.3e-4
    duration_s: float = DURATION_S

    def record(
        self,
        effects: Effects,
        mu: float,
        pulse: Pulse,
        start: tuple[float, float],
        chain: Chain,
        rng: np.random.Generator,
        source: str = '',
    ) -> BristleRecord:
        """One hit's record from rest at start = (x, z)."""
        motion = move(Rig(Bristles(mu, effects), pulse), start, self.duration_s)
        lag = effects.lag_s

        def seen(t: np.ndarray) -> np.ndarray:
            """What the vibrometer aims at moves with: the rig plus a second mode (exact)."""
            velocity = motion.state(t - lag)[1]
            if effects.mode_hz:
                velocity += exponential_response(
                    mode(effects), pulse.exponentials, t - lag - pulse.onset_s
                )
            return velocity

        samples = round(self.duration_s * chain.rate_hz)
        moving = max(motion.still_s, pulse.onset_s + mode_ring_s(effects)) + lag + 0.02
        active = (pulse.onset_s, min(self.duration_s, moving))
        force = chain.force(pulse, samples) + chain.force_offset_n
        force += rng.normal(0.0, self.force_white_n, samples)
        force += red_noise(rng, samples, chain.rate_hz, self.force_red_n)
        speed = chain.velocity(seen, samples, active) + effects.velocity_offset_m_s
        speed += rng.normal(0.0, self.velocity_white_m_s, samples)
        speed += red_noise(rng, samples, chain.rate_hz, self.velocity_red_m_s)
        return BristleRecord(
            quantised(force, FORCE_RANGE_N),
            quantised(speed, VELOCITY_RANGE_M_S),
            chain.rate_hz,
            pulse,
            mu,
            start[0],
            motion.rest_m,
            chain,
            motion.end,
            source,
        )

    def session(
        self,
        effects: Effects,
        mu: float,
        rng: np.random.Generator,
        levels_n: Sequence[float],
        *,
        chained: bool = False,
        centred: bool = False,
    ) -> list[BristleRecord]:
        """One record a level; mu changes by effects.mu_step a hit; the chain drawn a session.

        chained: the first hit from rest at the centre, each later one from the state the one
        before left; centred: every hit from rest at the centre; otherwise each from rest
        somewhere in the friction band.
        """
        low, high = AC_TIME_CONSTANT_S
        chain = Chain(
            float(rng.choice(RATES_HZ)),
            float(rng.choice(DECODER_HZ)),
            float(np.exp(rng.uniform(np.log(low), np.log(high)))),
            float(rng.uniform(-1.0, 1.0) * self.force_offset_n),
        )
        records, start = [], (0.0, 0.0)
        for index, level in enumerate(levels_n):
            hit_mu = mu * (1.0 + effects.mu_step) ** index
            if not (chained or centred):
                x = in_band(Bristles(hit_mu, effects), rng)
                start = (x, resting_bristle(effects, x))
            onset = PRETRIGGER_S + rng.uniform(0.0, 1.0) / chain.rate_hz
            made = self.record(
                effects,
                hit_mu,
                random_pulse(rng, float(level), onset),
                start,
                chain,
                rng,
                f'{self.name} hit {index}',
            )
            records.append(made)
            if chained:
                start = made.end_state
        return records


BRISTLE = BristleWorld()
"""The `bristle` world (module doc)."""
