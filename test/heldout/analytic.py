"""A fourth held-out world, `analytic`: written when `ivp` was about to become a
tuning world, and never looked at before its first sweep (never tuned on).

Other choices than `lab.EVENTS`, `lab.STEPS` and `ivp.IVP` at every stage, sharing only the
`lab.Effects` description:

- Hits: a rubber tip's asymmetric pulses, a skewed raised cosine (a quick rise, a slower fall)
  and a beta pulse u^a (T - u)^b with b > a, each followed by a small rebound bump (the tip
  bouncing back onto the rig); onset anywhere between samples; impulses and the cumulative
  impulse exact in closed form (`Tap.impulse_until`: the regularised incomplete beta function
  for the beta pulse).
- Motion, linear between events (Coulomb friction, with damping, asymmetry, a drifting mu):
  solved in closed form piecewise. Each slide after the hit is the exact damped oscillation
  about the slide's equilibrium (x = -s mu_s N / k); during the hit the forced response is the
  Duhamel integral of the exact impulse response, by Gauss-Legendre quadrature between
  consecutive query times; the breakaway instant and each stop are roots of these analytic
  expressions, found by `scipy.optimize.brentq`. Nonlinear contacts and springs (Stribeck, a
  cubic spring, a wear track) are integrated by scipy's implicit Radau with the stop located
  as an event.
- Sample rate: drawn per session from the lab DAQ rates 10, 10.24 (an NI 9234's) and 12.8 kHz.
- Acquisition: each channel integrated exactly over cells of an eighth of a sample period
  (the force by its closed-form cumulative impulse, the velocity by the change of the exact
  position), through the same 6th-order Chebyshev type I IIR anti-alias filter (0.5 dB
  ripple, 0.4 of the sample rate) on both channels, so no delay between them; then a small
  force zero offset, white noise plus 1/f^alpha noise (alpha drawn 0.3-1.5 a channel a
  session), and 24-bit rounding over +-5000 N and +-1 m/s.
- Starts: each hit of an isolated session from rest somewhere in the friction band, not at
  the centre: the diagnosis is told to fit each start (`FITTED`, the CLI's default), since no
  lab knows it. A session hiding direction-dependent friction is re-centred before each hit
  (told `CENTRE`): with fitted starts an asymmetry is exactly a shifted centre, invisible to
  any diagnosis (docs/explanation/heldout-validation.md). Chained sessions start at the centre
  and each later hit where the one before left the rig.
"""

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.integrate
import scipy.optimize
import scipy.signal
import scipy.special

from heldout.lab import Effects

MASS_KG, STIFFNESS_N_PER_M, DAMPING_N_S_PER_M = 10.391, 1982.0, 0.275
NORMAL_N = 0.680 * 9.81
RATES_HZ = (10_000.0, 10_240.0, 12_800.0)
"""Lab DAQ rates a session is recorded at (10.24 kHz: an NI 9234's)."""
CELLS_PER_SAMPLE = 8
PRETRIGGER_S = 0.15
FORCE_RANGE_N, VELOCITY_RANGE_M_S = 5000.0, 1.0
"""The 24-bit converter's +- ranges (a 1 mV/N hammer and a 200 mm/s/V vibrometer on +-5 V)."""
FILTER_ORDER, FILTER_RIPPLE_DB, FILTER_CUTOFF = 6, 0.5, 0.4
"""The anti-alias filter: Chebyshev type I, its cutoff as a fraction of the sample rate."""
GAUSS_NODES = 8
"""Gauss-Legendre nodes between consecutive query times of a Duhamel integral."""


