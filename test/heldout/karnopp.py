"""An eighth held-out world, `karnopp`: a controls engineer's simulator, one explicit loop.

Written when `analytic` was about to become a tuning world, its physics checked
against lab's event-located DOP853 (`heldout.plant.solve_events`, in its tests only) before
any diagnosis ran on it (never tuned on). It shares only `lab.Effects` (the effect vocabulary
and its parameters) with the other worlds and makes other choices at every stage:

- Integrator: fixed-step classical RK4 compiled by numba, one loop carrying the rig, the
  hammer and the second mode together: steps of a third of the acquisition grid's cell
  (about 0.8 us) while the hammer is near or in contact, one cell (about 2.5 us) after it.
- Friction: Karnopp's stick-slip model (Karnopp 1985). Inside a velocity window
  |v| < `WINDOW_M_S` (1e-6 m/s) friction balances the applied force (hammer, spring and
  damper) up to the static limit N (mu_dir track(x) + static_excess), so the rig sticks,
  or stops at that limit and the rig breaks away; outside it the kinetic law
  sign(v) N (mu_dir track(x) + static_excess e^(-(v/vs)^2)) acts, mu_dir = mu +- asymmetry / 2
  (asymmetry: mu in +x minus mu in -x), track(x) = 1 + A sin(2 pi x / L + phase). After each
  step a rig inside the window whose applied force the static limit holds is set exactly to
  rest (v = 0, x held), so a stuck rig stays where it is. The window is wider than the
  velocity a step can change by at a stop (the static limit over the mass times the step),
  so every stop falls into it. The stop is the window's, not located: the friction turns
  over up to dv / |a| early, an error proportional to dv (first order at stops).
- Hits: a Hunt-Crossley hammer tip striking the moving rig. A hammer of m_h (0.1-0.3 kg)
  meets the rig at speed V0 and pushes with F = K d^1.5 (1 + 1.5 (1 - e) d' / V0) while
  its indentation d = x_hammer - x_rig is positive (e the restitution, 0.5-0.9), the hammer,
  the rig and the mode stepped together; the contact ends where d returns to zero and the
  hammer is withdrawn. K and V0 are solved from the dimensionless rigid-target equation
  u'' = -u^1.5 (1 + 1.5 (1 - e) u') (one RK4 run a hit) with the two bodies' reduced mass,
  so the contact lasts the drawn 0.8-3 ms (log-uniform) and the peak is the drawn level
  (within 2.5 % of the paper's) to the rig's spring and friction during the contact.
  The force channel measures the contact force (a load cell of no mass of its own).
- Acquisition: 10 or 20.48 kHz a session. Both channels through the same 4th-order analog
  Bessel anti-alias filter (-3 dB at 0.4 of the rate), simulated exactly for an input
  linear between points of a fine grid (`scipy.signal.cont2discrete`, first-order hold),
  the force on the integrator's contact steps, the velocity on a grid of about 2.5 us. The
  vibrometer's decoder: a 1st-order tracking low-pass before the Bessel (corner 2-5 kHz at
  20.48 kHz, 4-5 kHz at 10 kHz), its stated delay 1 / (2 pi f) taken off as a vibrometer's
  acquisition does. A multiplexed ADC reads the velocity 1-5 us after the force (a real,
  unstated skew). The force: white noise 0.2 N and a constant zero offset up to 0.2 N. The
  velocity: white noise 1e-4 m/s and a random walk (Brownian, 1/f^2) from zero at the
  record's start, its RMS over the record 0.1-0.3 of the white's (drawn a session). 16-bit
  rounding over +-2 kN and +-0.5 m/s (steps 0.06 N and 1.5e-5 m/s, their rounding noise 0.09
  and 0.04 of the white).
- The vibrometer sees the rig's velocity plus a second mode's (m2 x2'' + c2 x2' + k2 x2 = F,
  driven by the contact force, uncoupled, stepped in the same loop), lagged in continuous
  time (v(t - lag), cubic Hermite between steps from the velocity and the acceleration),
  plus its zero offset.
- Records of 12 s, the hit 0.4 s after the first sample, its onset anywhere between samples.
  Starts: each hit of an isolated session from rest somewhere within 90 % of the friction
  band's half width (diagnosed with fitted starts), at the centre when the session is
  re-centred (`re_centred`: it hides direction-dependent friction); chained sessions start
  the first hit at the centre and each later one where the one before came to rest.
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
RATES_HZ = (10_000.0, 20_480.0)
GRID_HZ = 400_000.0
"""The acquisition grid's rate, rounded to a whole number of cells a sample."""
SUBSTEPS = 3
"""RK4 steps a grid cell while the hammer is near or in contact."""
WINDOW_M_S = 1e-6
"""Karnopp's velocity window dv [m/s]."""
BESSEL_ORDER, BESSEL_SHARE = 4, 0.4
"""The anti-alias filter's order and -3 dB frequency over the sample rate."""
TRACKING_HZ = {10_000.0: (4_000.0, 5_000.0), 20_480.0: (2_000.0, 5_000.0)}
"""The vibrometer decoder's tracking corner's range at each rate [Hz]."""
SKEW_S = (1e-6, 5e-6)
PRETRIGGER_S = 0.4
DURATION_S = 12.0
FORCE_RANGE_N, VELOCITY_RANGE_M_S, BITS = 2_000.0, 0.5, 16
HAMMER_KG = (0.1, 0.3)
RESTITUTION = (0.5, 0.9)
CONTACT_S = (0.8e-3, 3e-3)
PEAK_SCATTER = 0.025
"""A hit's drawn peak lies within this share of its level."""
ZERO_OFFSET_N = 0.2
DRIFT_SHARE = (0.1, 0.3)
"""The velocity's random walk: its RMS over a record over the white noise's."""
FORCE_TAIL_S = 5e-3
"""How long the force channel's filter is run on after the contact (its response is then
e^-100 of its peak)."""
UNIT_STEP = 1e-4
"""The dimensionless rigid-target run's step."""


