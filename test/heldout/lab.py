"""Worlds, hidden effects and records: what a held-out session looks like, and its truth.

A `World` is one way of making data: an integrator (`plant.solve_events` or
`plant.solve_steps`), the hit shapes it draws, an acquisition (`chain.Daq`) and the response
sensor: a vibrometer (velocity) or an accelerometer (acceleration, the derivative of the
motion's velocity read before the anti-alias filter, with the chain's noise, offset and drift
in m/s^2, as an IEPE accelerometer's DC-coupled chain gives them). `Effects`
hold what is hidden in a session, each as the physics it is (not as the product's model
terms): added viscous damping, a Stribeck contact, direction-dependent friction, a cubic
spring, a second structural mode seen by the vibrometer, a vibrometer zero offset, a
vibrometer lag, friction changing from hit to hit, friction varying along a wear track.
`record` makes one hit's record; `session` a session of hits, each from rest at the centre
(isolated) or where the previous one stopped (chained).
"""

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.integrate

from heldout.chain import Channel, Daq, acquire, digitise
from heldout.forces import LEVELS_N, Hit, random_hit
from heldout.plant import Contact, Motion, Plant, solve_events, solve_steps

DIFFERENCE_S = 1e-6
"""Half the step of the central difference an accelerometer world reads the velocity by [s]."""
PRETRIGGER_S = 0.1
"""Time from a record's first sample to the hit's onset (plus a random fraction of a sample)."""


@dataclass(frozen=True)
class World:
    """One independent way of making data."""

    name: str
    solver: Callable[..., Motion]
    shapes: tuple[str, ...]
    daq: Daq
    """Its `velocity` channel is the response sensor's, in that sensor's units."""
    sensor: str = 'velocity'
    """What the response sensor measures: 'velocity' or 'acceleration'."""


EVENTS = World(
    'events',
    solve_events,
    ('half_sine', 'hertz'),
    Daq(
        force=Channel(0.2, offset=0.22, drift=0.05, hum=0.05, full_scale=5000.0),
        velocity=Channel(1e-4, drift=3e-6, hum=5e-6, full_scale=2.0),
        filter_kind='butter',
        filter_order=8,
        cutoff_hz=4000.0,
        mains_hz=50.0,
    ),
)
"""Event-located DOP853, half-sine and Hertzian hits, white noise, a Butterworth chain."""


STEPS = World(
    'steps',
    solve_steps,
    ('hertz', 'double_exponential'),
    Daq(
        force=Channel(
            0.15, coloured_std=0.1, coloured_pole=0.8, offset=-0.3, drift=0.1, walk=True, hum=0.08
        ),
        velocity=Channel(
            0.9e-4, coloured_std=0.3e-4, coloured_pole=0.7, drift=4e-6, walk=True, hum=4e-6
        ),
        filter_kind='bessel',
        filter_order=4,
        cutoff_hz=3000.0,
        mains_hz=60.0,
    ),
)
"""Fixed-step RK4 at 200 kHz, Hertzian and two-exponential hits, white plus coloured noise,
a Bessel chain, 60 Hz mains, random-walk drift."""


ACCELEROMETER = World(
    'accelerometer',
    solve_events,
    ('half_sine', 'hertz', 'double_exponential'),
    Daq(
        force=Channel(0.2, offset=0.15, drift=0.05, hum=0.05, full_scale=5000.0),
        velocity=Channel(1.5e-3, offset=0.02, drift=2e-4, walk=True, hum=2e-3),
        filter_kind='butter',
        filter_order=6,
        cutoff_hz=3500.0,
        mains_hz=50.0,
    ),
    sensor='acceleration',
)
"""Event-located DOP853 measured by an accelerometer: white noise of 1.5e-3 m/s^2 (a common
100 mV/g sensor's broadband resolution, 0.00015 g), a zero offset and a random-walk drift of
the acceleration (integrated, a random walk and a wandering slope of the velocity), mains hum,
a Butterworth chain, and no rounding (a 24-bit IEPE module steps far below its noise)."""


@dataclass(frozen=True)
class Effects:
    """What a session hides (all zero: the plain Coulomb rig)."""

    added_damping_n_s_per_m: float = 0.0
    static_excess: float = 0.0
    stribeck_speed_m_s: float = 2e-3
    asymmetry: float = 0.0
    cubic_n_per_m3: float = 0.0
    mode_hz: float = 0.0
    mode_damping_ratio: float = 0.01
    mode_mass_kg: float = 1000.0
    velocity_offset_m_s: float = 0.0
    lag_s: float = 0.0
    mu_step: float = 0.0
    """Relative change of mu from one hit to the next."""
    track_amplitude: float = 0.0
    track_wavelength_m: float = 6e-3
    track_phase: float = 0.0


@dataclass(frozen=True)
class Record:
    """One hit's record as the DAQ saved it, and its truth."""

    force_n: np.ndarray
    velocity_m_s: np.ndarray
    """The response sensor's samples: m/s, or m/s^2 when `quantity` is acceleration."""
    sample_rate_hz: float
    hit: Hit
    """The hit, its onset on the record's clock [s]."""
    mu: float
    start_m: float
    rest_m: float
    source: str = ''
    quantity: str = 'velocity'
    """What the response sensor measured (the world's sensor)."""


