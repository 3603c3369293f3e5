"""A seventh held-out world, `newmark`: a structural dynamicist's simulator, implicit steps.

Written when `bristle` was about to become a tuning world, its physics checked
against lab's event-located DOP853 (`heldout.plant.solve_events`) before any diagnosis ran
on it (never tuned on). It shares only `lab.Effects` (the effect vocabulary and its
parameters) with the other worlds and makes other choices at every stage:

- Integrator: Newmark-beta with average acceleration (gamma 1/2, beta 1/4: implicit,
  unconditionally stable, second order, no numerical damping), fixed steps of
  `FINE_STEP_S` (0.5 us) while the hammer force acts and `COARSE_STEP_S` (10 us) after it,
  Newton iteration each step on the displacement for the nonlinear terms (a cubic spring,
  Stribeck, a wear track), compiled by numba (a 12 s record in tens of milliseconds).
  Halving both steps moves the velocity by about 1e-8 m/s (the test allows 1e-7): the hit
  is resolved to (h omega)^2 / 12 ~ 1e-6 of its velocity change, the rig's 2.2 Hz swing to
  1e-9. Against lab's DOP853 the motion is within 2e-8 m/s and rests within 1e-9 m (test).
- Friction: Coulomb with the stick rule, N (mu_dir(s) track(x) + static_excess e^(-(v/vs)^2))
  while sliding in direction s (mu_dir = mu +- asymmetry / 2, track(x) = 1 + A sin(2 pi x / L
  + phase)), and N (mu_dir track(x) + static_excess) holding a stuck rig. Where the velocity
  changes sign inside a step the zero is located by bisection on the step's fraction (each
  trial a Newmark step of that fraction, so the stop is the integrator's own), then the stick
  rule decides: stay stuck (v = 0, x held) while the spring and the hammer stay within the
  static limit, otherwise slide on the way the net force pushes. A stuck rig breaks away
  (from rest when the hammer starts, or later in the hit) where the net force leaves the
  static limit, that instant bisected within the step; stuck once the hammer is gone, it
  stays so (the record's rest).
- Hits: a Kelvin-Voigt hammer tip. A hammer of m_h (0.1-0.3 kg) strikes a rigid target
  through a linear tip spring k_t and dashpot c_t (damping ratio 0.05-0.2); its indentation
  is a damped sine in closed form, its force f = k_t d + c_t d' jumps to c_t V at the
  touch, and the contact ends exactly where f returns to zero (a closed-form root, before the
  tip is back at its undeformed length: the dashpot would pull). Contact 0.4-3 ms, the
  impact speed scaled so the peak is within 3 % of the level; onset anywhere between
  samples. The impulse is m_h times the hammer's velocity change (the rebound slower than
  the impact), and the force's running integral is closed form too.
- Acquisition: the sample rate drawn a session from 10 and 16.384 kHz. Each channel's input
  is averaged over cells of a sixteenth of a sample period (the force by its running
  impulse, the velocity by the change of position: both exact), through an analog 6th-order
  Chebyshev type II anti-alias filter (60 dB stopband from the Nyquist frequency) discretised
  by the bilinear transform prewarped to the stopband edge on that grid, the same on both
  channels, and read at the samples. The force channel: a charge amplifier's zero settling
  exponentially from an offset at each record's start (up to 0.2 N, time constant 2-20 s,
  drawn a session), white noise. The velocity channel: white noise and the floor's
  narrow-band vibration (white noise through a 2nd-order resonance, centre 8-40 Hz, Q 1-3,
  its RMS 0.2-0.35 of the white's, drawn a session). 24-bit rounding over +-10 kN and +-2 m/s.
- The vibrometer sees the rig's velocity plus a second structural mode's (m2 x2'' + c2 x2' +
  k2 x2 = f, driven by the hammer, uncoupled, exact by partial fractions of the pulse's
  complex exponentials), lagged in continuous time (v(t - lag)), plus its zero offset.
- Records of 12 s, the hit 0.4 s after the first sample. Starts as `bristle`: each hit of
  an isolated session from rest somewhere in the friction band (diagnosed with fitted
  starts), re-centred when the session hides direction-dependent friction; chained sessions
  start each hit where the one before came to rest.
"""

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numba
import numpy as np
import scipy.signal

from heldout.lab import Effects

