"""Continuous-time motion of the friction oscillator under a continuous force, with stick-slip.

    m x'' + c x' + k x + k3 x^3 + s N mu(v, x) = f(t),   s = sgn(v),

with the stick rule: when the velocity reaches zero at time t, the mass stays put while the
net force |f(t) - k x - k3 x^3| does not exceed mu_s N (towards the side it pushes), and
breaks away at the instant it does. f(t) is the sum of the hammer pulses, evaluated as the
continuous function it is (never interpolated from samples), and every event (reversal,
stick, break-away) is located in continuous time; the motion is sampled afterwards by
`Trajectory.evaluate` at any times.

Two paths give the same motion:

- general: scipy's DOP853 (rtol 1e-10) on each sliding phase, stopped by terminal events at
  v = 0 and at jumps of the friction law in position; at rest, the break-away instant is a
  sign change of |f(t) - spring| - mu_s N scanned over the pulse and refined by brentq.
- closed form (`method='auto'`, used where it applies): while no pulse acts (f = 0), the law's
  sliding coefficient depends on the direction only, the spring is linear and the plant is
  underdamped, each half cycle is a damped oscillation about the shifted equilibrium
  x_e = -s F / k; its reversal time is the first zero of the closed-form velocity, which is
  explicit: theta = (atan2(D, C) + pi / 2) mod pi for v ~ C cos(theta) + D sin(theta).
  Pulses still go through DOP853 (a few ms of integration per hit).
"""

import bisect
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.integrate import solve_ivp

from worlds.friction import FrictionLaw
from worlds.pulses import PlacedPulse
from worlds.world import Plant, World

RTOL = 1e-10
"""Relative tolerance of every DOP853 integration."""
ATOL = (1e-13, 1e-12)
"""Absolute tolerances of DOP853 on (position [m], velocity [m/s])."""
_BREAKAWAY_SCAN_POINTS = 513
METHODS = ('auto', 'general')
_FIRST_STEP_FROM_REST_S = 1e-9


@dataclass(frozen=True)
class PlantState:
    """Where the rig is at one instant: position, velocity and, at rest, since when."""

    position_m: float
    velocity_m_s: float = 0.0
    # Time [s] the mass last came to rest (dwell-time effects); None while it moves.
    stuck_since_s: float | None = None


@dataclass(frozen=True)
class MotionEvent:
    """A located instant of the motion: kind is 'break-away', 'reversal' or 'stick'."""

    time_s: float
    position_m: float
    kind: str