@dataclass(frozen=True)
class Tap:
    """A rubber-tipped hammer hit: its main pulse and a small rebound, onset [s].

    shape 'skewed_cosine': a raised-cosine rise over rise_s and fall over fall_s; 'beta': peak
    x (u/(m T))^a ((T - u)/((1 - m) T))^b over T = rise_s + fall_s, m = a / (a + b) (its peak
    at rise_s). The rebound: a raised cosine of rebound_ratio x peak, rebound_s long, starting
    gap_s after the main pulse.
    """

    shape: str
    peak_n: float
    rise_s: float
    fall_s: float
    onset_s: float
    rebound_ratio: float = 0.04
    gap_s: float = 0.5e-3
    rebound_s: float = 0.6e-3

    @property
    def main_s(self) -> float:
        """The main pulse's duration [s]."""
        return self.rise_s + self.fall_s

    @property
    def rebound_start_s(self) -> float:
        """When the rebound begins [s]."""
        return self.onset_s + self.main_s + self.gap_s

    @property
    def end_s(self) -> float:
        """When the force is over [s]."""
        return self.rebound_start_s + self.rebound_s

    @property
    def edges_s(self) -> tuple[float, ...]:
        """Where the force is not smooth: onset, peak, main pulse's end, rebound's ends [s]."""
        peak = self.onset_s + self.rise_s
        return (self.onset_s, peak, self.onset_s + self.main_s, self.rebound_start_s, self.end_s)

    def _exponents(self) -> tuple[float, float]:
        """The beta pulse's a and b (its peak at rise_s)."""
        a = 2.0
        return a, a * self.fall_s / self.rise_s

    def _beta_area(self) -> float:
        a, b = self._exponents()
        m = a / (a + b)
        return self.main_s * scipy.special.beta(a + 1.0, b + 1.0) / (m**a * (1.0 - m) ** b)

    def force(self, time_s: np.ndarray | float) -> np.ndarray:
        """The force at any times [N]."""
        u = np.asarray(time_s, dtype=float) - self.onset_s
        main = np.clip(u, 0.0, self.main_s)
        if self.shape == 'skewed_cosine':
            rising = 0.5 * (1.0 - np.cos(math.pi * np.minimum(main, self.rise_s) / self.rise_s))
            falling = 0.5 * (1.0 + np.cos(math.pi * (main - self.rise_s) / self.fall_s))
            shape = np.where(main < self.rise_s, rising, falling)
        else:
            a, b = self._exponents()
            m = a / (a + b)
            w = main / self.main_s
            shape = (w / m) ** a * ((1.0 - w) / (1.0 - m)) ** b
        inside = (u > 0.0) & (u < self.main_s)
        r = np.clip(np.asarray(time_s, dtype=float) - self.rebound_start_s, 0.0, self.rebound_s)
        bump = 0.5 * self.rebound_ratio * (1.0 - np.cos(2.0 * math.pi * r / self.rebound_s))
        return self.peak_n * (np.where(inside, shape, 0.0) + bump)

    def impulse_until(self, time_s: np.ndarray | float) -> np.ndarray:
        """The exact impulse delivered by a time, the force's antiderivative [N s]."""
        u = np.clip(np.asarray(time_s, dtype=float) - self.onset_s, 0.0, self.main_s)
        if self.shape == 'skewed_cosine':
            tr, tf = self.rise_s, self.fall_s
            up = np.minimum(u, tr)
            down = np.clip(u - tr, 0.0, tf)
            main = 0.5 * (up - tr / math.pi * np.sin(math.pi * up / tr))
            main = main + 0.5 * (down + tf / math.pi * np.sin(math.pi * down / tf))
        else:
            a, b = self._exponents()
            main = self._beta_area() * scipy.special.betainc(a + 1.0, b + 1.0, u / self.main_s)
        r = np.clip(np.asarray(time_s, dtype=float) - self.rebound_start_s, 0.0, self.rebound_s)
        period = self.rebound_s
        bump = (
            0.5
            * self.rebound_ratio
            * (r - period / (2 * math.pi) * np.sin(2 * math.pi * r / period))
        )
        return self.peak_n * (main + bump)

    @property
    def impulse_n_s(self) -> float:
        """Exact impulse of the whole hit [N s]."""
        return float(self.impulse_until(self.end_s))