# --- the hammer -------------------------------------------------------------------------


@numba.njit(cache=True)
def _unit_contact(damping: float) -> tuple[float, float]:
    """RK4 of u'' = -u^1.5 (1 + damping u'), u(0) = 0, u'(0) = 1: (the contact's end, where u
    returns to zero (interpolated), the largest u^1.5 (1 + damping u'))."""
    u, w, s, peak = 0.0, 1.0, 0.0, 0.0
    h = UNIT_STEP
    while True:
        k1u, k1w = w, -(max(u, 0.0) ** 1.5) * (1.0 + damping * w)
        u2, w2 = u + 0.5 * h * k1u, w + 0.5 * h * k1w
        k2u, k2w = w2, -(max(u2, 0.0) ** 1.5) * (1.0 + damping * w2)
        u3, w3 = u + 0.5 * h * k2u, w + 0.5 * h * k2w
        k3u, k3w = w3, -(max(u3, 0.0) ** 1.5) * (1.0 + damping * w3)
        u4, w4 = u + h * k3u, w + h * k3w
        k4u, k4w = w4, -(max(u4, 0.0) ** 1.5) * (1.0 + damping * w4)
        u_next = u + h / 6.0 * (k1u + 2.0 * k2u + 2.0 * k3u + k4u)
        w_next = w + h / 6.0 * (k1w + 2.0 * k2w + 2.0 * k3w + k4w)
        if u_next <= 0.0:
            return s + h * u / (u - u_next), peak
        u, w, s = u_next, w_next, s + h
        peak = max(peak, u**1.5 * (1.0 + damping * w))


