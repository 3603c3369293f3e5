"""A held-out world, `moreau`: a nonsmooth-mechanics lab's simulator, written when
`events` and `analytic` were about to become tuning worlds, and never looked at before its
first sweep (never tuned on).

Other choices than `lab.EVENTS`, `lab.STEPS`, `ivp.IVP` and `analytic.ANALYTIC` at every stage,
sharing only the `lab.Effects` description:

- Hits: not a prescribed pulse but a collision. A hammer body (0.1-0.3 kg a session) flies at
  the rig and strikes it through a Hertzian tip, F = k_tip max(delta, 0)^1.5 with delta the
  tip's overlap with the struck point; the contact is integrated with the rig, and the force
  sensor reads the contact force. The tip stiffness is drawn a session so a 1000 N hit lasts
  1.5-3.5 ms (the paper's impulses, 0.98-1.64 N s at 450-1450 N, are 2-4 ms of its rubber
  tip); each hit's speed is set from Hertz's impact solution so its peak lands within 2 % of a
  level. Contact begins at a random time between samples (and between steps).
- Motion: Moreau-Jean time stepping (the theta-method, theta = `THETA`) at a fine step of
  `STEPS_PER_SAMPLE` steps a sample, every body in one step: the rig (with a cubic spring and
  added damping), a second structural mode at the struck point (the hammer drives it through
  the same contact; the vibrometer sees the struck point), the hammer. The smooth forces are
  implicit (Newton iterations on the step's equations); the Coulomb contact is the set-valued
  law on the step's end velocity, solved exactly each step as a one-dimensional projection:
  the rig sticks when the impulse that would hold it lies inside the friction cone of the
  static coefficient (direction-dependent: asymmetric friction), and otherwise slides against
  the kinetic coefficient at the step's end speed (Stribeck, by a scalar fixed point) and
  position (a wear track).
- Acquisition: a dynamic signal analyser. Both channels, read at every fine step, are
  decimated to the sample rate (8, 10.24 or 25.6 kHz, drawn a session) by one linear-phase
  Kaiser FIR (cutoff at half the sample rate, 90 dB stop band 0.05 of the rate either side)
  with its group delay compensated, as a DSA's delta-sigma filter on both channels alike:
  no delay between channels, the force's pre-ringing included. Band-limited white noise and
  mains hum (50 or 60 Hz a session, harmonics 2-5, amplitudes drawn) on both channels; a
  vibrometer lag is a delay of its analog output (interpolated between steps); 16-bit
  rounding over +-5000 N and +-1 m/s.
- Sessions are continuous, on one clock: each hit finds the rig where the one before left
  it, after a drawn wait (a second mode rings on through it, the hum keeps its phase); mu
  drifts between hits. The first hit of a session starts where an earlier, unrecorded one
  left the rig (anywhere in the friction band), and the diagnosis is told to fit each start
  (`FITTED`). A session hiding direction-dependent friction is re-centred before each hit
  (`CENTRE`: against fitted starts an asymmetry is exactly a shifted centre, invisible to any
  diagnosis); chained sessions start at the centre (`CHAINED`).
"""

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numba
import numpy as np
import scipy.signal

from heldout.lab import Effects

MASS_KG, STIFFNESS_N_PER_M, DAMPING_N_S_PER_M = 10.391, 1982.0, 0.275
NORMAL_N = 0.680 * 9.81
THETA = 0.5
"""The theta-method's weight: 0.5 (the trapezoid) adds no numerical damping to the modes."""
STEPS_PER_SAMPLE = {8_000.0: 50, 10_240.0: 40, 25_600.0: 20}
"""Sample rates a session is recorded at, and the fine steps a sample (400-512 kHz)."""
RATES_HZ = tuple(STEPS_PER_SAMPLE)
PRETRIGGER_S = 0.12
DURATION_S = 12.0
WAIT_S = (3.0, 20.0)
"""The wait between one record's end and the next one's start [s]."""
FORCE_RANGE_N, VELOCITY_RANGE_M_S = 5000.0, 1.0
"""The 16-bit converter's +- ranges."""
FIR_HALF_SAMPLES = 29
"""The decimating FIR's half length in output samples (its group delay, compensated)."""
FIR_STOP_DB = 90.0
LAG_MARGIN_S = 5e-4
"""The stretch simulated before a record's first filter span for a vibrometer lag (at most
this) [s]; as much after its last, so consecutive records' stretches are 2 (K / rate + it)
shorter than the time between them."""
NOISE_TAPS = 129
HERTZ_TIME = 2.9432
"""Hertz's impact duration over delta_max / approach speed (Johnson, Contact Mechanics)."""
GONE_M = 1e-3
"""A hammer this far behind the struck point and receding has left for good [m]."""