def random_tap(rng: np.random.Generator, level_n: float, onset_s: float) -> Tap:
    """A skewed raised cosine or a beta pulse, 1.5-4 ms, peak within 2 % of a level."""
    shape = str(rng.choice(('skewed_cosine', 'beta')))
    main = rng.uniform(1.5e-3, 4e-3)
    rise = main * rng.uniform(0.25, 0.45)
    return Tap(
        shape,
        level_n * rng.uniform(0.98, 1.02),
        rise,
        main - rise,
        onset_s,
        rebound_ratio=rng.uniform(0.02, 0.06),
        gap_s=rng.uniform(0.3e-3, 1.0e-3),
        rebound_s=rng.uniform(0.4e-3, 0.8e-3),
    )


@dataclass(frozen=True)
class Oscillator:
    """m y'' + c y' + k y = f(t): its exact free motion and its Duhamel forced motion."""

    mass_kg: float
    damping_n_s_per_m: float
    stiffness_n_per_m: float

    @property
    def decay(self) -> float:
        """sigma = c / 2m [1/s]."""
        return self.damping_n_s_per_m / (2.0 * self.mass_kg)

    @property
    def damped(self) -> float:
        """omega_d [rad/s]."""
        return math.sqrt(self.stiffness_n_per_m / self.mass_kg - self.decay**2)

    def free(self, y0: float, v0: float, tau: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """(y, y') a time tau after (y0, v0), no force."""
        s, w = self.decay, self.damped
        tau = np.asarray(tau, dtype=float)
        b = (v0 + s * y0) / w
        envelope, c, n = np.exp(-s * tau), np.cos(w * tau), np.sin(w * tau)
        y = envelope * (y0 * c + b * n)
        v = envelope * ((b * w - s * y0) * c - (y0 * w + s * b) * n)
        return y, v

    def first_stop(self, y0: float, v0: float) -> float:
        """The first time after 0 the free velocity is zero [s] (brentq on the expression)."""
        half = math.pi / self.damped
        if v0 == 0.0:
            return half  # the velocity is -e^(-s t) y0 (w + s^2/w) sin(w t) exactly
        return scipy.optimize.brentq(
            lambda t: float(self.free(y0, v0, t)[1]), 0.0, half, xtol=1e-15, rtol=1e-15
        )

    def forced(
        self,
        y0: float,
        v0: float,
        force: Callable[[np.ndarray], np.ndarray],
        t0: float,
        times: np.ndarray,
        edges: Sequence[float] = (),
    ) -> tuple[np.ndarray, np.ndarray]:
        """(y, y') at sorted times >= t0 from (y0, v0) at t0 under a force.

        The particular part is the Duhamel integral e^(-s t)/(m w) [sin(w t) Ic - cos(w t) Is]
        with Ic, Is = int e^(s u) (cos, sin)(w u) f(u) du, accumulated by Gauss-Legendre
        quadrature between consecutive query times and the force's edges.
        """
        s, w = self.decay, self.damped
        tau = np.asarray(times, dtype=float) - t0
        cuts = [e - t0 for e in edges if t0 < e < t0 + tau[-1]]
        knots = np.unique(np.concatenate(([0.0], tau, cuts)))
        nodes, weights = np.polynomial.legendre.leggauss(GAUSS_NODES)
        left, width = knots[:-1, None], np.diff(knots)[:, None]
        u = left + 0.5 * width * (nodes + 1.0)
        f = force(u + t0) * np.exp(s * u) * 0.5 * width * weights
        cumulative_c = np.concatenate(([0.0], np.cumsum((f * np.cos(w * u)).sum(axis=1))))
        cumulative_s = np.concatenate(([0.0], np.cumsum((f * np.sin(w * u)).sum(axis=1))))
        at = np.searchsorted(knots, tau)
        ic, is_ = cumulative_c[at], cumulative_s[at]
        envelope, c, n = np.exp(-s * tau) / (self.mass_kg * w), np.cos(w * tau), np.sin(w * tau)
        y_free, v_free = self.free(y0, v0, tau)
        y = y_free + envelope * (n * ic - c * is_)
        v = v_free + envelope * ((w * c - s * n) * ic + (s * c + w * n) * is_)
        return y, v


@dataclass(frozen=True)
class Friction:
    """The contact: mu by direction (asymmetry), speed (Stribeck) and position (a wear track)."""

    mu: float
    effects: Effects

    def base(self, direction: float, x: float) -> float:
        """Sliding coefficient before the Stribeck excess [-]."""
        e = self.effects
        track = 1.0 + e.track_amplitude * math.sin(
            2.0 * math.pi * x / e.track_wavelength_m + e.track_phase
        )
        return (self.mu + 0.5 * e.asymmetry * direction) * track

    def kinetic(self, direction: float, speed: float, x: float) -> float:
        """Coefficient while sliding at a speed [-]."""
        e = self.effects
        return self.base(direction, x) + e.static_excess * math.exp(
            -((speed / e.stribeck_speed_m_s) ** 2)
        )

    def static(self, direction: float, x: float) -> float:
        """Coefficient a stuck mass holds against when pushed in a direction [-]."""
        return self.base(direction, x) + self.effects.static_excess

    @property
    def linear(self) -> bool:
        """Whether slides are linear (no Stribeck excess, no wear track)."""
        return not self.effects.static_excess and not self.effects.track_amplitude


Segment = tuple[float, float, Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]]
"""A phase of the motion: from, to [s], and (x, v) at times inside it."""


