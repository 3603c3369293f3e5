"""The rig as a friction oscillator, and its motion by two independent integrators.

    m x'' + c x' + k x + k3 x^3 = f(t) - F_friction,

with a contact whose coefficient may depend on the sliding direction (asymmetry), on speed
(Stribeck: mu_k(v) = mu_dir + dmu exp(-(v/vs)^2)) and on position (a wear track,
mu_dir (1 + a sin(2 pi x / lambda + phi))); static friction is mu_k(0). Where the velocity
reaches zero the mass sticks while |f - k x - k3 x^3| stays within static friction, and breaks
away once it leaves it.

- `solve_events`: event-located. Each slide (one direction, smooth right-hand side) is
  integrated by scipy's DOP853 at rtol 1e-11 to the zero of the velocity, located as an event;
  spans are split at the hit's edges (where the force is not smooth); a stick is held in
  closed form and its breakaway, if the force is still acting, found by root bracketing.
- `solve_steps`: a fine fixed step (RK4 at `STEP_HZ`), the stick rule applied where the
  velocity changes sign inside a step (the crossing interpolated, the step redone from it).

Both return a `Motion`: position and velocity at any times, and where the mass came to rest.
Nothing here uses the product: rig constants are the paper's numbers, written again.
"""

import math
from dataclasses import dataclass, field

import numba
import numpy as np
import scipy.integrate
import scipy.interpolate
import scipy.optimize

from heldout.forces import Hit

GRAVITY_M_S2 = 9.81


@dataclass(frozen=True)
class Plant:
    """The FMM's constants (the paper's): mass, stiffness, damping, normal load; cubic spring."""

    mass_kg: float = 10.391
    stiffness_n_per_m: float = 1982.0
    damping_n_s_per_m: float = 0.275
    normal_n: float = 0.680 * GRAVITY_M_S2
    cubic_n_per_m3: float = 0.0

    def spring_n(self, x: float | np.ndarray) -> float | np.ndarray:
        """Spring force k x + k3 x^3 [N]."""
        return self.stiffness_n_per_m * x + self.cubic_n_per_m3 * x**3


@dataclass(frozen=True)
class Contact:
    """The friction law: direction, speed and position dependence."""

    mu: float
    asymmetry: float = 0.0
    """mu in +x minus mu in -x (their mean is mu)."""
    static_excess: float = 0.0
    stribeck_speed_m_s: float = 2e-3
    track_amplitude: float = 0.0
    track_wavelength_m: float = 6e-3
    track_phase: float = 0.0

    def base(self, direction: float, x: float) -> float:
        """The sliding coefficient in a direction at a position, before Stribeck."""
        mu = self.mu + 0.5 * self.asymmetry * direction
        if self.track_amplitude:
            mu *= 1.0 + self.track_amplitude * math.sin(
                2.0 * math.pi * x / self.track_wavelength_m + self.track_phase
            )
        return mu

    def kinetic(self, direction: float, speed: float, x: float) -> float:
        """The coefficient while sliding at a speed [m/s]."""
        excess = self.static_excess * math.exp(-((speed / self.stribeck_speed_m_s) ** 2))
        return self.base(direction, x) + excess

    def static(self, direction: float, x: float) -> float:
        """The coefficient that holds a stuck mass against a push in a direction."""
        return self.base(direction, x) + self.static_excess