@dataclass(frozen=True)
class Hammer:
    """A Hunt-Crossley hammer tip: F = K d^1.5 (1 + 1.5 (1 - e) d' / V0) for d > 0.

    Designed on a rigid target of the hammer and rig's reduced mass m_r: in u = d / D,
    s = t V0 / D with D = (m_r V0^2 / K)^(2/5) the contact is u'' = -u^1.5 (1 + 1.5 (1 - e) u'),
    which depends on e alone; its end s_c and peak phi give the contact time D s_c / V0 and the
    peak K D^1.5 phi.
    """

    mass_kg: float
    stiffness_n_per_m1_5: float
    """K [N/m^1.5]."""
    restitution: float
    speed_m_s: float
    """The impact speed V0 [m/s]."""
    onset_s: float

    @property
    def reduced_kg(self) -> float:
        """The hammer and rig's reduced mass m_h m / (m_h + m) [kg]."""
        return self.mass_kg * MASS_KG / (self.mass_kg + MASS_KG)

    @property
    def damping(self) -> float:
        """1.5 (1 - e): the dimensionless Hunt-Crossley damping."""
        return 1.5 * (1.0 - self.restitution)

    @property
    def scale_m(self) -> float:
        """D = (m_r V0^2 / K)^(2/5) [m]."""
        return (self.reduced_kg * self.speed_m_s**2 / self.stiffness_n_per_m1_5) ** 0.4

    @property
    def contact_s(self) -> float:
        """How long the tip pushes on a rigid target of the reduced mass [s]."""
        return self.scale_m / self.speed_m_s * _unit_contact(self.damping)[0]

    @property
    def peak_n(self) -> float:
        """The largest force on a rigid target of the reduced mass [N]."""
        return self.stiffness_n_per_m1_5 * self.scale_m**1.5 * _unit_contact(self.damping)[1]

    @property
    def parameters(self) -> np.ndarray:
        """The loop's hammer vector: m_h, K, 1.5 (1 - e) / V0, V0, onset."""
        return np.array(
            [
                self.mass_kg,
                self.stiffness_n_per_m1_5,
                self.damping / self.speed_m_s,
                self.speed_m_s,
                self.onset_s,
            ]
        )


def hammer_for(
    peak_n: float, mass_kg: float, restitution: float, contact_s: float, onset_s: float
) -> Hammer:
    """The hammer whose contact on a rigid target of the reduced mass lasts contact_s and
    peaks at peak_n: V0 = F T / (m_r s_c phi), K = m_r V0^(-1/2) (s_c / T)^(5/2)."""
    end, phi = _unit_contact(1.5 * (1.0 - restitution))
    reduced = mass_kg * MASS_KG / (mass_kg + MASS_KG)
    speed = peak_n * contact_s / (reduced * end * phi)
    stiffness = reduced * speed**-0.5 * (end / contact_s) ** 2.5
    return Hammer(mass_kg, stiffness, restitution, speed, onset_s)


def random_hammer(rng: np.random.Generator, level_n: float, onset_s: float) -> Hammer:
    """A hammer of 0.1-0.3 kg, restitution 0.5-0.9, contact 0.8-3 ms (log-uniform), its
    peak within PEAK_SCATTER of a level."""
    low, high = CONTACT_S
    return hammer_for(
        level_n * rng.uniform(1.0 - PEAK_SCATTER, 1.0 + PEAK_SCATTER),
        rng.uniform(*HAMMER_KG),
        rng.uniform(*RESTITUTION),
        float(np.exp(rng.uniform(math.log(low), math.log(high)))),
        onset_s,
    )


# --- the loop: rig, hammer and mode by RK4, Karnopp friction ----------------------------

# rig: m, c, k, k3, N, mu, asymmetry, static_excess, vs, A, L, phase, dv
# mode: m2, c2, k2 (m2 = 0: none)
# hammer: m_h, K, 1.5 (1 - e) / V0, V0, onset


@numba.njit(cache=True, inline='always')
def _track(p, x):
    if p[9] == 0.0:
        return 1.0
    return 1.0 + p[9] * math.sin(2.0 * math.pi * x / p[10] + p[11])


@numba.njit(cache=True, inline='always')
def _static(p, s, x):
    """The static limit against a push in direction s [N]."""
    return p[4] * ((p[5] + 0.5 * p[6] * s) * _track(p, x) + p[7])