# the kernel's parameter vector, by index
(
    _M,
    _C,
    _K,
    _K3,
    _N,
    _MU,
    _ASYM,
    _EXCESS,
    _VS,
    _TAMP,
    _TWL,
    _TPH,
    _M2,
    _C2,
    _K2,
    _MH,
    _KTIP,
    _THETA,
) = range(18)
# the kernel's state vector: rig x, v; mode y, w; hammer z, u; rig moving?; hammer flying?
_X, _V, _Y, _W, _Z, _U, _RIG_ON, _HAMMER_ON = range(8)


@numba.njit(cache=True)
def _mu(p: np.ndarray, direction: float, speed: float, x: float) -> float:
    """The friction coefficient in a direction at a speed and position (static at speed 0)."""
    base = p[_MU] + 0.5 * p[_ASYM] * direction
    if p[_TAMP] != 0.0:
        base *= 1.0 + p[_TAMP] * math.sin(2.0 * math.pi * x / p[_TWL] + p[_TPH])
    if p[_EXCESS] != 0.0:
        base += p[_EXCESS] * math.exp(-((speed / p[_VS]) ** 2))
    return base


@numba.njit(cache=True)
def _slide(p: np.ndarray, free: float, compliance: float, h: float, direction: float, x: float):
    """The end speed of a slide: s = free - compliance h N mu_k(s), s > 0 (a contraction)."""
    s = free - compliance * h * p[_N] * _mu(p, direction, free, x)
    for _ in range(20):
        new = free - compliance * h * p[_N] * _mu(p, direction, s, x)
        if abs(new - s) <= 1e-16 + 1e-15 * abs(s):
            return new
        s = new
    return s


@numba.njit(cache=True)
def _forces(p, q, v, on):
    """Smooth forces on (rig, mode, hammer), the contact force, its slope in the overlap."""
    delta = q[2] - q[0] - q[1]
    contact = 0.0
    slope = 0.0
    if on[2] and delta > 0.0:
        root = math.sqrt(delta)
        contact = p[_KTIP] * delta * root
        slope = 1.5 * p[_KTIP] * root
    fx = -p[_C] * v[0] - p[_K] * q[0] - p[_K3] * q[0] ** 3 + contact
    fy = -p[_C2] * v[1] - p[_K2] * q[1] + contact
    return fx, fy, -contact, contact, slope


@numba.njit(cache=True)
def _invert(a, out):
    """The inverse of a 3x3 matrix (cofactors) into out."""
    out[0, 0] = a[1, 1] * a[2, 2] - a[1, 2] * a[2, 1]
    out[0, 1] = a[0, 2] * a[2, 1] - a[0, 1] * a[2, 2]
    out[0, 2] = a[0, 1] * a[1, 2] - a[0, 2] * a[1, 1]
    out[1, 0] = a[1, 2] * a[2, 0] - a[1, 0] * a[2, 2]
    out[1, 1] = a[0, 0] * a[2, 2] - a[0, 2] * a[2, 0]
    out[1, 2] = a[0, 2] * a[1, 0] - a[0, 0] * a[1, 2]
    out[2, 0] = a[1, 0] * a[2, 1] - a[1, 1] * a[2, 0]
    out[2, 1] = a[0, 1] * a[2, 0] - a[0, 0] * a[2, 1]
    out[2, 2] = a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0]
    det = a[0, 0] * out[0, 0] + a[0, 1] * out[1, 0] + a[0, 2] * out[2, 0]
    for i in range(3):
        for j in range(3):
            out[i, j] /= det