@dataclass
class Motion:
    """A trajectory: slides as dense solutions or samples, sticks as held positions."""

    start_s: float
    x0_m: float
    pieces: list = field(default_factory=list)
    """(t0, t1, kind, data): 'rest' (data: the position) or 'slide' (data: t -> (x, v))."""
    rest_s: float = math.inf
    rest_m: float = math.nan

    def evaluate(self, time_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(position [m], velocity [m/s]) at the times (before the start: at rest at x0)."""
        t = np.asarray(time_s, dtype=float)
        x = np.full(t.shape, self.x0_m)
        v = np.zeros(t.shape)
        for t0, t1, kind, data in self.pieces:
            inside = (t >= t0) & (t < t1)
            if not inside.any():
                continue
            if kind == 'rest':
                x[inside] = data
                v[inside] = 0.0
            else:
                x[inside], v[inside] = data(t[inside])
        after = t >= self.rest_s
        x[after] = self.rest_m
        v[after] = 0.0
        return x, v


def _net_force(plant: Plant, hit: Hit, t: float, x: float) -> float:
    return hit.force_at(t) - plant.spring_n(x)


def _breakaway(plant: Plant, contact: Contact, hit: Hit, t: float, x: float) -> tuple[float, int]:
    """(time, direction) a mass stuck at x from t starts to slide, or (inf, 0) if never."""
    end = hit.end_s
    if t >= end:
        net = -plant.spring_n(x)
        for direction in (1, -1):
            if direction * net > plant.normal_n * contact.static(direction, x):
                return t, direction
        return math.inf, 0

    def excess(time: float) -> float:
        net = _net_force(plant, hit, time, x)
        direction = 1 if net >= 0.0 else -1
        return abs(net) - plant.normal_n * contact.static(direction, x)

    grid = np.linspace(t, end, 400)
    values = np.array([excess(g) for g in grid])
    above = np.flatnonzero(values > 0.0)
    if above.size == 0:
        # the hit is over and the spring alone does not break the stick
        return _breakaway(plant, contact, hit, end, x) if end > t else (math.inf, 0)
    i = int(above[0])
    when = (
        grid[0]
        if i == 0
        else scipy.optimize.brentq(excess, grid[i - 1], grid[i], xtol=1e-13, rtol=1e-14)
    )
    net = _net_force(plant, hit, min(when + 1e-12, end), x)
    return float(when), 1 if net >= 0.0 else -1


def solve_events(plant: Plant, contact: Contact, hit: Hit, x0_m: float, stop_s: float) -> Motion:
    """The motion after a hit by event-located DOP853 slides (module doc)."""
    motion = Motion(hit.onset_s, x0_m)
    t, x = hit.onset_s, x0_m
    m, c, n = plant.mass_kg, plant.damping_n_s_per_m, plant.normal_n
    while t < stop_s:
        when, direction = _breakaway(plant, contact, hit, t, x)
        if not math.isfinite(when) or when >= stop_s:
            motion.pieces.append((t, stop_s, 'rest', x))
            motion.rest_s, motion.rest_m = t, x
            return motion
        if when > t:
            motion.pieces.append((t, when, 'rest', x))
        t, v = when, 0.0
        if when >= hit.end_s and _piecewise_linear(plant, contact):
            t, x = _closed_form_slide(motion, plant, contact, t, x, 0.0, direction)
            continue

        def rhs(time, z, s=direction):
            speed = abs(z[1])
            friction = s * n * contact.kinetic(s, speed, z[0])
            return (z[1], (hit.force_at(time) - c * z[1] - plant.spring_n(z[0]) - friction) / m)

        def reverses(time, z):
            return z[1]

        reverses.terminal = True
        reverses.direction = -direction
        state = np.array([x, v])
        edges = [e for e in (hit.onset_s, hit.end_s) if t < e < stop_s] + [stop_s]
        start = t
        stopped = False
        for edge in edges:
            solution = scipy.integrate.solve_ivp(
                rhs,
                (t, edge),
                state,
                method='DOP853',
                rtol=1e-11,
                atol=(1e-13, 1e-12),
                dense_output=True,
                events=reverses,
                max_step=2e-3,
            )
            motion.pieces.append((t, float(solution.t[-1]), 'slide', _dense(solution)))
            t, state = float(solution.t[-1]), solution.y[:, -1].copy()
            if solution.status == 1:
                stopped = True
                break
        if t <= start:
            raise RuntimeError('the event solver made no progress')
        x = float(state[0])
        if not stopped:
            motion.rest_s, motion.rest_m = math.inf, math.nan
            return motion
    return motion


def _piecewise_linear(plant: Plant, contact: Contact) -> bool:
    """Whether a slide with the hit over is linear with constant friction (closed form)."""
    return not (plant.cubic_n_per_m3 or contact.static_excess or contact.track_amplitude)


def _closed_form_slide(
    motion: Motion, plant: Plant, contact: Contact, t: float, x: float, v: float, s: int
) -> tuple[float, float]:
    """One slide with no force acting, in closed form to its reversal: (time, position) there.

    m x'' + c x' + k x = -s mu_s N about the centre xc = -s mu_s N / k: x = xc + e^{-a tau}
    (A cos w tau + B sin w tau); the velocity's first zero after tau = 0 ends the slide.
    """
    m, k = plant.mass_kg, plant.stiffness_n_per_m
    a = plant.damping_n_s_per_m / (2.0 * m)
    w = math.sqrt(k / m - a * a)
    centre = -s * plant.normal_n * contact.base(s, 0.0) / k
    big_a = x - centre
    big_b = (v + a * big_a) / w
    p, q = big_b * w - a * big_a, big_a * w + a * big_b
    phase = math.atan2(q, p)
    tau = (0.5 * math.pi - phase) % math.pi
    if tau < 1e-12:
        tau += math.pi
    tau /= w

    def evaluate(time_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        u = time_s - t
        envelope = np.exp(-a * u)
        cos, sin = np.cos(w * u), np.sin(w * u)
        return (
            centre + envelope * (big_a * cos + big_b * sin),
            envelope * (p * cos - q * sin),
        )

    end = t + tau
    motion.pieces.append((t, end, 'slide', evaluate))
    return end, float(evaluate(np.array([end]))[0][0])


def _dense(solution):
    def evaluate(time_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        z = solution.sol(time_s)
        return z[0], z[1]

    return evaluate


STEP_HZ = 200_000.0
"""The fixed step's rate: 20 steps per 10 kHz sample."""


def solve_steps(plant: Plant, contact: Contact, hit: Hit, x0_m: float, stop_s: float) -> Motion:
    """The motion after a hit by fixed RK4 steps at STEP_HZ with the stick rule (module doc).

    The trajectory is kept on the step grid and read between steps by cubic Hermite
    interpolation (position with its velocity, velocity with its acceleration).
    """
    shape = ('half_sine', 'hertz', 'double_exponential').index(hit.shape)
    amplitude = hit._amplitude() if hit.shape == 'double_exponential' else hit.peak_n
    times, xs, vs, accs, count = _rk4_run(
        np.array(
            [
                plant.mass_kg,
                plant.damping_n_s_per_m,
                plant.stiffness_n_per_m,
                plant.cubic_n_per_m3,
                plant.normal_n,
            ]
        ),
        np.array(
            [
                contact.mu,
                contact.asymmetry,
                contact.static_excess,
                contact.stribeck_speed_m_s,
                contact.track_amplitude,
                contact.track_wavelength_m,
                contact.track_phase,
            ]
        ),
        np.array(
            [
                shape,
                amplitude,
                hit.contact_s,
                hit.onset_s,
                hit.end_s,
                hit.rise_ratio * hit.contact_s,
            ]
        ),
        x0_m,
        stop_s,
        1.0 / STEP_HZ,
    )
    times, xs, vs, accs = times[:count], xs[:count], vs[:count], accs[:count]
    motion = Motion(hit.onset_s, x0_m)
    position = scipy.interpolate.CubicHermiteSpline(times, xs, vs)
    velocity = scipy.interpolate.CubicHermiteSpline(times, vs, accs)
    motion.pieces.append(
        (float(times[0]), float(times[-1]), 'slide', lambda t: (position(t), velocity(t)))
    )
    motion.rest_s, motion.rest_m = float(times[-1]), float(xs[-1])
    return motion


@numba.njit(cache=True)
def _force(hit: np.ndarray, t: float) -> float:
    u = t - hit[3]
    if u <= 0.0 or t >= hit[4]:
        return 0.0
    if hit[0] == 0.0:
        return hit[1] * math.sin(math.pi * u / hit[2])
    if hit[0] == 1.0:
        return hit[1] * math.sin(math.pi * u / hit[2]) ** 1.5
    return hit[1] * (math.exp(-u / hit[2]) - math.exp(-u / hit[5]))


@numba.njit(cache=True)
def _base_mu(contact: np.ndarray, s: float, x: float) -> float:
    mu = contact[0] + 0.5 * contact[1] * s
    if contact[4] != 0.0:
        mu *= 1.0 + contact[4] * math.sin(2.0 * math.pi * x / contact[5] + contact[6])
    return mu


@numba.njit(cache=True)
def _acceleration(plant, contact, hit, t, x, v, s):
    excess = contact[2] * math.exp(-((abs(v) / contact[3]) ** 2))
    friction = s * plant[4] * (_base_mu(contact, s, x) + excess)
    spring = plant[2] * x + plant[3] * x**3
    return (_force(hit, t) - plant[1] * v - spring - friction) / plant[0]


@numba.njit(cache=True)
def _rk4_run(plant, contact, hit, x0, stop, h):
    size = int((stop - hit[3]) / h) + 1000
    times, xs, vs, accs = np.empty(size), np.empty(size), np.empty(size), np.empty(size)
    t, x, v = hit[3], x0, 0.0
    times[0], xs[0], vs[0], accs[0] = t, x, v, 0.0
    count, stuck, s = 1, True, 0.0
    while t < stop and count < size:
        if stuck:
            net = _force(hit, t) - plant[2] * x - plant[3] * x**3
            s = 1.0 if net >= 0.0 else -1.0
            if abs(net) <= plant[4] * (_base_mu(contact, s, x) + contact[2]):
                if t >= hit[4]:
                    break
                t += h
                times[count], xs[count], vs[count], accs[count] = t, x, 0.0, 0.0
                count += 1
                continue
            stuck = False
        k1v = _acceleration(plant, contact, hit, t, x, v, s)
        k1x = v
        k2v = _acceleration(
            plant, contact, hit, t + 0.5 * h, x + 0.5 * h * k1x, v + 0.5 * h * k1v, s
        )
        k2x = v + 0.5 * h * k1v
        k3v = _acceleration(
            plant, contact, hit, t + 0.5 * h, x + 0.5 * h * k2x, v + 0.5 * h * k2v, s
        )
        k3x = v + 0.5 * h * k2v
        k4v = _acceleration(plant, contact, hit, t + h, x + h * k3x, v + h * k3v, s)
        k4x = v + h * k3v
        x_new = x + h / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x)
        v_new = v + h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v)
        if v_new * s < 0.0:
            # the velocity reached zero inside the step: end the step at the crossing
            step = h * v / (v - v_new)
            if step <= 1e-12:
                stuck = True
                v = 0.0
                continue
            x = x + v * step + 0.5 * k1v * step * step
            t, v, stuck = t + step, 0.0, True
            accs[count] = 0.0
        else:
            t, x, v = t + h, x_new, v_new
            accs[count] = _acceleration(plant, contact, hit, t, x, v, s)
        times[count], xs[count], vs[count] = t, x, v
        count += 1
    return times, xs, vs, accs, count