@numba.njit(cache=True, inline='always')
def _kinetic(p, s, v, x):
    """The kinetic friction's size sliding in direction s at velocity v [N]."""
    excess = p[7] * math.exp(-((v / p[8]) ** 2)) if p[7] != 0.0 else 0.0
    return p[4] * ((p[5] + 0.5 * p[6] * s) * _track(p, x) + excess)


@numba.njit(cache=True, inline='always')
def _contact(hammer, x, v, xh, vh):
    """The Hunt-Crossley force [N] (zero while the indentation is not positive)."""
    d = xh - x
    if d <= 0.0:
        return 0.0
    return max(hammer[1] * d**1.5 * (1.0 + hammer[2] * (vh - v)), 0.0)


@numba.njit(cache=True, inline='always')
def _rig_acceleration(p, x, v, push):
    """Karnopp: inside the window friction balances the applied force up to the static
    limit; outside it the kinetic law [m/s^2]."""
    applied = push - p[1] * v - p[2] * x - p[3] * x * x * x
    if abs(v) < p[12]:
        s = 1.0 if applied >= 0.0 else -1.0
        limit = _static(p, s, x)
        if abs(applied) <= limit:
            return 0.0
        return (applied - s * limit) / p[0]
    s = 1.0 if v > 0.0 else -1.0
    return (applied - s * _kinetic(p, s, v, x)) / p[0]


@numba.njit(cache=True, inline='always')
def _derivatives(p, mode, hammer, on, y, out):
    """d/dt of (x, v, x_hammer, v_hammer, x2, v2); returns the contact force [N]."""
    push = _contact(hammer, y[0], y[1], y[2], y[3]) if on else 0.0
    out[0] = y[1]
    out[1] = _rig_acceleration(p, y[0], y[1], push)
    out[2] = y[3]
    out[3] = -push / hammer[0] if on else 0.0
    out[4] = y[5]
    out[5] = (push - mode[1] * y[5] - mode[2] * y[4]) / mode[0] if mode[0] > 0.0 else 0.0
    return push


@numba.njit(cache=True, inline='always')
def _rk4(p, mode, hammer, on, y, h, k1, k2, k3, k4, tmp):
    """One classical RK4 step of size h, in place."""
    _derivatives(p, mode, hammer, on, y, k1)
    for i in range(6):
        tmp[i] = y[i] + 0.5 * h * k1[i]
    _derivatives(p, mode, hammer, on, tmp, k2)
    for i in range(6):
        tmp[i] = y[i] + 0.5 * h * k2[i]
    _derivatives(p, mode, hammer, on, tmp, k3)
    for i in range(6):
        tmp[i] = y[i] + h * k3[i]
    _derivatives(p, mode, hammer, on, tmp, k4)
    for i in range(6):
        y[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])


@numba.njit(cache=True, inline='always')
def _held(p, hammer, on, y):
    """Whether the rig is inside the window with its applied force within the static limit
    (then it is set exactly to rest)."""
    if abs(y[1]) >= p[12]:
        return False
    push = _contact(hammer, y[0], 0.0, y[2], y[3]) if on else 0.0
    applied = push - p[2] * y[0] - p[3] * y[0] * y[0] * y[0]
    s = 1.0 if applied >= 0.0 else -1.0
    return abs(applied) <= _static(p, s, y[0])