@numba.njit(cache=True)
def _step(p, state, h, work):
    """One Moreau-Jean step of every moving body; the state updated in place.

    M (v+ - v) = h [theta f(q_theta, v+) + (1 - theta) f(q, v)] + r e_x, with
    q_theta = q + h [theta v+ + (1 - theta) v] (also the step's end position q+) and r the
    friction impulse: r in -h N mu_s [-1, 1] when v+_x = 0, else -h N mu_k(|v+_x|) sign(v+_x).
    Newton on the smooth part; at each iterate the friction is the exact solution of the
    one-dimensional problem. work: scratch (q, v, end, at, residual, free; matrices w, inverse,
    stiffness).
    """
    theta = p[_THETA]
    on = (state[_RIG_ON] != 0.0, p[_M2] > 0.0, state[_HAMMER_ON] != 0.0)
    mass = (p[_M], p[_M2], p[_MH])
    damp = (-p[_C], -p[_C2], 0.0)
    vectors, w, inverse, stiff = work
    q, v, end, at, residual, free = vectors
    q[0], q[1], q[2] = state[_X], state[_Y], state[_Z]
    v[0], v[1], v[2] = state[_V], state[_W], state[_U]
    f0 = _forces(p, q, v, on)[:3]
    linear = not on[2] and p[_K3] == 0.0
    for i in range(3):
        end[i] = v[i]
    for _ in range(50):
        for i in range(3):
            at[i] = q[i] + h * (theta * end[i] + (1.0 - theta) * v[i])
        fx, fy, fz, _, slope = _forces(p, at, end, on)
        f = (fx, fy, fz)
        # stiffness K = df/dq of the smooth forces (the damping C = df/dv is diagonal)
        stiff[0, 0] = -p[_K] - 3.0 * p[_K3] * at[0] ** 2 - slope
        stiff[0, 1] = stiff[1, 0] = -slope
        stiff[0, 2] = stiff[2, 0] = slope
        stiff[1, 1] = -p[_K2] - slope
        stiff[1, 2] = stiff[2, 1] = slope
        stiff[2, 2] = -slope
        for i in range(3):
            for j in range(3):
                w[i, j] = 0.0
            if not on[i]:
                w[i, i] = 1.0
                residual[i] = 0.0
                continue
            residual[i] = mass[i] * (end[i] - v[i]) - h * (theta * f[i] + (1.0 - theta) * f0[i])
            w[i, i] = mass[i] - h * theta * damp[i]
            for j in range(3):
                if on[j]:
                    w[i, j] -= h * h * theta * theta * stiff[i, j]
        _invert(w, inverse)
        for i in range(3):
            free[i] = end[i] - (
                inverse[i, 0] * residual[0]
                + inverse[i, 1] * residual[1]
                + inverse[i, 2] * residual[2]
            )
        impulse, stuck = 0.0, False
        if on[0]:
            compliance, x = inverse[0, 0], q[0]
            if free[0] > compliance * h * p[_N] * _mu(p, 1.0, 0.0, x):
                impulse = (_slide(p, free[0], compliance, h, 1.0, x) - free[0]) / compliance
            elif free[0] < -compliance * h * p[_N] * _mu(p, -1.0, 0.0, x):
                impulse = (-_slide(p, -free[0], compliance, h, -1.0, x) - free[0]) / compliance
            else:
                impulse, stuck = -free[0] / compliance, True
        change = 0.0
        for i in range(3):
            new = free[i] + inverse[i, 0] * impulse
            if i == 0 and stuck:
                new = 0.0  # stuck: exactly at rest
            change = max(change, abs(new - end[i]))
            end[i] = new
        if linear or change <= 1e-13 * (1.0 + abs(end[0]) + abs(end[1]) + abs(end[2])):
            break
    for i in range(3):
        q[i] += h * (theta * end[i] + (1.0 - theta) * v[i])
    state[_X], state[_Y], state[_Z] = q[0], q[1], q[2]
    state[_V], state[_W], state[_U] = end[0], end[1], end[2]