MASS_KG, STIFFNESS_N_PER_M, DAMPING_N_S_PER_M = 10.391, 1982.0, 0.275
NORMAL_N = 0.680 * 9.81
RATES_HZ = (10_000.0, 16_384.0)
OVERSAMPLE = 16
"""Cells of the filter's grid per sample."""
CHEBY_ORDER, CHEBY_STOP_DB = 6, 60.0
PRETRIGGER_S = 0.4
DURATION_S = 12.0
FORCE_RANGE_N, VELOCITY_RANGE_M_S, BITS = 10_000.0, 2.0, 24
FINE_STEP_S = 0.5e-6
"""The Newmark step while the hammer force acts (at most; the contact is cut in equal steps)."""
COARSE_STEP_S = 1e-5
"""The Newmark step once the hammer is gone."""
HAMMER_KG = (0.1, 0.3)
TIP_DAMPING = (0.05, 0.2)
CONTACT_S = (0.4e-3, 3e-3)
ZERO_OFFSET_N = 0.2
ZERO_TIME_CONSTANT_S = (2.0, 20.0)
FLOOR_HZ, FLOOR_Q, FLOOR_SHARE = (8.0, 40.0), (1.0, 3.0), (0.2, 0.35)


@dataclass(frozen=True)
class Hammer:
    """A Kelvin-Voigt hammer tip striking a rigid target at a speed.

    The indentation d obeys m_h d'' + c_t d' + k_t d = 0, d(0) = 0, d'(0) = V: with
    omega^2 = k_t / m_h, a = zeta omega, w = omega sqrt(1 - zeta^2),
    d = V / w e^(-a u) sin(w u), and the force on the target
    f = k_t d + c_t d' = m_h V e^(-a u) (P sin(w u) + Q cos(w u)), P = (omega^2 - 2 a^2) / w,
    Q = 2 a, zero where tan(w u) = -Q / P.
    """

    mass_kg: float
    omega_rad_s: float
    """The tip's undamped angular frequency sqrt(k_t / m_h) [rad/s]."""
    zeta: float
    speed_m_s: float
    """The impact speed V [m/s]."""
    onset_s: float

    @property
    def stiffness_n_per_m(self) -> float:
        """k_t."""
        return self.mass_kg * self.omega_rad_s**2

    @property
    def damping_n_s_per_m(self) -> float:
        """c_t."""
        return 2.0 * self.mass_kg * self.zeta * self.omega_rad_s

    @property
    def decay(self) -> float:
        """a = zeta omega [1/s]."""
        return self.zeta * self.omega_rad_s

    @property
    def damped(self) -> float:
        """w = omega sqrt(1 - zeta^2) [rad/s]."""
        return self.omega_rad_s * math.sqrt(1.0 - self.zeta**2)

    @property
    def coefficients(self) -> tuple[float, float]:
        """(m_h V P, m_h V Q) [N]: f = e^(-a u) (first sin(w u) + second cos(w u))."""
        a, w = self.decay, self.damped
        scale = self.mass_kg * self.speed_m_s
        return scale * (self.omega_rad_s**2 - 2.0 * a * a) / w, scale * 2.0 * a

    @property
    def contact_s(self) -> float:
        """How long the tip pushes: the first zero of f after the touch [s]."""
        p, q = self.coefficients
        return (math.pi - math.atan2(q, p)) / self.damped

    @property
    def end_s(self) -> float:
        """When the force is over [s]."""
        return self.onset_s + self.contact_s

    def _unit_force(self, u: np.ndarray) -> np.ndarray:
        p, q = self.coefficients
        return np.exp(-self.decay * u) * (p * np.sin(self.damped * u) + q * np.cos(self.damped * u))

    def force(self, time_s: np.ndarray | float) -> np.ndarray:
        """The force at any times [N] (from the touch, inclusive, to the end)."""
        u = np.asarray(time_s, dtype=float) - self.onset_s
        inside = (u >= 0.0) & (u <= self.contact_s)
        return np.where(inside, self._unit_force(np.where(inside, u, 0.0)), 0.0)

    def force_at(self, time_s: float) -> float:
        """The force at one time [N]."""
        return float(self.force(time_s))

    def tip_speed(self, u: np.ndarray | float) -> np.ndarray:
        """d'(u) [m/s]: the hammer's speed into the target, u after the touch."""
        a, w = self.decay, self.damped
        u = np.asarray(u, dtype=float)
        return self.speed_m_s * np.exp(-a * u) * (np.cos(w * u) - a / w * np.sin(w * u))

    def impulse_until(self, time_s: np.ndarray | float) -> np.ndarray:
        """The running impulse m_h (V - d'(u)) [N s] (0 before the touch, the impulse after)."""
        u = np.clip(np.asarray(time_s, dtype=float) - self.onset_s, 0.0, self.contact_s)
        return self.mass_kg * (self.speed_m_s - self.tip_speed(u))

    @property
    def impulse_n_s(self) -> float:
        """m_h (V + |rebound speed|) [N s]."""
        return float(self.mass_kg * (self.speed_m_s - self.tip_speed(self.contact_s)))

    @property
    def peak_time_s(self) -> float:
        """Where f' = 0: tan(w u) = (w P - a Q) / (a P + w Q), after the touch [s]."""
        p, q = self.coefficients
        a, w = self.decay, self.damped
        return math.atan2(w * p - a * q, a * p + w * q) / w

    @property
    def peak_n(self) -> float:
        """The largest force [N]."""
        return float(self._unit_force(np.array(self.peak_time_s)))

    @property
    def exponentials(self) -> tuple[tuple[complex, complex], ...]:
        """The force while in contact as sum c e^(lam u): (c [N], lam [1/s]) pairs."""
        p, q = self.coefficients
        lam = complex(-self.decay, self.damped)
        c = complex(q, -p) / 2.0  # (q - i p) / 2 e^(lam u) + conjugate = e^(-a u)(p sin + q cos)
        return ((c, lam), (c.conjugate(), lam.conjugate()))