@numba.njit(cache=True)
def _run(
    p,
    mode,
    hammer,
    start_m,
    cell_s,
    substeps,
    first,
    last,
    shift,
    fraction,
    ad,
    bd,
    cd,
    dd,
    cells,
    samples,
    keep,
    capacity,
    traces,
):
    """The rig, hammer and mode from the grid node `first` (at rest at start_m, the hammer
    approaching at V0) to grid node `last`, and the velocity channel streamed on the way.

    Grid node i is at i cell_s on the record's clock. The velocity channel's node j, read at
    j cell_s + skew, is what the vibrometer saw a fixed time earlier or later: the cubic
    Hermite between the loop's nodes j + shift and j + shift + 1 at `fraction`, through the
    first-order-hold state space (ad, bd, cd, dd); its every `cells`-th output is a sample.
    Returns (velocity samples, the contact force at each step from `first` while the hammer
    is near (times first cell_s + k cell_s / substeps; up to `capacity`), their count, the
    hammer's final velocity, the rest time (inf while moving), the position at the end, and
    every `keep`-th node's (t, x, v, x2, v2) (keep 0: none; up to `traces`) with their count).
    """
    out = np.zeros(samples)
    forces = np.zeros(capacity)
    trace = np.zeros((traces, 5))
    y = np.array([start_m, 0.0, 0.0, hammer[3], 0.0, 0.0])
    t = first * cell_s
    y[2] = start_m - hammer[3] * (hammer[4] - t)
    k1, k2, k3, k4 = np.zeros(6), np.zeros(6), np.zeros(6), np.zeros(6)
    tmp, rates = np.zeros(6), np.zeros(6)
    on, touched = True, False
    stuck, stuck_since = True, t
    state, scratch = np.zeros(ad.shape[0]), np.zeros(ad.shape[0])
    count, traced = 0, 0
    forces[count] = 0.0
    count += 1
    ring = mode[0] > 0.0
    omega2 = math.sqrt(mode[2] / mode[0]) if ring else 0.0
    speed, slope = 0.0, 0.0
    final_hammer = hammer[3]
    i = first
    while i < last:
        if keep > 0 and (i - first) % keep == 0 and traced < traces:
            trace[traced, 0], trace[traced, 1], trace[traced, 2] = t, y[0], y[1]
            trace[traced, 3], trace[traced, 4] = y[4], y[5]
            traced += 1
        if on:
            h = cell_s / substeps
            for k in range(substeps):
                _rk4(p, mode, hammer, on, y, h, k1, k2, k3, k4, tmp)
                if y[2] - y[0] > 0.0:
                    touched = True
                elif touched:
                    on = False
                if _held(p, hammer, on, y):
                    y[1] = 0.0
                    if not stuck:
                        stuck, stuck_since = True, (i + (k + 1.0) / substeps) * cell_s
                else:
                    stuck = False
                push = _contact(hammer, y[0], y[1], y[2], y[3]) if on else 0.0
                if count < capacity:
                    forces[count] = push
                    count += 1
            final_hammer = y[3]
        else:
            _rk4(p, mode, hammer, on, y, cell_s, k1, k2, k3, k4, tmp)
            if _held(p, hammer, on, y):
                y[1] = 0.0
                if not stuck:
                    stuck, stuck_since = True, (i + 1.0) * cell_s
            else:
                stuck = False
        i += 1
        t = i * cell_s
        _derivatives(p, mode, hammer, on, y, rates)
        new_speed, new_slope = y[1] + y[5], rates[1] + rates[5]
        j = i - 1 - shift
        if j >= 0:
            r = fraction
            r2, r3 = r * r, r * r * r
            u = (
                (2.0 * r3 - 3.0 * r2 + 1.0) * speed
                + (r3 - 2.0 * r2 + r) * cell_s * slope
                + (-2.0 * r3 + 3.0 * r2) * new_speed
                + (r3 - r2) * cell_s * new_slope
            )
            if j % cells == 0 and j // cells < samples:
                value = dd[0] * u
                for a in range(state.size):
                    value += cd[a] * state[a]
                out[j // cells] = value
            for a in range(state.size):
                scratch[a] = bd[a] * u
                for b in range(state.size):
                    scratch[a] += ad[a, b] * state[b]
            state, scratch = scratch, state
        speed, slope = new_speed, new_slope
        still = not ring or math.hypot(y[5], omega2 * y[4]) < 1e-13
        if stuck and not on and still and np.abs(state).max() < 1e-16:
            break
    return (
        out,
        forces,
        count,
        final_hammer,
        stuck_since if stuck else math.inf,
        y[0],
        trace,
        traced,
    )


@numba.njit(cache=True)
def _filtered(ad, bd, cd, dd, u):
    """A first-order-hold state space run over inputs from rest."""
    out = np.empty(u.size)
    state, scratch = np.zeros(ad.shape[0]), np.zeros(ad.shape[0])
    for k in range(u.size):
        value = dd[0] * u[k]
        for a in range(state.size):
            value += cd[a] * state[a]
        out[k] = value
        for a in range(state.size):
            scratch[a] = bd[a] * u[k]
            for b in range(state.size):
                scratch[a] += ad[a, b] * state[b]
        state, scratch = scratch, state
    return out


# --- the rig and its hits -------------------------------------------------------------


@dataclass(frozen=True)
class Rig:
    """The plant with its hidden mechanical effects, and the friction at one hit's mu."""

    mu: float
    effects: Effects
    window_m_s: float = WINDOW_M_S
    """Karnopp's velocity window dv [m/s]."""

    @property
    def parameters(self) -> np.ndarray:
        """The loop's rig vector."""
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
                self.window_m_s,
            ]
        )

    @property
    def mode(self) -> np.ndarray:
        """The loop's mode vector m2, c2, k2 (zeros without a mode)."""
        e = self.effects
        if not e.mode_hz:
            return np.zeros(3)
        omega = 2.0 * math.pi * e.mode_hz
        return np.array(
            [
                e.mode_mass_kg,
                2.0 * e.mode_damping_ratio * omega * e.mode_mass_kg,
                omega**2 * e.mode_mass_kg,
            ]
        )

    def half_band_m(self) -> float:
        """The friction band's half width where it is narrowest (track at its lowest) [m]."""
        e = self.effects
        lowest = min(self.mu + 0.5 * e.asymmetry * s for s in (1.0, -1.0))
        return NORMAL_N * (lowest * (1.0 - e.track_amplitude) + e.static_excess) / STIFFNESS_N_PER_M