def _mode_velocity(effects: Effects, hit: Hit) -> Callable[[np.ndarray], np.ndarray]:
    """The second mode's velocity at any times: m2 x2'' + c2 x2' + k2 x2 = f(t)."""
    if not effects.mode_hz:
        return lambda t: np.zeros(np.shape(t))
    omega = 2 * math.pi * effects.mode_hz
    zeta, mass = effects.mode_damping_ratio, effects.mode_mass_kg

    def rhs(time, z):
        return (z[1], float(hit.force_n(time)) / mass - 2 * zeta * omega * z[1] - omega**2 * z[0])

    during = scipy.integrate.solve_ivp(
        rhs,
        (hit.onset_s, hit.end_s),
        (0.0, 0.0),
        method='DOP853',
        rtol=1e-11,
        atol=(1e-15, 1e-12),
        dense_output=True,
    )
    x_end, v_end = during.y[:, -1]
    decay, damped = zeta * omega, omega * math.sqrt(1 - zeta * zeta)

    def velocity(time_s: np.ndarray) -> np.ndarray:
        t = np.asarray(time_s, dtype=float)
        out = np.zeros(t.shape)
        inside = (t > hit.onset_s) & (t < hit.end_s)
        if inside.any():
            out[inside] = during.sol(t[inside])[1]
        late = t >= hit.end_s
        tau = t[late] - hit.end_s
        a, b = x_end, (v_end + decay * x_end) / damped
        envelope = np.exp(-decay * tau)
        # x = e^{-d tau} (a cos w tau + b sin w tau); v its derivative
        out[late] = envelope * (
            (b * damped - decay * a) * np.cos(damped * tau)
            - (a * damped + decay * b) * np.sin(damped * tau)
        )
        return out

    return velocity


def record(
    world: World,
    effects: Effects,
    mu: float,
    hit: Hit,
    start_m: float,
    rng: np.random.Generator,
    duration_s: float = 12.0,
    source: str = '',
) -> Record:
    """One hit's record: the motion from start_m, sampled through the world's chain.

    hit: its onset on the record's clock (PRETRIGGER_S plus a fraction of a sample).
    """
    plant = Plant(
        damping_n_s_per_m=Plant().damping_n_s_per_m + effects.added_damping_n_s_per_m,
        cubic_n_per_m3=effects.cubic_n_per_m3,
    )
    contact = Contact(
        mu,
        asymmetry=effects.asymmetry,
        static_excess=effects.static_excess,
        stribeck_speed_m_s=effects.stribeck_speed_m_s,
        track_amplitude=effects.track_amplitude,
        track_wavelength_m=effects.track_wavelength_m,
        track_phase=effects.track_phase,
    )
    motion = world.solver(plant, contact, hit, start_m, duration_s)
    mode = _mode_velocity(effects, hit)
    lag = effects.lag_s

    def velocity(t: np.ndarray) -> np.ndarray:
        return motion.evaluate(t - lag)[1] + mode(t - lag)

    response = velocity
    if world.sensor == 'acceleration':
        if effects.velocity_offset_m_s:
            raise ValueError('a velocity offset is a vibrometer effect, not an accelerometer one')

        def response(t: np.ndarray) -> np.ndarray:
            """The velocity's central difference over 2 us: its derivative on the fine grid."""
            return (velocity(t + DIFFERENCE_S) - velocity(t - DIFFERENCE_S)) / (2 * DIFFERENCE_S)

    daq = world.daq
    samples = round(duration_s * daq.rate_hz)
    end = motion.rest_s if math.isfinite(motion.rest_s) else duration_s
    ring = 0.0
    if effects.mode_hz:
        # until the mode's envelope is far below a noise deviation
        decay = effects.mode_damping_ratio * 2 * math.pi * effects.mode_hz
        ring = math.log(1e4 * hit.impulse_n_s / effects.mode_mass_kg / daq.velocity.noise_std)
        ring = max(ring, 0.0) / decay
    velocity_active = (hit.onset_s, min(duration_s, max(end, hit.end_s + ring) + lag + 0.01))
    force = acquire(daq, hit.force_n, daq.force, samples, 0.0, (hit.onset_s, hit.end_s), rng)
    speed = acquire(daq, response, daq.velocity, samples, 0.0, velocity_active, rng)
    speed = speed + effects.velocity_offset_m_s
    return Record(
        digitise(force, daq.force),
        digitise(speed, daq.velocity),
        daq.rate_hz,
        hit,
        mu,
        start_m,
        motion.rest_m,
        source,
        world.sensor,
    )


def session(
    world: World,
    effects: Effects,
    mu: float,
    rng: np.random.Generator,
    levels_n: Sequence[float] = LEVELS_N,
    *,
    chained: bool = False,
    duration_s: float = 12.0,
    shapes: Sequence[str] | None = None,
) -> list[Record]:
    """One record a hit at each level in turn; mu changes by effects.mu_step from hit to hit.

    chained: each hit finds the rig where the previous one left it (a continuous session);
    otherwise every hit starts from rest at the centre.
    """
    records, start = [], 0.0
    for index, level in enumerate(levels_n):
        onset = PRETRIGGER_S + rng.uniform(0.0, 1.0) / world.daq.rate_hz
        hit = random_hit(rng, float(level), onset, tuple(shapes or world.shapes))
        hit_mu = mu * (1.0 + effects.mu_step) ** index
        made = record(
            world, effects, hit_mu, hit, start, rng, duration_s, f'{world.name} hit {index}'
        )
        records.append(made)
        if chained and math.isfinite(made.rest_m):
            start = made.rest_m
    return records