def hammer_for(level_n: float, mass_kg: float, zeta: float, contact_s: float, onset_s: float):
    """The hammer whose contact lasts contact_s and whose force peaks at level_n."""
    # the contact's angle w T = pi - atan2(Q, P) depends on zeta alone
    unit = Hammer(mass_kg, 1.0, zeta, 1.0, onset_s)
    omega = unit.contact_s / contact_s
    shaped = Hammer(mass_kg, omega, zeta, 1.0, onset_s)
    return Hammer(mass_kg, omega, zeta, level_n / shaped.peak_n, onset_s)


def random_hammer(rng: np.random.Generator, level_n: float, onset_s: float) -> Hammer:
    """A hammer of 0.1-0.3 kg, tip damping ratio 0.05-0.2, contact 0.4-3 ms (log-uniform),
    its peak within 3 % of a level."""
    low, high = CONTACT_S
    return hammer_for(
        level_n * rng.uniform(0.97, 1.03),
        rng.uniform(*HAMMER_KG),
        rng.uniform(*TIP_DAMPING),
        float(np.exp(rng.uniform(np.log(low), np.log(high)))),
        onset_s,
    )


# --- the rig: Newmark-beta with Newton and the stick rule --------------------------------

# parameters: m, c, k, k3, N, mu, asymmetry, static_excess, vs, A, L, phase
# hammer: onset, end, decay, damped, first, second


@numba.njit(cache=True)
def _push(hammer, t):
    u = t - hammer[0]
    if u < 0.0 or t > hammer[1]:
        return 0.0
    w = hammer[3] * u
    return math.exp(-hammer[2] * u) * (hammer[4] * math.sin(w) + hammer[5] * math.cos(w))


@numba.njit(cache=True)
def _track(p, x):
    """track(x) and its slope."""
    if p[9] == 0.0:
        return 1.0, 0.0
    phase = 2.0 * math.pi * x / p[10] + p[11]
    return 1.0 + p[9] * math.sin(phase), p[9] * 2.0 * math.pi / p[10] * math.cos(phase)


@numba.njit(cache=True)
def _limit(p, s, x):
    """The static friction holding a stuck rig pushed in direction s [N]."""
    track, _ = _track(p, x)
    return p[4] * ((p[5] + 0.5 * p[6] * s) * track + p[7])


@numba.njit(cache=True)
def _net(p, hammer, t, x):
    """Hammer minus spring: what friction must hold at rest [N]."""
    return _push(hammer, t) - p[2] * x - p[3] * x**3