@numba.njit(cache=True)
def _step_apart(p, state, h):
    """`_step` with the hammer gone: rig and mode no longer touch it, so each is a body of
    its own and the 3x3 Newton system is two scalar ones (the same step, less work)."""
    theta = p[_THETA]
    if state[_RIG_ON] != 0.0:
        x, v = state[_X], state[_V]
        m, c, k, k3 = p[_M], p[_C], p[_K], p[_K3]
        f0 = -c * v - k * x - k3 * x**3
        end = v
        for _ in range(50):
            at = x + h * (theta * end + (1.0 - theta) * v)
            f = -c * end - k * at - k3 * at**3
            residual = m * (end - v) - h * (theta * f + (1.0 - theta) * f0)
            compliance = 1.0 / (m + h * theta * c + h * h * theta * theta * (k + 3.0 * k3 * at**2))
            free = end - compliance * residual
            if free > compliance * h * p[_N] * _mu(p, 1.0, 0.0, x):
                new = _slide(p, free, compliance, h, 1.0, x)
            elif free < -compliance * h * p[_N] * _mu(p, -1.0, 0.0, x):
                new = -_slide(p, -free, compliance, h, -1.0, x)
            else:
                new = 0.0
            change = abs(new - end)
            end = new
            if k3 == 0.0 or change <= 1e-13 * (1.0 + abs(end)):
                break
        state[_X] = x + h * (theta * end + (1.0 - theta) * v)
        state[_V] = end
    if p[_M2] > 0.0:
        y, w = state[_Y], state[_W]
        f0 = -p[_C2] * w - p[_K2] * y
        f = -p[_C2] * w - p[_K2] * (y + h * w)
        stiffness = p[_M2] + h * theta * p[_C2] + h * h * theta * theta * p[_K2]
        end = w + h * (theta * f + (1.0 - theta) * f0) / stiffness
        state[_Y] = y + h * (theta * end + (1.0 - theta) * w)
        state[_W] = end


@numba.njit(cache=True)
def _contact(p, state):
    """The tip's contact force at a state [N]."""
    delta = state[_Z] - state[_X] - state[_Y]
    if state[_HAMMER_ON] == 0.0 or delta <= 0.0:
        return 0.0
    return p[_KTIP] * delta**1.5


@numba.njit(cache=True)
def _run(p, state, h, steps, force_out, velocity_out, position_out):
    """`steps` steps from the state (updated); the node values written if the outputs have
    steps + 1 entries: contact force, struck point's velocity, rig position."""
    record = force_out.size > 0
    work = ([np.zeros(3) for _ in range(6)], np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 3)))
    if record:
        force_out[0] = _contact(p, state)
        velocity_out[0] = state[_V] + state[_W]
        position_out[0] = state[_X]
    for j in range(1, steps + 1):
        if state[_RIG_ON] == 0.0 and state[_HAMMER_ON] == 0.0 and p[_M2] == 0.0:
            if record:  # nothing moves any more
                force_out[j:] = 0.0
                velocity_out[j:] = 0.0
                position_out[j:] = state[_X]
            return
        if state[_HAMMER_ON] != 0.0:
            _step(p, state, h, work)
        else:
            _step_apart(p, state, h)
        if state[_HAMMER_ON] != 0.0:
            gap = state[_X] + state[_Y] - state[_Z]
            if gap > GONE_M and state[_U] < 0.0:
                state[_HAMMER_ON] = 0.0
        if state[_RIG_ON] != 0.0 and state[_HAMMER_ON] == 0.0 and state[_V] == 0.0:
            x = state[_X]
            spring = p[_K] * x + p[_K3] * x**3
            if abs(spring) <= p[_N] * _mu(p, -math.copysign(1.0, spring), 0.0, x):
                state[_RIG_ON] = 0.0  # at rest for good: nothing but the hammer moves it
        if record:
            force_out[j] = _contact(p, state)
            velocity_out[j] = state[_V] + state[_W]
            position_out[j] = state[_X]