@dataclass(frozen=True)
class Motion:
    """The rig's motion from rest at start_m: phases, and where it came to rest."""

    start_m: float
    segments: tuple[Segment, ...]
    rest_m: float
    """Where it came to rest (NaN: still moving at the end)."""

    def state(self, time_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(x [m], v [m/s]) at any times."""
        t = np.asarray(time_s, dtype=float)
        x, v = np.full(t.shape, self.start_m), np.zeros(t.shape)
        for t0, t1, evaluate in self.segments:
            inside = (t >= t0) & (t < t1)
            if inside.any():
                x[inside], v[inside] = evaluate(t[inside])
            x[t >= t1] = evaluate(np.array([t1]))[0][0]
        return x, v

    @property
    def last_motion_s(self) -> float:
        """When the last moving phase ends [s]."""
        return self.segments[-1][1]


def _spring(effects: Effects, x: float) -> float:
    return STIFFNESS_N_PER_M * x + effects.cubic_n_per_m3 * x**3


def breakaway(friction: Friction, tap: Tap, x: float) -> float:
    """When the hammer tears the stuck mass at x loose in +x [s] (brentq on the force)."""
    effects = friction.effects
    holds = NORMAL_N * friction.static(1.0, x) + _spring(effects, x)
    peak = tap.onset_s + tap.rise_s
    return scipy.optimize.brentq(
        lambda t: float(tap.force(t)) - holds, tap.onset_s, peak, xtol=1e-15, rtol=1e-15
    )


def closed_form(friction: Friction, tap: Tap, start_m: float, stop_s: float) -> Motion:
    """The motion of a linear-between-events rig, piecewise in closed form."""
    effects = friction.effects
    osc = Oscillator(
        MASS_KG, DAMPING_N_S_PER_M + effects.added_damping_n_s_per_m, STIFFNESS_N_PER_M
    )
    segments: list[Segment] = []
    t = breakaway(friction, tap, start_m)
    centre = -NORMAL_N * friction.base(1.0, 0.0) / STIFFNESS_N_PER_M

    def hit_phase(times, t0=t, y0=start_m - centre, shift=centre):
        y, v = osc.forced(y0, 0.0, tap.force, t0, times, tap.edges_s)
        return y + shift, v

    end = tap.end_s
    grid = np.linspace(t, end, 400)
    _, v_grid = hit_phase(grid)
    if v_grid[1:].min() <= 0.0:
        raise ValueError('the mass stopped during the hit: outside what this world models')
    segments.append((t, end, hit_phase))
    x_end, v_end = (float(q[0]) for q in hit_phase(np.array([end])))
    t, x, v = end, x_end, v_end
    while t < stop_s:
        direction = math.copysign(1.0, v) if v else -math.copysign(1.0, x)
        centre = -direction * NORMAL_N * friction.base(direction, 0.0) / STIFFNESS_N_PER_M
        y0, v0 = x - centre, v
        duration = osc.first_stop(y0, v0)

        def slide(times, t0=t, y0=y0, v0=v0, shift=centre):
            y, speed = osc.free(y0, v0, times - t0)
            return y + shift, speed

        segments.append((t, t + duration, slide))
        t += duration
        x = float(osc.free(y0, v0, duration)[0]) + centre
        v = 0.0
        pushed = -math.copysign(1.0, x)
        if STIFFNESS_N_PER_M * abs(x) <= NORMAL_N * friction.static(pushed, x):
            return Motion(start_m, tuple(segments), x)
    return Motion(start_m, tuple(segments), math.nan)


def implicit(friction: Friction, tap: Tap, start_m: float, stop_s: float) -> Motion:
    """The motion of a nonlinear rig: Radau slides, each stop an event."""
    effects = friction.effects
    damping = DAMPING_N_S_PER_M + effects.added_damping_n_s_per_m
    segments: list[Segment] = []
    t, x, v = breakaway(friction, tap, start_m), start_m, 0.0
    direction = 1.0
    edges = [e for e in tap.edges_s if e > t]
    while t < stop_s:

        def rhs(time, z, s=direction):
            drag = s * NORMAL_N * friction.kinetic(s, abs(z[1]), z[0])
            push = float(tap.force(time)) if time < tap.end_s else 0.0
            return (z[1], (push - damping * z[1] - _spring(effects, z[0]) - drag) / MASS_KG)

        def stops(time, z):
            return z[1]

        stops.terminal, stops.direction = True, -direction
        upto = next((e for e in edges if e > t), stop_s)
        run = scipy.integrate.solve_ivp(
            rhs,
            (t, upto),
            (x, v),
            method='Radau',
            rtol=1e-9,
            atol=(1e-12, 1e-10),
            dense_output=True,
            events=stops,
            max_step=tap.rise_s / 20.0 if upto <= tap.end_s else math.inf,
        )
        if not run.success:
            raise RuntimeError(f'Radau failed: {run.message}')
        solution = run.sol
        segments.append((t, float(run.t[-1]), lambda times, sol=solution: tuple(sol(times))))
        t, x, v = float(run.t[-1]), float(run.y[0, -1]), float(run.y[1, -1])
        if run.status != 1:
            continue
        if t < tap.end_s:
            raise ValueError('the mass stopped during the hit: outside what this world models')
        v = 0.0
        direction = -math.copysign(1.0, _spring(effects, x))
        if abs(_spring(effects, x)) <= NORMAL_N * friction.static(direction, x):
            return Motion(start_m, tuple(segments), x)
    return Motion(start_m, tuple(segments), math.nan)


def motion(friction: Friction, tap: Tap, start_m: float, stop_s: float) -> Motion:
    """The rig's motion after a hit from rest at start_m: in closed form where slides are
    linear, else Radau."""
    linear = friction.linear and not friction.effects.cubic_n_per_m3
    return (closed_form if linear else implicit)(friction, tap, start_m, stop_s)


def mode_position(effects: Effects, tap: Tap) -> Callable[[np.ndarray], np.ndarray]:
    """The second mode's displacement at any times (Duhamel in the hit, free after); zero
    without one."""
    if not effects.mode_hz:
        return lambda t: np.zeros(np.shape(t))
    omega = 2.0 * math.pi * effects.mode_hz
    mass = effects.mode_mass_kg
    osc = Oscillator(mass, 2.0 * effects.mode_damping_ratio * omega * mass, omega**2 * mass)
    y_end, v_end = (
        float(q[0])
        for q in osc.forced(0.0, 0.0, tap.force, tap.onset_s, np.array([tap.end_s]), tap.edges_s)
    )

    def position(time_s: np.ndarray) -> np.ndarray:
        t = np.asarray(time_s, dtype=float)
        out = np.zeros(t.shape)
        inside = (t > tap.onset_s) & (t < tap.end_s)
        if inside.any():
            order = np.argsort(t[inside])
            y, _ = osc.forced(0.0, 0.0, tap.force, tap.onset_s, t[inside][order], tap.edges_s)
            out[np.flatnonzero(inside)[order]] = y
        late = t >= tap.end_s
        out[late] = osc.free(y_end, v_end, t[late] - tap.end_s)[0]
        return out

    return position


def anti_alias(rate_hz: float) -> np.ndarray:
    """The Chebyshev type I anti-alias filter on the cell grid, as second-order sections.

    Its gain at DC is calibrated to 1 (an even-order Chebyshev sits at the ripple's bottom
    there), as a DAQ's channel is calibrated.
    """
    sos = scipy.signal.cheby1(
        FILTER_ORDER,
        FILTER_RIPPLE_DB,
        FILTER_CUTOFF * rate_hz,
        fs=rate_hz * CELLS_PER_SAMPLE,
        output='sos',
    )
    dc = np.prod(sos[:, :3].sum(axis=1) / sos[:, 3:].sum(axis=1))
    sos[0, :3] /= dc
    return sos


def integrate_and_filter(
    antiderivative: Callable[[np.ndarray], np.ndarray],
    rate_hz: float,
    samples: int,
    active: tuple[float, float],
) -> np.ndarray:
    """A channel at `samples` samples from t = 0: its exact mean over each cell, filtered.

    antiderivative: the signal's integral (the force's impulse, the velocity's position);
    the signal is zero outside `active`.
    """
    sos = anti_alias(rate_hz)
    first = max(0, math.floor(active[0] * rate_hz) - 4)
    last = min(samples, math.ceil(active[1] * rate_hz) + 400)
    out = np.zeros(samples)
    cell = 1.0 / (rate_hz * CELLS_PER_SAMPLE)
    ends = cell * (
        first * CELLS_PER_SAMPLE
        - CELLS_PER_SAMPLE
        + 1
        + np.arange((last - first) * CELLS_PER_SAMPLE)
    )
    edges = np.concatenate(([ends[0] - cell], ends))
    means = np.diff(antiderivative(edges)) / cell
    filtered = scipy.signal.sosfilt(sos, means)
    out[first:last] = filtered[CELLS_PER_SAMPLE - 1 :: CELLS_PER_SAMPLE]
    return out


def coloured(rng: np.random.Generator, samples: int, rate_hz: float, std: float) -> np.ndarray:
    """1/f^alpha noise of a standard deviation, alpha drawn in 0.3-1.5 (flat below 0.1 Hz)."""
    alpha = rng.uniform(0.3, 1.5)
    spectrum = np.fft.rfft(rng.normal(size=samples))
    frequency = np.fft.rfftfreq(samples, 1.0 / rate_hz)
    spectrum /= np.maximum(frequency, 0.1) ** (alpha / 2.0)
    spectrum[0] = 0.0
    noise = np.fft.irfft(spectrum, samples)
    return std * noise / noise.std()


def quantised(values: np.ndarray, full_scale: float) -> np.ndarray:
    """Rounded to a 24-bit converter's step over +-full_scale, clipped there."""
    step = 2.0 * full_scale / 2**24
    return np.clip(np.round(values / step) * step, -full_scale, full_scale)


@dataclass(frozen=True)
class AnalyticRecord:
    """One hit's record as the DAQ delivered it, and its truth."""

    force_n: np.ndarray
    velocity_m_s: np.ndarray
    sample_rate_hz: float
    tap: Tap
    mu: float
    start_m: float
    rest_m: float
    source: str = ''


@dataclass(frozen=True)
class AnalyticWorld:
    """The `analytic` world (module doc): its noise levels and record length."""

    name: str = 'analytic'
    sensor: str = 'velocity'
    """What the response sensor measures (as `lab.World.sensor`): a vibrometer."""
    force_white_n: float = 0.15
    force_coloured_n: float = 0.1
    force_offset_n: float = 0.3
    """The largest force zero offset (drawn a session, either sign) [N]."""
    velocity_white_m_s: float = 1.0e-4
    velocity_coloured_m_s: float = 0.4e-4
    duration_s: float = 12.0

    def record(
        self,
        effects: Effects,
        mu: float,
        tap: Tap,
        start_m: float,
        rate_hz: float,
        offset_n: float,
        rng: np.random.Generator,
        source: str = '',
    ) -> AnalyticRecord:
        """One hit's record from rest at start_m."""
        moved = motion(Friction(mu, effects), tap, start_m, self.duration_s)
        mode = mode_position(effects, tap)
        lag = effects.lag_s

        def position(t: np.ndarray) -> np.ndarray:
            return moved.state(t - lag)[0] + mode(t - lag)

        ring = 0.0
        if effects.mode_hz:
            ring = 12.0 / (effects.mode_damping_ratio * 2 * math.pi * effects.mode_hz)
        moving_until = min(self.duration_s, max(moved.last_motion_s, tap.end_s + ring) + lag)
        samples = round(self.duration_s * rate_hz)
        force = integrate_and_filter(tap.impulse_until, rate_hz, samples, (tap.onset_s, tap.end_s))
        speed = integrate_and_filter(position, rate_hz, samples, (tap.onset_s, moving_until))
        force += offset_n + rng.normal(0.0, self.force_white_n, samples)
        force += coloured(rng, samples, rate_hz, self.force_coloured_n)
        speed += effects.velocity_offset_m_s + rng.normal(0.0, self.velocity_white_m_s, samples)
        speed += coloured(rng, samples, rate_hz, self.velocity_coloured_m_s)
        return AnalyticRecord(
            quantised(force, FORCE_RANGE_N),
            quantised(speed, VELOCITY_RANGE_M_S),
            rate_hz,
            tap,
            mu,
            start_m,
            moved.rest_m,
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
    ) -> list[AnalyticRecord]:
        """One record a level; mu changes by effects.mu_step a hit; the rate drawn a session.

        chained: the first hit from the centre, each later one where the one before left the
        rig; otherwise each from rest in the friction band, or at the centre if `re_centred`.
        """
        rate = float(rng.choice(RATES_HZ))
        offset = rng.uniform(-1.0, 1.0) * self.force_offset_n
        centred = chained or re_centred(effects)
        records, start = [], 0.0
        for index, level in enumerate(levels_n):
            hit_mu = mu * (1.0 + effects.mu_step) ** index
            if not centred:
                start = in_band(Friction(hit_mu, effects), rng)
            onset = PRETRIGGER_S + rng.uniform(0.0, 1.0) / rate
            tap = random_tap(rng, float(level), onset)
            made = self.record(
                effects, hit_mu, tap, start, rate, offset, rng, f'{self.name} hit {index}'
            )
            records.append(made)
            if chained and math.isfinite(made.rest_m):
                start = made.rest_m
        return records


def re_centred(effects: Effects) -> bool:
    """Whether a session's isolated hits start at the centre: where direction-dependent friction
    is hidden (against fitted starts it is exactly a shifted centre, so a lab re-centres)."""
    return bool(effects.asymmetry)


def in_band(friction: Friction, rng: np.random.Generator) -> float:
    """A rest position in the friction band, 20-90 % of its half width off centre [m]."""
    lowest = min(friction.static(1.0, 0.0), friction.static(-1.0, 0.0))
    lowest *= 1.0 - friction.effects.track_amplitude
    half_width = NORMAL_N * lowest / STIFFNESS_N_PER_M
    return float(rng.choice((-1.0, 1.0)) * rng.uniform(0.2, 0.9) * half_width)


ANALYTIC = AnalyticWorld()
"""The `analytic` world (module doc)."""