@numba.njit(cache=True)
def _step(p, hammer, s, t, x, v, a, h):
    """One Newmark step (gamma 1/2, beta 1/4) of size h sliding in direction s, by Newton on
    the new displacement: (x, v, a) at t + h."""
    m, c, k, k3, normal = p[0], p[1], p[2], p[3], p[4]
    mu_dir = p[5] + 0.5 * p[6] * s
    force = _push(hammer, t + h)
    x1 = x + h * v + 0.25 * h * h * a
    v1, a1 = v, a
    for _ in range(50):
        a1 = 4.0 / (h * h) * (x1 - x - h * v) - a
        v1 = 2.0 / h * (x1 - x) - v
        track, slope = _track(p, x1)
        excess = p[7] * math.exp(-((v1 / p[8]) ** 2))
        friction = s * normal * (mu_dir * track + excess)
        residual = m * a1 + c * v1 + k * x1 + k3 * x1**3 + friction - force
        slope_x = k + 3.0 * k3 * x1 * x1 + s * normal * mu_dir * slope
        slope_v = c - s * normal * 2.0 * v1 / (p[8] * p[8]) * excess
        jacobian = 4.0 * m / (h * h) + 2.0 / h * slope_v + slope_x
        dx = -residual / jacobian
        x1 += dx
        if abs(dx) <= 1e-17 + 1e-15 * abs(x1 - x):
            break
    a1 = 4.0 / (h * h) * (x1 - x - h * v) - a
    v1 = 2.0 / h * (x1 - x) - v
    return x1, v1, a1


@numba.njit(cache=True)
def _slide_acceleration(p, hammer, s, t, x):
    """The acceleration of a rig starting to slide from rest in direction s [m/s^2]."""
    return (_net(p, hammer, t, x) - s * _limit(p, s, x)) / p[0]


@numba.njit(cache=True)
def _excess(p, hammer, t, x):
    """How far the net force on a stuck rig exceeds the static limit [N], and its direction."""
    net = _net(p, hammer, t, x)
    s = 1.0 if net >= 0.0 else -1.0
    return abs(net) - _limit(p, s, x), s


@numba.njit(cache=True)
def _run(p, hammer, x0, stop, fine, coarse):
    """The motion from rest at x0 from the hammer's touch to stop: nodes (t, x, v), their
    count, the rest time (inf if still moving) and the rest position."""
    onset, end = hammer[0], hammer[1]
    pieces = max(1, int(math.ceil((end - onset) / fine)))
    fine = (end - onset) / pieces
    size = pieces + int((stop - end) / coarse) + 20_000
    ts, xs, vs = np.empty(size), np.empty(size), np.empty(size)
    t, x, v, a = onset, x0, 0.0, 0.0
    ts[0], xs[0], vs[0] = t, x, v
    count = 1
    stuck, s = True, 0.0
    index = 0
    rest_s = math.inf
    while t < stop and count < size - 2:
        index += 1
        if index <= pieces:
            target = onset + index * fine if index < pieces else end
        else:
            target = min(end + (index - pieces) * coarse, stop)
        while t < target - 1e-13:
            if stuck:
                excess, s = _excess(p, hammer, t, x)
                if excess <= 0.0:
                    if t >= end:
                        # the hammer is gone and the spring cannot break the stick
                        rest_s = t
                        ts[count], xs[count], vs[count] = stop, x, 0.0
                        return ts, xs, vs, count + 1, rest_s, x
                    later, s_later = _excess(p, hammer, target, x)
                    if later <= 0.0:
                        t = target
                        break
                    lo, hi = t, target
                    for _ in range(80):
                        mid = 0.5 * (lo + hi)
                        if _excess(p, hammer, mid, x)[0] > 0.0:
                            hi = mid
                        else:
                            lo = mid
                        if hi - lo < 1e-15:
                            break
                    t = hi
                    s = _excess(p, hammer, t, x)[1]
                    ts[count], xs[count], vs[count] = t, x, 0.0
                    count += 1
                stuck = False
                v = 0.0
                a = _slide_acceleration(p, hammer, s, t, x)
                continue
            h = target - t
            x1, v1, a1 = _step(p, hammer, s, t, x, v, a, h)
            if s * v1 > 0.0:
                t, x, v, a = target, x1, v1, a1
                break
            # the velocity reaches zero inside the step: bisect the step's fraction
            lo, hi = 0.0, 1.0
            for _ in range(100):
                mid = 0.5 * (lo + hi)
                xm, vm, am = _step(p, hammer, s, t, x, v, a, mid * h)
                if s * vm > 0.0:
                    lo = mid
                else:
                    hi = mid
                if (hi - lo) * h < 1e-14:
                    break
            if hi * h < 1e-12:
                # the slide could not start: at rest where the step starts
                ts[count], xs[count], vs[count] = t, x, 0.0
                count += 1
                stuck, v, a = True, 0.0, 0.0
                excess, back = _excess(p, hammer, t, x)
                if excess > 0.0 and back != s:
                    # a reversal the step before ended a hair short of: the stick rule
                    # slides the rig back the way the net force pushes
                    continue
                # stuck for the rest of this step
                if t >= end:
                    rest_s = t
                    ts[count], xs[count], vs[count] = stop, x, 0.0
                    return ts, xs, vs, count + 1, rest_s, x
                t = target
                break
            x, vm, am = _step(p, hammer, s, t, x, v, a, hi * h)
            t = t + hi * h
            v, a, stuck = 0.0, 0.0, True
            if t >= target - 1e-13:
                t = target
            ts[count], xs[count], vs[count] = t, x, 0.0
            count += 1
        if t >= target - 1e-13 and ts[count - 1] < target - 1e-13:
            ts[count], xs[count], vs[count] = target, x, v
            count += 1
            t = target
    return ts, xs, vs, count, rest_s, x