def in_band(rig: Rig, rng: np.random.Generator) -> float:
    """A rest position drawn uniformly within 90 % of the friction band's half width [m]."""
    return float(rng.uniform(-0.9, 0.9) * rig.half_band_m())


def re_centred(effects: Effects) -> bool:
    """Whether a session's isolated hits start at the centre: where direction-dependent friction
    is hidden (against fitted starts it is a shifted centre, so a lab re-centres)."""
    return bool(effects.asymmetry)


# --- acquisition ------------------------------------------------------------------------


def bessel(rate_hz: float) -> tuple[np.ndarray, np.ndarray, float]:
    """The analog anti-alias prototype, 4th-order Bessel, -3 dB at BESSEL_SHARE of the rate:
    (zeros, poles [rad/s], gain), DC gain 1."""
    return scipy.signal.bessel(
        BESSEL_ORDER, 2.0 * math.pi * BESSEL_SHARE * rate_hz, analog=True, norm='mag', output='zpk'
    )


def analog(rate_hz: float, tracking_hz: float = 0.0) -> tuple[np.ndarray, ...]:
    """The Bessel filter, behind a 1st-order tracking low-pass at tracking_hz if given, as a
    continuous state space (A, B, C, D), built on the prototype normalised to its corner
    (its matrices of order one) and scaled back."""
    corner = 2.0 * math.pi * BESSEL_SHARE * rate_hz
    zeros, poles, gain = scipy.signal.bessel(
        BESSEL_ORDER, 1.0, analog=True, norm='mag', output='zpk'
    )
    if tracking_hz:
        pole = 2.0 * math.pi * tracking_hz / corner
        poles, gain = np.r_[poles, -pole], gain * pole
    a, b, c, d = scipy.signal.zpk2ss(zeros, poles, gain)
    return corner * a, corner * b, c, d