@dataclass(frozen=True)
class Hammer:
    """The hammer body and its Hertzian tip, F = tip k max(delta, 0)^1.5."""

    mass_kg: float
    tip_n_per_m1_5: float

    def effective_mass_kg(self, rig_kg: float = MASS_KG) -> float:
        """The two-body collision's reduced mass [kg]."""
        return self.mass_kg * rig_kg / (self.mass_kg + rig_kg)

    def speed_for(self, peak_n: float) -> float:
        """The approach speed whose Hertz impact on a free rig peaks at peak_n [m/s]:
        1/2 m_eff V^2 = 2/5 k delta_max^2.5 with k delta_max^1.5 = peak."""
        delta = (peak_n / self.tip_n_per_m1_5) ** (2.0 / 3.0)
        return math.sqrt(0.8 * peak_n * delta / self.effective_mass_kg())

    def contact_s(self, peak_n: float) -> float:
        """Hertz's contact duration of a hit peaking at peak_n [s]."""
        delta = (peak_n / self.tip_n_per_m1_5) ** (2.0 / 3.0)
        return HERTZ_TIME * delta / self.speed_for(peak_n)


def random_hammer(rng: np.random.Generator) -> Hammer:
    """A hammer of 0.1-0.3 kg whose tip makes a 1000 N hit last 1.5-3.5 ms."""
    mass = rng.uniform(0.1, 0.3)
    contact, peak = rng.uniform(1.5e-3, 3.5e-3), 1000.0
    reduced = mass * MASS_KG / (mass + MASS_KG)
    # T = 2.9432 delta / V and V^2 = 0.8 F delta / m_eff: delta = 0.8 F (T / 2.9432)^2 / m_eff
    delta = 0.8 * peak * (contact / HERTZ_TIME) ** 2 / reduced
    return Hammer(mass, peak / delta**1.5)


@dataclass(frozen=True)
class Chain:
    """A session's acquisition: the rate and what each channel adds after the filter."""

    rate_hz: float
    force_white_n: float
    velocity_white_m_s: float
    mains_hz: float
    force_hum_n: tuple[float, ...]
    """Amplitudes of the mains fundamental and harmonics 2-5 on the force [N]."""
    velocity_hum_m_s: tuple[float, ...]
    hum_phases: tuple[float, ...]

    @property
    def steps_per_sample(self) -> int:
        """Fine steps a sample."""
        return STEPS_PER_SAMPLE[self.rate_hz]

    @property
    def step_s(self) -> float:
        """The fine step [s]."""
        return 1.0 / (self.rate_hz * self.steps_per_sample)

    def hum(self, amplitudes: tuple[float, ...], time_s: np.ndarray) -> np.ndarray:
        """Mains hum at session times [channel units]."""
        out = np.zeros(time_s.shape)
        pairs = zip(amplitudes, self.hum_phases, strict=True)
        for order, (amplitude, phase) in enumerate(pairs, start=1):
            out += amplitude * np.sin(2.0 * math.pi * order * self.mains_hz * time_s + phase)
        return out


def random_chain(rng: np.random.Generator) -> Chain:
    """A rate, noise levels and mains hum drawn for a session."""
    rate = float(rng.choice(RATES_HZ))
    relative = np.concatenate(([1.0], rng.uniform(0.0, 0.4, 4) / np.arange(2, 6)))
    force_hum = rng.uniform(0.02, 0.1) * relative
    velocity_hum = rng.uniform(2e-6, 1e-5) * relative
    return Chain(
        rate,
        rng.uniform(0.12, 0.25),
        rng.uniform(0.8e-4, 1.2e-4),
        float(rng.choice((50.0, 60.0))),
        tuple(force_hum),
        tuple(velocity_hum),
        tuple(rng.uniform(0.0, 2.0 * math.pi, 5)),
    )