@numba.njit(cache=True)
def _hermite(ts, xs, vs, count, queries, start):
    """Position and velocity at sorted query times: the cubic Hermite through the nodes'
    positions and velocities (start before the first node, the last node's after it)."""
    n = queries.size
    x_out, v_out = np.empty(n), np.empty(n)
    j = 0
    for i in range(n):
        q = queries[i]
        if q <= ts[0]:
            x_out[i], v_out[i] = start, 0.0
            continue
        if q >= ts[count - 1]:
            x_out[i], v_out[i] = xs[count - 1], vs[count - 1]
            continue
        while ts[j + 1] < q:
            j += 1
        h = ts[j + 1] - ts[j]
        if h <= 0.0:
            x_out[i], v_out[i] = xs[j + 1], vs[j + 1]
            continue
        r = (q - ts[j]) / h
        x0, x1, m0, m1 = xs[j], xs[j + 1], vs[j] * h, vs[j + 1] * h
        r2, r3 = r * r, r * r * r
        x_out[i] = (
            (2 * r3 - 3 * r2 + 1) * x0
            + (r3 - 2 * r2 + r) * m0
            + (-2 * r3 + 3 * r2) * x1
            + (r3 - r2) * m1
        )
        v_out[i] = (
            (6 * r2 - 6 * r) * x0
            + (3 * r2 - 4 * r + 1) * m0
            + (-6 * r2 + 6 * r) * x1
            + (3 * r2 - 2 * r) * m1
        ) / h
    return x_out, v_out


@dataclass(frozen=True)
class Rig:
    """The plant with its hidden mechanical effects, and the friction at one hit's mu."""

    mu: float
    effects: Effects

    @property
    def parameters(self) -> np.ndarray:
        """The integrator's parameter vector."""
        e = self.effects
        return np.array(
            [
                MASS_KG,
                DAMPING_N_S_PER_M + e.added_damping_n_s_per_m,
                STIFFNESS_N_PER_M,
                e.cubic_n_per_m3,
                NORMAL_N,
                self.mu,
                e.asymmetry,
                e.static_excess,
                e.stribeck_speed_m_s,
                e.track_amplitude,
                e.track_wavelength_m,
                e.track_phase,
            ]
        )

    def half_band_m(self) -> float:
        """The friction band's half width where it is narrowest (track at its lowest) [m]."""
        e = self.effects
        lowest = min(self.mu + 0.5 * e.asymmetry * s for s in (1.0, -1.0))
        return NORMAL_N * (lowest * (1.0 - e.track_amplitude) + e.static_excess) / STIFFNESS_N_PER_M