def first_order_hold(system: tuple[np.ndarray, ...], step_s: float) -> tuple[np.ndarray, ...]:
    """The state space exact for an input linear between points step_s apart:
    (ad, bd, cd, dd) of x[k+1] = ad x[k] + bd u[k], y[k] = cd x[k] + dd u[k]."""
    ad, bd, cd, dd, _ = scipy.signal.cont2discrete(system, step_s, method='foh')
    return tuple(
        np.ascontiguousarray(m, dtype=float) for m in (ad, bd.ravel(), cd.ravel(), dd.ravel())
    )


def quantised(values: np.ndarray, full_scale: float) -> np.ndarray:
    """Rounded to a BITS converter's step over +-full_scale, clipped there."""
    step = 2.0 * full_scale / 2**BITS
    return np.clip(np.round(values / step) * step, -full_scale, full_scale - step)


def random_walk(rng: np.random.Generator, samples: int, rms: float) -> np.ndarray:
    """A Brownian path from zero at the first sample, scaled to an RMS over the record."""
    walk = np.r_[0.0, np.cumsum(rng.normal(size=samples - 1))]
    return rms * walk / math.sqrt(np.mean(walk**2))


@dataclass(frozen=True)
class Chain:
    """One session's acquisition (drawn a session)."""

    rate_hz: float
    tracking_hz: float
    """The vibrometer decoder's tracking low-pass corner [Hz]."""
    skew_s: float
    """How long after the force the multiplexed ADC reads the velocity [s]."""
    zero_n: float
    """The force channel's zero offset [N]."""
    drift_share: float
    """The velocity's random walk: its RMS over a record over the white noise's."""

    @property
    def cells(self) -> int:
        """Grid cells a sample."""
        return round(GRID_HZ / self.rate_hz)

    @property
    def decoder_delay_s(self) -> float:
        """The tracking filter's low-frequency group delay 1 / (2 pi f), which the vibrometer's
        acquisition takes off [s]."""
        return 1.0 / (2.0 * math.pi * self.tracking_hz)


@dataclass(frozen=True)
class Strike:
    """A hit as it happened: the hammer, and its contact force on the moving rig."""

    hammer: Hammer
    times_s: np.ndarray
    """The loop's steps while the hammer was near [s]."""
    force_n: np.ndarray
    """The contact force there [N]."""
    impulse_n_s: float
    """m_h (V0 - the hammer's velocity after the contact) [N s]."""

    @property
    def onset_s(self) -> float:
        """When the tip touched [s]."""
        return self.hammer.onset_s

    @property
    def end_s(self) -> float:
        """The first step after the contact (the force zero there) [s]."""
        return float(self.times_s[np.flatnonzero(self.force_n > 0.0)[-1] + 1])

    @property
    def peak_n(self) -> float:
        """The largest force at the steps [N]."""
        return float(self.force_n.max())


@dataclass(frozen=True)
class Motion:
    """One hit's channels before offsets, noise and rounding, and its truth."""

    force_n: np.ndarray
    velocity_m_s: np.ndarray
    strike: Strike
    rest_s: float
    """When the rig stuck for good (inf if still moving at the end) [s]."""
    rest_m: float
    """Where it rests (where it was at the end if still moving) [m]."""
    trace: np.ndarray
    """Every `keep`-th grid node's (t [s], x [m], v [m/s], x2 [m], v2 [m/s])."""