@dataclass(frozen=True)
class _Rest:
    start_s: float
    stop_s: float
    position_m: float

    def evaluate(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return np.full(t_s.shape, self.position_m), np.zeros(t_s.shape)


@dataclass(frozen=True)
class _FreeOscillation:
    """x = x_e + y, y'' + 2 a y' + w^2 y = 0 from (y0, v0) at start_s (underdamped)."""

    start_s: float
    stop_s: float
    equilibrium_m: float
    y0_m: float
    v0_m_s: float
    decay_per_s: float
    omega_rad_s: float

    @property
    def damped_omega(self) -> float:
        return math.sqrt(self.omega_rad_s**2 - self.decay_per_s**2)

    def _coefficients(self) -> tuple[float, float, float]:
        """(B, C, D): y = e^(-a tau)(y0 cos + B sin), v = e^(-a tau)(C cos + D sin)."""
        a, wd = self.decay_per_s, self.damped_omega
        return (
            (self.v0_m_s + a * self.y0_m) / wd,
            self.v0_m_s,
            -(a * self.v0_m_s + self.omega_rad_s**2 * self.y0_m) / wd,
        )

    def evaluate(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        tau = t_s - self.start_s
        b, c, d = self._coefficients()
        envelope = np.exp(-self.decay_per_s * tau)
        phase = self.damped_omega * tau
        cos, sin = envelope * np.cos(phase), envelope * np.sin(phase)
        return self.equilibrium_m + self.y0_m * cos + b * sin, c * cos + d * sin

    def first_reversal_s(self) -> float:
        """Time after start_s of the first zero of the velocity (explicit, see module)."""
        _, c, d = self._coefficients()
        theta = (math.atan2(d, c) + 0.5 * math.pi) % math.pi
        return (theta if theta > 0.0 else math.pi) / self.damped_omega

    def speed_bound_m_s(self, t_s: float) -> float:
        """An upper bound of |v| from t_s on (the envelope)."""
        _, c, d = self._coefficients()
        return math.hypot(c, d) * math.exp(-self.decay_per_s * (t_s - self.start_s))


@dataclass(frozen=True)
class _Integrated:
    start_s: float
    stop_s: float
    solution: Callable[[np.ndarray], np.ndarray]

    def evaluate(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        position, velocity = self.solution(t_s)
        return position, velocity


@dataclass
class Trajectory:
    """Position and velocity of one body over [start_s, stop_s], piecewise in continuous time."""

    start_s: float
    stop_s: float
    segments: list = field(default_factory=list)
    events: list[MotionEvent] = field(default_factory=list)

    def _add(self, segment) -> None:
        if segment.stop_s > segment.start_s:
            self.segments.append(segment)

    def evaluate(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(position [m], velocity [m/s]) at sorted times inside [start_s, stop_s].

        A scalar time gives 0-d arrays.
        """
        shape = np.shape(t_s)
        t_s = np.asarray(t_s, dtype=float).ravel()
        if t_s.size and (
            t_s[0] < self.start_s or t_s[-1] > self.stop_s or np.any(t_s[1:] < t_s[:-1])
        ):
            raise ValueError(f'times must be sorted and inside [{self.start_s}, {self.stop_s}] s')
        position, velocity = np.empty(t_s.shape), np.empty(t_s.shape)
        starts = np.searchsorted(t_s, [s.start_s for s in self.segments], 'left')
        stops = np.append(starts[1:], t_s.size)
        for segment, first, last in zip(self.segments, starts, stops, strict=True):
            if last > first:
                position[first:last], velocity[first:last] = segment.evaluate(t_s[first:last])
        return position.reshape(shape), velocity.reshape(shape)

    def active_windows(self, speed_tolerance_m_s: float = 0.0) -> list[tuple[float, float]]:
        """Merged [start, stop] spans outside which the body rests (speed below the tolerance).

        A free decay counts until its envelope falls below the tolerance: with the default 0
        every moving segment counts whole.
        """
        windows: list[list[float]] = []
        for segment in self.segments:
            start, stop = segment.start_s, segment.stop_s
            if isinstance(segment, _Rest):
                continue
            if isinstance(segment, _FreeOscillation) and speed_tolerance_m_s > 0:
                bound = segment.speed_bound_m_s(start)
                if bound <= speed_tolerance_m_s:
                    continue
                stop = min(
                    stop, start + math.log(bound / speed_tolerance_m_s) / segment.decay_per_s
                )
            elif isinstance(segment, _FreeOscillation) and segment.speed_bound_m_s(start) == 0:
                continue
            if windows and windows[-1][1] >= start:
                windows[-1][1] = max(windows[-1][1], stop)
            else:
                windows.append([start, stop])
        return [(a, b) for a, b in windows]

    def reversals(self) -> list[MotionEvent]:
        """Every instant the velocity reached zero (turning points and final stops)."""
        return [event for event in self.events if event.kind in ('reversal', 'stick')]


def _force_function(pulses: Sequence[PlacedPulse]) -> Callable[[float], float]:
    if not pulses:
        return lambda t: 0.0
    return lambda t: sum(p.pulse.force_at(t - p.start_s) for p in pulses)


def _force_intervals(
    pulses: Sequence[PlacedPulse], start_s: float, stop_s: float
) -> list[tuple[float, float, list[PlacedPulse]]]:
    """[a, b) pieces of [start_s, stop_s] with the pulses acting in each (empty: free)."""
    cuts = sorted(
        {
            start_s,
            stop_s,
            *(t for p in pulses for t in (p.start_s, p.stop_s) if start_s < t < stop_s),
        }
    )
    pieces = []
    for a, b in zip(cuts[:-1], cuts[1:], strict=True):
        middle = 0.5 * (a + b)
        pieces.append((a, b, [p for p in pulses if p.start_s <= middle <= p.stop_s]))
    return pieces


def _integrate(
    rhs,
    start_s: float,
    stop_s: float,
    state: Sequence[float],
    events: list,
    max_step: float,
    first_step: float | None = None,
):
    """DOP853 from `state`, stopping at the first terminal event; dense output kept."""
    return solve_ivp(
        rhs,
        (start_s, stop_s),
        list(state),
        method='DOP853',
        rtol=RTOL,
        atol=ATOL,
        events=events or None,
        dense_output=True,
        max_step=max_step,
        first_step=first_step,
    )


class _Solver:
    """One run of the stick-slip motion; see `simulate_motion`."""

    def __init__(self, world: World, pulses: Sequence[PlacedPulse], method: str) -> None:
        if method not in METHODS:
            raise ValueError(f'unknown method {method!r}; known: {", ".join(METHODS)}')
        self.plant: Plant = world.mechanics
        self.law: FrictionLaw = world.friction
        self.pulses = list(pulses)
        p = self.plant
        self.omega = math.sqrt(p.stiffness_n_per_m / p.mass_kg)
        self.decay = p.damping_n_s_per_m / (2.0 * p.mass_kg)
        self.closed_form = (
            method == 'auto' and p.cubic_stiffness_n_per_m3 == 0.0 and self.decay < self.omega
        )
        self.max_step = 0.05 / p.natural_frequency_hz

    def net_force_n(self, force_n: float, position_m: float) -> float:
        return force_n - self.plant.spring_force_n(position_m)

    def settle(self, trajectory: Trajectory, t: float, x: float, force_n: float) -> int:
        """Stick test at a velocity zero: 0 if the mass sticks, else the new direction."""
        net = self.net_force_n(force_n, x)
        direction = 1 if net > 0 else -1
        if abs(net) <= self.plant.normal_force_n * self.law.static_mu(direction, x, 0.0):
            trajectory.events.append(MotionEvent(t, x, 'stick'))
            return 0
        return direction

    def breakaway_s(
        self, pulses: list[PlacedPulse], a: float, b: float, x: float, since: float
    ) -> float | None:
        """First instant in [a, b] the net force leaves the static band, or None.

        Scanned on a grid over the interval (a pulse: a few microseconds apart), the first
        crossing refined by bisection to rounding, keeping the side where the force already
        exceeds the band (so the mass does accelerate from the returned instant).
        """
        spring = self.plant.spring_force_n(x)
        normal = self.plant.normal_force_n

        def excess(t: np.ndarray | float) -> np.ndarray:
            net = sum((p.force_n(t) for p in pulses), -spring)
            dwell = np.asarray(t) - since
            limit = np.where(
                net > 0, self.law.static_mu(1, x, dwell), self.law.static_mu(-1, x, dwell)
            )
            return np.abs(net) - normal * limit

        grid = np.linspace(a, b, _BREAKAWAY_SCAN_POINTS)
        above = np.flatnonzero(excess(grid) > 0.0)
        if not above.size:
            return None
        i = int(above[0])
        if i == 0:
            return a
        below, beyond = float(grid[i - 1]), float(grid[i])
        while True:
            middle = 0.5 * (below + beyond)
            if middle in (below, beyond):
                return beyond
            if excess(middle) > 0.0:
                beyond = middle
            else:
                below = middle

    def slide_closed_form(
        self, trajectory: Trajectory, direction: int, t: float, b: float, x: float, v: float
    ) -> tuple[float, float, float, bool]:
        """One half cycle (or up to b) in closed form: (t, x, v, reached_zero_velocity)."""
        friction_n = self.plant.normal_force_n * self.law.constant_sliding_mu(direction)
        equilibrium = -direction * friction_n / self.plant.stiffness_n_per_m
        piece = _FreeOscillation(t, b, equilibrium, x - equilibrium, v, self.decay, self.omega)
        reversal = t + piece.first_reversal_s()
        end = min(reversal, b)
        piece = replace(piece, stop_s=end)
        trajectory._add(piece)
        position, velocity = piece.evaluate(np.array([end]))
        if reversal <= b:
            return end, float(position[0]), 0.0, True
        return end, float(position[0]), float(velocity[0]), False

    def slide_ode(
        self,
        trajectory: Trajectory,
        direction: int,
        pulses: list[PlacedPulse],
        t: float,
        b: float,
        x: float,
        v: float,
    ) -> tuple[float, float, float, bool]:
        """Integrate sliding towards `direction` until v = 0 or b: (t, x, v, stopped).

        Between two jumps of the law in position (`position_breaks_m`) the law is read at the
        position clamped inside the current piece, so the right-hand side stays smooth even in
        a step that straddles the next jump; a terminal event stops on the jump, and the next
        piece starts there.
        """
        p, law, force = self.plant, self.law, _force_function(pulses)
        normal, s = p.normal_force_n, direction
        breaks = law.position_breaks_m

        def stop(time: float, z: np.ndarray) -> float:
            return z[1]

        stop.terminal, stop.direction = True, -s
        while True:
            i = (bisect.bisect_right if s > 0 else bisect.bisect_left)(breaks, x)
            low = breaks[i - 1] if i > 0 else -math.inf
            high = breaks[i] if i < len(breaks) else math.inf
            inner = (math.nextafter(low, math.inf), math.nextafter(high, -math.inf))

            def rhs(time: float, z: np.ndarray, inner=inner) -> tuple[float, float]:
                position, velocity = z
                mu = law.sliding_mu(s, abs(velocity), min(max(position, inner[0]), inner[1]))
                return velocity, (
                    force(time)
                    - p.damping_n_s_per_m * velocity
                    - p.spring_force_n(position)
                    - s * normal * mu
                ) / p.mass_kg

            events = [stop]
            edge = high if s > 0 else low
            if math.isfinite(edge):

                def crossing(time: float, z: np.ndarray, edge: float = edge) -> float:
                    return z[0] - edge

                crossing.terminal, crossing.direction = True, s
                events.append(crossing)
            # From rest under a pulse the first step is 1 ns: a mass released just as the pulse
            # starts pushing the other way moves for microseconds before it reverses, and a
            # longer first step would put that reversal at the start instant.
            first_step = _FIRST_STEP_FROM_REST_S if v == 0.0 and pulses else None
            result = _integrate(rhs, t, b, (x, v), events, self.max_step, first_step)
            if result.status < 0:
                raise RuntimeError(f'DOP853 failed at t = {t} s: {result.message}')
            trajectory._add(_Integrated(t, float(result.t[-1]), result.sol))
            if result.status == 0:
                return b, float(result.y[0, -1]), float(result.y[1, -1]), False
            fired = min((times[0], i) for i, times in enumerate(result.t_events) if times.size)
            t, index = float(fired[0]), fired[1]
            x, v = (float(value) for value in result.y_events[index][0])
            if index == 0:
                return t, x, 0.0, True
            # The crossing state from a step rather than the dense interpolant (1e-10 better).
            if result.t.size > 2:
                v = float(
                    _integrate(rhs, float(result.t[-2]), t, result.y[:, -2], [], self.max_step).y[
                        1, -1
                    ]
                )
            x = edge

    def run(
        self, start_s: float, stop_s: float, state: PlantState
    ) -> tuple[Trajectory, PlantState]:
        trajectory = Trajectory(start_s, stop_s)
        t, x, v = start_s, float(state.position_m), float(state.velocity_m_s)
        since = state.stuck_since_s if state.stuck_since_s is not None else start_s
        direction = 0 if v == 0.0 else (1 if v > 0 else -1)
        if direction == 0:
            direction = self._start_direction(x, _force_function(self.pulses)(start_s))
            if direction:
                trajectory.events.append(MotionEvent(t, x, 'break-away'))
        for a, b, acting in _force_intervals(self.pulses, start_s, stop_s):
            t = a
            while t < b:
                if direction == 0:
                    moment = self.breakaway_s(acting, t, b, x, since) if acting else None
                    if moment is None:
                        trajectory._add(_Rest(t, b, x))
                        t = b
                        continue
                    trajectory._add(_Rest(t, moment, x))
                    t = moment
                    net = self.net_force_n(_force_function(acting)(t), x)
                    direction = 1 if net > 0 else -1
                    trajectory.events.append(MotionEvent(t, x, 'break-away'))
                    continue
                closed = (
                    self.closed_form
                    and not acting
                    and self.law.constant_sliding_mu(direction) is not None
                )
                slide = self.slide_closed_form if closed else self.slide_ode
                args = (direction, t, b, x, v) if closed else (direction, acting, t, b, x, v)
                moved_from = t
                t, x, v, stopped = slide(trajectory, *args)
                if stopped and t == moved_from and v == 0.0:
                    raise RuntimeError(
                        f'no motion from the velocity zero at t = {t} s: the '
                        'friction law has kinetic above static friction'
                    )
                if stopped:
                    force = _force_function(acting)(t)
                    direction = self.settle(trajectory, t, x, force)
                    if direction:
                        trajectory.events.append(MotionEvent(t, x, 'reversal'))
                    else:
                        since = t
        final = PlantState(x, v if direction else 0.0, None if direction else since)
        return trajectory, final

    def _start_direction(self, x: float, force_n: float) -> int:
        """At rest at the start: 0 if it holds, else the direction it is released towards."""
        net = self.net_force_n(force_n, x)
        direction = 1 if net > 0 else -1
        limit = self.plant.normal_force_n * self.law.static_mu(direction, x, 0.0)
        return direction if abs(net) > limit else 0


def simulate_motion(
    world: World,
    pulses: Sequence[PlacedPulse],
    start_s: float,
    stop_s: float,
    state: PlantState,
    *,
    method: str = 'auto',
) -> tuple[Trajectory, PlantState]:
    """The rig's motion over [start_s, stop_s] from `state` under the hammer `pulses`.

    Returns the continuous trajectory and the state at stop_s. A state at rest whose position
    lies outside the static band is released there (the paper's initial-displacement test).
    `method`: 'auto' solves force-free half cycles in closed form where the law allows it,
    'general' integrates everything with DOP853 (the check on 'auto').
    """
    if not stop_s > start_s:
        raise ValueError(f'stop_s ({stop_s}) must be after start_s ({start_s})')
    return _Solver(world, pulses, method).run(start_s, stop_s, state)


def linear_response(
    mass_kg: float,
    damping_n_s_per_m: float,
    stiffness_n_per_m: float,
    pulses: Sequence[PlacedPulse],
    start_s: float,
    stop_s: float,
) -> Trajectory:
    """Response of a linear mode at rest at start_s to the pulses: DOP853 while a pulse acts,
    the closed-form free decay in between."""
    omega = math.sqrt(stiffness_n_per_m / mass_kg)
    decay = damping_n_s_per_m / (2.0 * mass_kg)
    if not decay < omega:
        raise ValueError('linear_response needs an underdamped mode')
    trajectory = Trajectory(start_s, stop_s)
    x = v = 0.0
    for a, b, acting in _force_intervals(pulses, start_s, stop_s):
        if not acting:
            piece = _FreeOscillation(a, b, 0.0, x, v, decay, omega)
            trajectory._add(piece)
            (x,), (v,) = piece.evaluate(np.array([b]))
            continue
        force = _force_function(acting)

        def rhs(time: float, z: np.ndarray, force=force) -> tuple[float, float]:
            return z[1], (
                force(time) - damping_n_s_per_m * z[1] - stiffness_n_per_m * z[0]
            ) / mass_kg

        result = _integrate(rhs, a, b, (x, v), [], 0.05 * 2.0 * math.pi / omega)
        trajectory._add(_Integrated(a, b, result.sol))
        x, v = float(result.y[0, -1]), float(result.y[1, -1])
    return trajectory