@dataclass(frozen=True)
class Motion:
    """A hit's motion: Newmark nodes, where and when it came to rest."""

    start_m: float
    times_s: np.ndarray
    positions_m: np.ndarray
    velocities_m_s: np.ndarray
    rest_s: float
    """When the rig stuck for good (inf if still moving at the end) [s]."""
    end_m: float
    """Where it was at the end (its rest) [m]."""

    def state(self, time_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(position [m], velocity [m/s]) at sorted times, at rest before the touch."""
        t = np.asarray(time_s, dtype=float)
        return _hermite(
            self.times_s,
            self.positions_m,
            self.velocities_m_s,
            self.times_s.size,
            np.ascontiguousarray(t.ravel()),
            self.start_m,
        )

    @property
    def rest_m(self) -> float:
        """Where the rig rests at the end [m]."""
        return self.end_m


def move(
    rig: Rig,
    hammer: Hammer,
    start_m: float,
    stop_s: float,
    fine_s: float = FINE_STEP_S,
    coarse_s: float = COARSE_STEP_S,
) -> Motion:
    """The motion from rest at start_m, struck at the hammer's onset, to stop_s (module doc)."""
    first, second = hammer.coefficients
    ts, xs, vs, count, rest_s, end = _run(
        rig.parameters,
        np.array([hammer.onset_s, hammer.end_s, hammer.decay, hammer.damped, first, second]),
        float(start_m),
        float(stop_s),
        float(fine_s),
        float(coarse_s),
    )
    return Motion(start_m, ts[:count].copy(), xs[:count].copy(), vs[:count].copy(), rest_s, end)


def in_band(rig: Rig, rng: np.random.Generator) -> float:
    """A rest position drawn uniformly within 95 % of the friction band's half width [m]."""
    return float(rng.uniform(-0.95, 0.95) * rig.half_band_m())


# --- the second mode ------------------------------------------------------------------


def mode_response(
    effects: Effects, hammer: Hammer, time_s: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The second mode's (displacement [m], velocity [m/s]) under the hammer at any times.

    In contact the force is sum c e^(lam u); each exponential input e^(lam u) H(u) into
    1 / D(s), D = m2 s^2 + c2 s + k2, gives e^(lam u) / D(lam) + sum_i e^(p_i u) / (D'(p_i)
    (p_i - lam)) (partial fractions). After the contact the mode rings freely from its state
    there, x = 2 Re(B e^(p tau)).
    """
    t = np.asarray(time_s, dtype=float)
    if not effects.mode_hz:
        return np.zeros(t.shape), np.zeros(t.shape)
    omega = 2.0 * math.pi * effects.mode_hz
    zeta, m2 = effects.mode_damping_ratio, effects.mode_mass_kg
    pole = omega * complex(-zeta, math.sqrt(1.0 - zeta * zeta))
    poles = (pole, pole.conjugate())

    def forced(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        x = np.zeros(u.shape, dtype=complex)
        v = np.zeros(u.shape, dtype=complex)
        for c, lam in hammer.exponentials:
            term = c / (m2 * (lam - poles[0]) * (lam - poles[1])) * np.exp(lam * u)
            x, v = x + term, v + lam * term
            for p, q in (poles, poles[::-1]):
                term = c / (m2 * (p - q) * (p - lam)) * np.exp(p * u)
                x, v = x + term, v + p * term
        return x.real, v.real

    x, v = np.zeros(t.shape), np.zeros(t.shape)
    u = t - hammer.onset_s
    inside = (u >= 0.0) & (u < hammer.contact_s)
    x[inside], v[inside] = forced(u[inside])
    x_end, v_end = (float(value[0]) for value in forced(np.array([hammer.contact_s])))
    beta = (pole.real * x_end / 2.0 - v_end / 2.0) / pole.imag
    big_b = complex(x_end / 2.0, beta)
    after = u >= hammer.contact_s
    ring = big_b * np.exp(pole * (u[after] - hammer.contact_s))
    x[after], v[after] = 2.0 * ring.real, 2.0 * (pole * ring).real
    return x, v


def mode_ring_s(effects: Effects) -> float:
    """How long the second mode rings above 1e-9 of its start (0 without one) [s]."""
    if not effects.mode_hz:
        return 0.0
    return math.log(1e9) / (effects.mode_damping_ratio * 2.0 * math.pi * effects.mode_hz)


# --- acquisition ------------------------------------------------------------------------


def chebyshev(rate_hz: float, edge_hz: float | None = None) -> tuple[np.ndarray, np.ndarray, float]:
    """The analog anti-alias prototype: 6th-order Chebyshev II, 60 dB from edge_hz (the
    Nyquist frequency by default), as (zeros, poles [rad/s], gain), DC gain 1."""
    edge = rate_hz / 2.0 if edge_hz is None else edge_hz
    zeros, poles, gain = scipy.signal.cheby2(
        CHEBY_ORDER, CHEBY_STOP_DB, 2.0 * math.pi * edge, analog=True, output='zpk'
    )
    dc = gain * np.prod(-zeros) / np.prod(-poles)
    return zeros, poles, float(gain / dc.real)


def tustin(rate_hz: float) -> np.ndarray:
    """The anti-alias filter on the fine grid (OVERSAMPLE x the rate) by the bilinear
    transform, prewarped so the stopband edge (the Nyquist frequency) lands where it is,
    its DC gain set to 1 exactly: second-order sections."""
    fine = rate_hz * OVERSAMPLE
    edge = rate_hz / 2.0
    warped = fine / math.pi * math.tan(math.pi * edge / fine)
    zeros, poles, gain = scipy.signal.bilinear_zpk(*chebyshev(rate_hz, warped), fine)
    dc = gain * np.prod(1.0 - zeros) / np.prod(1.0 - poles)
    return scipy.signal.zpk2sos(zeros, poles, gain / dc.real)


def cell_means(running: np.ndarray, cell_s: float) -> np.ndarray:
    """A signal's mean over each cell from its running integral at the cells' edges."""
    return np.diff(running) / cell_s


def floor_noise(
    rng: np.random.Generator, samples: int, rate_hz: float, centre_hz: float, q: float, std: float
) -> np.ndarray:
    """White noise through the resonance (omega0 / Q) s / (s^2 + (omega0 / Q) s + omega0^2)
    (bilinear, prewarped to its centre), scaled to a stationary std, started stationary."""
    omega = 2.0 * math.pi * centre_hz
    b, a = scipy.signal.bilinear([omega / q, 0.0], [1.0, omega / q, omega * omega], rate_hz)
    impulse = scipy.signal.lfilter(b, a, np.r_[1.0, np.zeros(round(4.0 * rate_hz))])
    settle = round(2.0 * rate_hz)
    out = scipy.signal.lfilter(b, a, rng.normal(size=samples + settle))[settle:]
    return std * out / math.sqrt(np.sum(impulse**2))


def quantised(values: np.ndarray, full_scale: float) -> np.ndarray:
    """Rounded to a BITS converter's step over +-full_scale, clipped there."""
    step = 2.0 * full_scale / 2**BITS
    return np.clip(np.round(values / step) * step, -full_scale, full_scale)


@dataclass(frozen=True)
class Chain:
    """One session's acquisition (drawn a session)."""

    rate_hz: float
    zero_n: float
    """The charge amplifier's zero at each record's start [N]."""
    zero_time_constant_s: float
    floor_hz: float
    floor_q: float
    floor_share: float
    """The floor vibration's RMS over the velocity's white noise."""

    def filtered(self, running, samples: int, active: tuple[float, float]) -> np.ndarray:
        """A channel's samples: its input's running integral (a function of time, zero before
        active[0], its input zero after active[1]) -> cell means on the fine grid -> the
        discretised anti-alias filter -> every OVERSAMPLE-th value."""
        cell = 1.0 / (self.rate_hz * OVERSAMPLE)
        first = max(0, math.floor(active[0] * self.rate_hz) - 2)
        last = min(samples, math.ceil(active[1] * self.rate_hz) + 1)
        centres = (first * OVERSAMPLE + np.arange((last - first) * OVERSAMPLE)) * cell
        edges = np.r_[centres - 0.5 * cell, centres[-1] + 0.5 * cell]
        values = scipy.signal.sosfilt(tustin(self.rate_hz), cell_means(running(edges), cell))
        out = np.zeros(samples)
        out[first:last] = values[::OVERSAMPLE]
        return out

    def zero(self, samples: int) -> np.ndarray:
        """The charge amplifier's settling zero at each sample [N]."""
        return self.zero_n * np.exp(-np.arange(samples) / self.rate_hz / self.zero_time_constant_s)


@dataclass(frozen=True)
class NewmarkRecord:
    """One hit's record as the DAQ delivered it, and its truth."""

    force_n: np.ndarray
    velocity_m_s: np.ndarray
    sample_rate_hz: float
    hammer: Hammer
    """The pulse, its onset on the record's clock."""
    mu: float
    start_m: float
    rest_m: float
    rest_s: float
    """When the rig stuck for good [s] (inf if still moving at the record's end)."""
    chain: Chain
    source: str = ''

    @property
    def pulse(self) -> Hammer:
        """The hit (as other worlds' records name it)."""
        return self.hammer


@dataclass(frozen=True)
class NewmarkWorld:
    """The `newmark` world (module doc): its noise levels and record length."""

    name: str = 'newmark'
    sensor: str = 'velocity'
    """What the response sensor measures (as `lab.World.sensor`): a vibrometer."""
    force_white_n: float = 0.15
    velocity_white_m_s: float = 1.0e-4
    duration_s: float = DURATION_S

    def record(
        self,
        effects: Effects,
        mu: float,
        hammer: Hammer,
        start_m: float,
        chain: Chain,
        rng: np.random.Generator,
        source: str = '',
    ) -> NewmarkRecord:
        """One hit's record from rest at start_m."""
        motion = move(Rig(mu, effects), hammer, start_m, self.duration_s)
        lag = effects.lag_s

        def travelled(t: np.ndarray) -> np.ndarray:
            """The running integral of what the vibrometer sees: rig plus mode, lagged."""
            x = motion.state(t - lag)[0] - start_m
            if effects.mode_hz:
                x = x + mode_response(effects, hammer, t - lag)[0]
            return x

        samples = round(self.duration_s * chain.rate_hz)
        still = motion.rest_s if math.isfinite(motion.rest_s) else self.duration_s
        moving = max(still, hammer.end_s + mode_ring_s(effects)) + lag + 0.05
        force = chain.filtered(hammer.impulse_until, samples, (hammer.onset_s, hammer.end_s + 0.05))
        force += chain.zero(samples) + rng.normal(0.0, self.force_white_n, samples)
        speed = chain.filtered(travelled, samples, (hammer.onset_s, min(self.duration_s, moving)))
        speed += effects.velocity_offset_m_s + rng.normal(0.0, self.velocity_white_m_s, samples)
        speed += floor_noise(
            rng,
            samples,
            chain.rate_hz,
            chain.floor_hz,
            chain.floor_q,
            chain.floor_share * self.velocity_white_m_s,
        )
        return NewmarkRecord(
            quantised(force, FORCE_RANGE_N),
            quantised(speed, VELOCITY_RANGE_M_S),
            chain.rate_hz,
            hammer,
            mu,
            start_m,
            motion.rest_m,
            motion.rest_s,
            chain,
            source,
        )

    def chain(self, rng: np.random.Generator) -> Chain:
        """A session's acquisition, drawn."""
        low, high = ZERO_TIME_CONSTANT_S
        return Chain(
            float(rng.choice(RATES_HZ)),
            float(rng.uniform(-1.0, 1.0) * ZERO_OFFSET_N),
            float(np.exp(rng.uniform(np.log(low), np.log(high)))),
            float(np.exp(rng.uniform(*np.log(FLOOR_HZ)))),
            float(rng.uniform(*FLOOR_Q)),
            float(rng.uniform(*FLOOR_SHARE)),
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
    ) -> list[NewmarkRecord]:
        """One record a level; mu changes by effects.mu_step a hit; the chain drawn a session.

        chained: the first hit from rest at the centre, each later one from where the one
        before came to rest; centred: every hit from rest at the centre; otherwise each from
        rest somewhere in the friction band.
        """
        chain = self.chain(rng)
        records, start = [], 0.0
        for index, level in enumerate(levels_n):
            hit_mu = mu * (1.0 + effects.mu_step) ** index
            if not (chained or centred):
                start = in_band(Rig(hit_mu, effects), rng)
            onset = PRETRIGGER_S + rng.uniform(0.0, 1.0) / chain.rate_hz
            made = self.record(
                effects,
                hit_mu,
                random_hammer(rng, float(level), onset),
                start,
                chain,
                rng,
                f'{self.name} hit {index}',
            )
            records.append(made)
            if chained:
                start = made.rest_m
        return records


NEWMARK = NewmarkWorld()
"""The `newmark` world (module doc)."""