def move(
    rig: Rig,
    hammer: Hammer,
    start_m: float,
    chain: Chain,
    duration_s: float,
    lag_s: float = 0.0,
    keep: int = 0,
    refine: int = 1,
) -> Motion:
    """The hit from rest at start_m through the chain (module doc); keep: trace every
    keep-th grid node; refine: that many times finer steps and grid."""
    cells = chain.cells * refine
    cell_s = 1.0 / (chain.rate_hz * cells)
    samples = round(duration_s * chain.rate_hz)
    first = math.floor(hammer.onset_s / cell_s)
    phase = (chain.skew_s - lag_s + chain.decoder_delay_s) / cell_s
    shift = math.floor(phase)
    last = samples * cells + max(shift + 1, 0)
    fine_s = cell_s / SUBSTEPS
    capacity = math.ceil(2.0 * hammer.contact_s / fine_s) + 4 * SUBSTEPS
    traces = (last - first) // keep + 2 if keep else 1
    velocity, forces, count, hammer_after, rest_s, end_m, trace, traced = _run(
        rig.parameters,
        rig.mode,
        hammer.parameters,
        float(start_m),
        cell_s,
        SUBSTEPS,
        first,
        last,
        shift,
        phase - shift,
        *first_order_hold(analog(chain.rate_hz, chain.tracking_hz), cell_s),
        cells,
        samples,
        keep,
        capacity,
        traces,
    )
    times = (first + np.arange(count) / SUBSTEPS) * cell_s
    strike = Strike(
        hammer, times, forces[:count], hammer.mass_kg * (hammer.speed_m_s - hammer_after)
    )
    tail = np.zeros(count + math.ceil(FORCE_TAIL_S / fine_s))
    tail[:count] = forces[:count]
    filtered = _filtered(*first_order_hold(analog(chain.rate_hz), fine_s), tail)
    index = first * SUBSTEPS + np.arange(tail.size)
    at = index % (SUBSTEPS * cells) == 0
    sample = index[at] // (SUBSTEPS * cells)
    force = np.zeros(samples)
    force[sample[sample < samples]] = filtered[at][sample < samples]
    return Motion(force, velocity, strike, rest_s, end_m, trace[:traced])


# --- records and sessions ---------------------------------------------------------------


@dataclass(frozen=True)
class KarnoppRecord:
    """One hit's record as the DAQ delivered it, and its truth."""

    force_n: np.ndarray
    velocity_m_s: np.ndarray
    sample_rate_hz: float
    strike: Strike
    """The hit, its onset on the record's clock."""
    mu: float
    start_m: float
    rest_m: float
    rest_s: float
    """When the rig stuck for good [s] (inf if still moving at the record's end)."""
    chain: Chain
    source: str = ''

    @property
    def pulse(self) -> Strike:
        """The hit (as other worlds' records name it)."""
        return self.strike


@dataclass(frozen=True)
class KarnoppWorld:
    """The `karnopp` world (module doc): its noise levels and record length."""

    name: str = 'karnopp'
    sensor: str = 'velocity'
    """What the response sensor measures (as `lab.World.sensor`): a vibrometer."""
    force_white_n: float = 0.2
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
    ) -> KarnoppRecord:
        """One hit's record from rest at start_m."""
        motion = move(Rig(mu, effects), hammer, start_m, chain, self.duration_s, effects.lag_s)
        samples = motion.force_n.size
        force = motion.force_n + chain.zero_n + rng.normal(0.0, self.force_white_n, samples)
        speed = motion.velocity_m_s + effects.velocity_offset_m_s
        speed += rng.normal(0.0, self.velocity_white_m_s, samples)
        speed += random_walk(rng, samples, chain.drift_share * self.velocity_white_m_s)
        return KarnoppRecord(
            quantised(force, FORCE_RANGE_N),
            quantised(speed, VELOCITY_RANGE_M_S),
            chain.rate_hz,
            motion.strike,
            mu,
            start_m,
            motion.rest_m,
            motion.rest_s,
            chain,
            source,
        )

    def chain(self, rng: np.random.Generator) -> Chain:
        """A session's acquisition, drawn."""
        rate = float(rng.choice(RATES_HZ))
        low, high = TRACKING_HZ[rate]
        return Chain(
            rate,
            float(np.exp(rng.uniform(math.log(low), math.log(high)))),
            float(rng.uniform(*SKEW_S)),
            float(rng.uniform(-1.0, 1.0) * ZERO_OFFSET_N),
            float(rng.uniform(*DRIFT_SHARE)),
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
    ) -> list[KarnoppRecord]:
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


KARNOPP = KarnoppWorld()
"""The `karnopp` world (module doc)."""