def decimator(rate_hz: float) -> np.ndarray:
    """The DSA's decimating FIR on the fine grid: linear phase, 2 K M + 1 taps (K =
    FIR_HALF_SAMPLES, M steps a sample), so its delay is K whole samples; DC gain 1."""
    factor = STEPS_PER_SAMPLE[rate_hz]
    taps = 2 * FIR_HALF_SAMPLES * factor + 1
    beta = scipy.signal.kaiser_beta(FIR_STOP_DB)
    return scipy.signal.firwin(
        taps, 0.5 * rate_hz, window=('kaiser', beta), fs=rate_hz * factor, scale=True
    )


def decimate(fine: np.ndarray, rate_hz: float, samples: int) -> np.ndarray:
    """`samples` samples of a fine-step signal through the FIR, delay compensated.

    fine: (samples + 2 K) M + 1 node values; sample s is the filter centred on node (K + s) M.
    Where the signal is constant over a whole filter span, the output is that constant.
    """
    factor, half = STEPS_PER_SAMPLE[rate_hz], FIR_HALF_SAMPLES
    fir = decimator(rate_hz)
    out = np.empty(samples)
    moved = np.flatnonzero(fine != fine[0])
    if moved.size == 0:
        out[:] = fine[0]
        return out
    settled = np.flatnonzero(fine != fine[-1])
    first, last = int(moved[0]), int(settled[-1]) + 1
    low = min(samples, max(0, first // factor - 2 * half - 1))
    high = min(samples, last // factor + 1)
    out[:low], out[high:] = fine[0], fine[-1]
    if high > low:
        span = fine[low * factor : (high - 1 + 2 * half) * factor + 1]
        filtered = scipy.signal.upfirdn(fir, span, 1, factor)
        out[low:high] = filtered[2 * half : 2 * half + high - low]
    return out


def band_limited_noise(rng: np.random.Generator, samples: int, std: float) -> np.ndarray:
    """White noise as the DSA's filter leaves it: flat to 0.45 of the rate, of a given std."""
    fir = scipy.signal.firwin(NOISE_TAPS, 0.9, window=('kaiser', 8.0))
    white = rng.normal(size=samples + NOISE_TAPS - 1)
    return std * np.convolve(white, fir, mode='valid') / math.sqrt(np.sum(fir**2))


def quantised(values: np.ndarray, full_scale: float) -> np.ndarray:
    """Rounded to a 16-bit converter's step over +-full_scale, clipped there."""
    step = 2.0 * full_scale / 2**16
    return np.clip(np.round(values / step) * step, -full_scale, full_scale)


@dataclass(frozen=True)
class Rig:
    """The bodies' parameters for the kernel: rig, contact law, second mode, hammer."""

    effects: Effects
    mu: float
    hammer: Hammer

    def parameters(
        self, normal_n: float = NORMAL_N, stiffness: float = STIFFNESS_N_PER_M
    ) -> np.ndarray:
        """The kernel's parameter vector."""
        e = self.effects
        mode_mass = mode_damping = mode_stiffness = 0.0
        if e.mode_hz:
            omega = 2.0 * math.pi * e.mode_hz
            mode_mass = e.mode_mass_kg
            mode_damping = 2.0 * e.mode_damping_ratio * omega * mode_mass
            mode_stiffness = omega**2 * mode_mass
        return np.array(
            [
                MASS_KG,
                DAMPING_N_S_PER_M + e.added_damping_n_s_per_m,
                stiffness,
                e.cubic_n_per_m3,
                normal_n,
                self.mu,
                e.asymmetry,
                e.static_excess,
                e.stribeck_speed_m_s,
                e.track_amplitude,
                e.track_wavelength_m,
                e.track_phase,
                mode_mass,
                mode_damping,
                mode_stiffness,
                self.hammer.mass_kg,
                self.hammer.tip_n_per_m1_5,
                THETA,
            ]
        )


@dataclass(frozen=True)
class Fine:
    """A stretch simulated at the fine step: node times and values, and the state after."""

    time_s: np.ndarray
    force_n: np.ndarray
    velocity_m_s: np.ndarray
    """The struck point's velocity (rig and second mode)."""
    position_m: np.ndarray
    """The rig's position."""
    state: np.ndarray


def simulate(
    parameters: np.ndarray, state: np.ndarray, start_s: float, step_s: float, steps: int
) -> Fine:
    """`steps` Moreau-Jean steps from a state at start_s, every node recorded."""
    state = state.copy()
    force, velocity, position = np.empty(steps + 1), np.empty(steps + 1), np.empty(steps + 1)
    _run(parameters, state, step_s, steps, force, velocity, position)
    return Fine(start_s + step_s * np.arange(steps + 1), force, velocity, position, state)


def initial_state(start_m: float, mode: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
    """The rig at rest at start_m (free to move), the mode's (y, w), no hammer."""
    return np.array([start_m, 0.0, mode[0], mode[1], 0.0, 0.0, 1.0, 0.0])


def launch(state: np.ndarray, hammer_speed: float, from_s: float, contact_s: float) -> None:
    """Send the hammer from a state at from_s so its tip meets the struck point at contact_s
    (the struck point as it is at from_s; a ringing second mode moves it by micrometres)."""
    state[_Z] = state[_X] + state[_Y] - hammer_speed * (contact_s - from_s)
    state[_U] = hammer_speed
    state[_HAMMER_ON] = 1.0
    state[_RIG_ON] = 1.0


@dataclass(frozen=True)
class MoreauRecord:
    """One hit's record as the analyser delivered it, and its truth."""

    force_n: np.ndarray
    velocity_m_s: np.ndarray
    sample_rate_hz: float
    hammer: Hammer
    hammer_speed_m_s: float
    onset_s: float
    """When the tip touched the rig, on the record's clock [s]."""
    impulse_n_s: float
    """The hammer's momentum change (the contact impulse, as the scheme integrated it)."""
    mu: float
    start_m: float
    rest_m: float
    source: str = ''


@dataclass(frozen=True)
class MoreauWorld:
    """The `moreau` world (module doc): its record length."""

    name: str = 'moreau'
    sensor: str = 'velocity'
    """What the response sensor measures (as `lab.World.sensor`): a vibrometer."""
    duration_s: float = DURATION_S

    def session(
        self,
        effects: Effects,
        mu: float,
        rng: np.random.Generator,
        levels_n: Sequence[float],
        *,
        chained: bool = False,
    ) -> list[MoreauRecord]:
        """One record a level on one clock; mu changes by effects.mu_step a hit.

        chained: the first hit from rest at the centre; otherwise from where an earlier hit
        left the rig (in the friction band), or at the centre before every hit if
        `re_centred`. Every later hit finds the rig where the one before left it.
        """
        chain = random_chain(rng)
        hammer = random_hammer(rng)
        centred = re_centred(effects) and not chained
        start = 0.0 if chained or centred else in_band(effects, mu, rng)
        state = initial_state(start)
        clock, records = 0.0, []
        for index, level in enumerate(levels_n):
            hit_mu = mu * (1.0 + effects.mu_step) ** index
            if centred:
                state[_X] = 0.0
            made, state = self.record(
                Rig(effects, hit_mu, hammer), chain, float(level), state, clock, rng
            )
            records.append(replace(made, source=f'{self.name} hit {index}'))
            gap = rng.uniform(*WAIT_S)
            clock += self.duration_s + gap
            if index + 1 < len(levels_n):
                # from the end of one simulated stretch to the start of the next
                between = gap - 2.0 * (FIR_HALF_SAMPLES / chain.rate_hz + LAG_MARGIN_S)
                state = wait(Rig(effects, hit_mu, hammer), state, chain, between)
        return records

    def record(
        self,
        rig: Rig,
        chain: Chain,
        level_n: float,
        state: np.ndarray,
        clock_s: float,
        rng: np.random.Generator,
    ) -> tuple[MoreauRecord, np.ndarray]:
        """One hit's record starting at session time clock_s, and the state at its end."""
        rate, factor = chain.rate_hz, chain.steps_per_sample
        samples = round(self.duration_s * rate)
        half = FIR_HALF_SAMPLES
        lag = rig.effects.lag_s
        lag_steps = round(LAG_MARGIN_S / chain.step_s)
        steps = (samples + 2 * half) * factor + 2 * lag_steps
        onset = PRETRIGGER_S + rng.uniform(0.0, 1.0) / rate
        speed = rig.hammer.speed_for(level_n * rng.uniform(0.98, 1.02))
        begin = -half / rate - lag_steps * chain.step_s
        state = state.copy()
        start_m = float(state[_X])
        launch(state, speed, begin, onset)
        fine = simulate(rig.parameters(), state, begin, chain.step_s, steps)
        kept = slice(lag_steps, lag_steps + (samples + 2 * half) * factor + 1)
        nodes, force = fine.time_s[kept], fine.force_n[kept]
        velocity = fine.velocity_m_s[kept]
        if lag:
            velocity = np.interp(nodes - lag, fine.time_s, fine.velocity_m_s)
        velocity += rig.effects.velocity_offset_m_s
        times = clock_s + np.arange(samples) / rate
        force_samples = decimate(force, rate, samples) + chain.hum(chain.force_hum_n, times)
        force_samples += band_limited_noise(rng, samples, chain.force_white_n)
        speed_samples = decimate(velocity, rate, samples)
        speed_samples += chain.hum(chain.velocity_hum_m_s, times)
        speed_samples += band_limited_noise(rng, samples, chain.velocity_white_m_s)
        after = fine.state
        still = after[_RIG_ON] == 0.0
        made = MoreauRecord(
            quantised(force_samples, FORCE_RANGE_N),
            quantised(speed_samples, VELOCITY_RANGE_M_S),
            rate,
            rig.hammer,
            speed,
            onset,
            rig.hammer.mass_kg * (speed - after[_U]),
            rig.mu,
            start_m,
            float(after[_X]) if still else math.nan,
        )
        return made, after


def wait(rig: Rig, state: np.ndarray, chain: Chain, wait_s: float) -> np.ndarray:
    """The state wait_s later, stepped at the same fine step: the mode rings on, the rig
    rests (or moves on, if it had not come to rest).

    With the rig at rest for good and the hammer gone, the mode alone is linear: its steps
    are the scheme's own one-step map (found by stepping each unit state) to the power.
    """
    state = state.copy()
    steps = round(wait_s / chain.step_s)
    parameters, empty = rig.parameters(), np.empty(0)
    if state[_RIG_ON] != 0.0 or state[_HAMMER_ON] != 0.0:
        _run(parameters, state, chain.step_s, steps, empty, empty, empty)
    elif rig.effects.mode_hz:
        columns = []
        for unit in ((1.0, 0.0), (0.0, 1.0)):
            probe = state.copy()
            probe[_Y], probe[_W] = unit
            _run(parameters, probe, chain.step_s, 1, empty, empty, empty)
            columns.append((probe[_Y], probe[_W]))
        step_map = np.linalg.matrix_power(np.array(columns).T, steps)
        state[_Y], state[_W] = step_map @ np.array((state[_Y], state[_W]))
    return state


def re_centred(effects: Effects) -> bool:
    """Whether a session's hits start at the centre, the rig re-centred before each: where
    direction-dependent friction is hidden (against fitted starts it is a shifted centre)."""
    return bool(effects.asymmetry)


def in_band(effects: Effects, mu: float, rng: np.random.Generator) -> float:
    """Where an earlier, unrecorded hit left the rig: uniform over 90 % of the band where
    static friction holds it [m]."""
    lowest = mu - 0.5 * abs(effects.asymmetry) + effects.static_excess
    lowest *= 1.0 - effects.track_amplitude
    return float(rng.uniform(-0.9, 0.9) * NORMAL_N * lowest / STIFFNESS_N_PER_M)


MOREAU = MoreauWorld()
"""The `moreau` world (module doc)."""
