"""Compiled time-stepping loops of the physics core; use them through `fmm_ros.core.physics`.

The oscillator is m x'' + c x' + k x + k3 x^3 + s F(s, |x'|) = f(t), where s = sgn(x') is the
sliding direction and F the friction force magnitude (kinetic, per direction, plus an optional
Stribeck excess that decays with speed). A resting mass (s = 0) stays put while the net applied
force g = f - k x - k3 x^3 lies within the static band [-Fs-, Fs+]; it breaks away in the
direction of g once g leaves the band.

Inter-sample assumption: the force is linear between samples (first-order hold). Every loop
advances one sample interval at a time, so its result does not depend on how a record is cut
into batches: the state carried between calls (`STATE_*` slots) is all it needs.

Event handling inside a sample interval, shared by the exact and the RK4 paths:
- break-away from rest: g is linear in time (x is fixed), so the crossing of the band edge is
  located in closed form;
- reversal / stop of a sliding mass: the velocity over a segment is bracketed by the cubic
  Hermite interpolant of (v, a) at its two ends, whose first non-positive point (in the sliding
  direction) is found on its monotone pieces, then polished by Newton steps on the true
  trajectory of the path (closed form or RK4); the stick test is applied at that instant.
"""

import math

import numpy as np
from numba import njit

# Slots of the parameter vector (float64[PARAM_SIZE]) built by model.py.
MASS = 0
DAMPING = 1
STIFFNESS = 2
CUBIC = 3
FRICTION_POS = 4  # kinetic friction force [N] opposing sliding in +x
FRICTION_NEG = 5  # kinetic friction force [N] opposing sliding in -x
STATIC_EXCESS = 6  # Stribeck: static minus kinetic friction force [N], both directions
STRIBECK_V = 7  # Stribeck velocity [m/s]
STEP = 8  # sample period h [s]
SUBSTEPS = 9  # RK4 segments per sample interval (nonlinear path)
NONLINEAR = 10  # 0: closed-form path (piecewise linear), 1: RK4 path, 2: RK4 near rest only
PHI = 11  # 4 slots: exact step matrix, row-major (x, v) <- (x, v)
GAMMA_U0 = 15  # 2 slots: response of (x, v) to the input at the interval start
GAMMA_DU = 17  # 2 slots: response of (x, v) to the input change over the interval
STRIBECK_DELTA = 19  # Stribeck shape exponent delta: excess x exp(-(|v|/vs)^delta) [-]
STRIBECK_FLAT_RATIO = 20  # |v|/vs above which the excess is below rounding: 36^(1/delta)
STRIBECK_ZONE_RATIO = 21  # |v|/vs below which RK4 segments resolve the excess: 16^(1/delta)
PARAM_SIZE = 22

# Slots of the state vector (float64[STATE_SIZE]) carried between calls.
STATE_X = 0  # displacement [m]
STATE_V = 1  # velocity [m/s]
STATE_MODE = 2  # +1 / -1 sliding, 0 at rest
STATE_REST_TIME = 3  # time the current rest began [s], NaN while sliding
STATE_INDEX = 4  # number of samples produced so far
STATE_FORCE = 5  # last force sample [N]
STATE_SIZE = 6

# Slots of a linear mode's vector (float64[MODE_SIZE]): state, then its exact step.
MODE_X = 0
MODE_V = 1
MODE_PHI = 2
MODE_GAMMA_U0 = 6
MODE_GAMMA_DU = 8
MODE_SIZE = 10

# Samples a stretch at rest is tested in at once (without a branch per sample).
REST_BLOCK = 64

# Velocity samples zeroed ahead for each sliding step (`oscillator_exact`).
ZERO_AHEAD = 16

# Samples of a delayed signal computed at once (their sources copied to a buffer first).
DELAY_CHUNK = 1024

MAX_FLOAT = 1.7976931348623157e308  # the largest finite float64

# More events than this inside one sample interval means chattering at rounding level: the
# mass is then held at rest for the rest of that interval.
MAX_EVENTS_PER_INTERVAL = 64

# Below STRIBECK_ZONE_RATIO * vs (4 vs for the Gaussian shape, delta = 2: where
# (v/vs)^delta = 16) the RK4 segments shrink to STRIBECK_STEP times the time the speed takes
# to cross vs, over which the Stribeck excess exp(-(v/vs)^delta) changes appreciably (for
# delta < 2 it changes more slowly above vs, so vs is the finer scale there).
STRIBECK_STEP = 0.2

# Above STRIBECK_FLAT_RATIO * vs (6 vs for delta = 2: where (v/vs)^delta = 36) the Stribeck
# excess, exp(-36) = 2.3e-16 of itself, is below the rounding of the kinetic friction it is
# added to: a Stribeck contact without a cubic spring (NONLINEAR 2) slides there on the
# closed-form path (exact where RK4 errs by a few 1e-13 m/s), and only nearer rest on RK4.
# The RK4 path ran a 30-hit Stribeck diagnosis's refit.
STRIBECK_FLAT = 6.0


@njit(cache=True)
def _spring(x, p):
    """Spring force [N] at displacement x: linear plus cubic."""
    return p[STIFFNESS] * x + p[CUBIC] * x * x * x


@njit(cache=True)
def _friction(sigma, v, p):
    """Friction force magnitude [N] while sliding in direction sigma at velocity v."""
    force = p[FRICTION_POS] if sigma > 0 else p[FRICTION_NEG]
    if p[STATIC_EXCESS] != 0.0:
        ratio = v / p[STRIBECK_V]
        if p[STRIBECK_DELTA] == 2.0:  # the Gaussian shape, squared rather than powered
            if ratio * ratio < STRIBECK_FLAT * STRIBECK_FLAT:  # else below rounding (above)
                force += p[STATIC_EXCESS] * math.exp(-ratio * ratio)
        else:
            ratio = abs(ratio)
            if ratio < p[STRIBECK_FLAT_RATIO]:
                force += p[STATIC_EXCESS] * math.exp(-(ratio ** p[STRIBECK_DELTA]))
    return force


@njit(cache=True)
def _break_direction(g, p):
    """0 if a resting mass stays put under net applied force g [N], else the way it slides."""
    if g > p[FRICTION_POS] + p[STATIC_EXCESS]:
        return 1
    if g < -(p[FRICTION_NEG] + p[STATIC_EXCESS]):
        return -1
    return 0


@njit(cache=True)
def _accel(x, v, f, sigma, p):
    """Acceleration [m/s^2] while sliding in direction sigma under applied force f."""
    return (f - p[DAMPING] * v - _spring(x, p) - sigma * _friction(sigma, v, p)) / p[MASS]


@njit(cache=True)
def _closed_form(x, v, u0, du_dt, tau, m, c, k):
    """State after tau of m x'' + c x' + k x = u0 + du_dt t (exact, any damping ratio).

    Particular solution x_p = (u0 - c du_dt / k + du_dt t) / k, plus the free response of the
    deviation: e^{At} = e^{-a t} [C(t) I + S(t) (A + a I)], a = c / 2m, with C, S the cos/sin
    (underdamped), cosh/sinh (overdamped) or 1/t (critical) pair of b^2 = k/m - a^2.
    """
    xp0 = (u0 - c * du_dt / k) / k
    vp = du_dt / k
    y = x - xp0
    w = v - vp
    alpha = 0.5 * c / m
    w0sq = k / m
    beta2 = w0sq - alpha * alpha
    if beta2 > 0.0:
        beta = math.sqrt(beta2)
        cos_t = math.cos(beta * tau)
        sin_t = math.sin(beta * tau) / beta
    elif beta2 < 0.0:
        beta = math.sqrt(-beta2)
        cos_t = math.cosh(beta * tau)
        sin_t = math.sinh(beta * tau) / beta
    else:
        cos_t = 1.0
        sin_t = tau
    decay = math.exp(-alpha * tau)
    xh = decay * (cos_t * y + sin_t * (alpha * y + w))
    vh = decay * (cos_t * w - sin_t * (w0sq * y + alpha * w))
    return xh + xp0 + vp * tau, vh + vp


@njit(cache=True)
def _rk4(x, v, a1, f0, df_dt, tau, sigma, p):
    """One classical Runge-Kutta step of length tau at fixed sliding direction sigma.

    a1: the acceleration at the start, `_accel(x, v, f0, sigma, p)`, which the caller has
    (`_interval` judges the segment by it): one evaluation of the friction fewer a step.
    """
    half = 0.5 * tau
    f_mid = f0 + df_dt * half
    v2 = v + half * a1
    a2 = _accel(x + half * v, v2, f_mid, sigma, p)
    v3 = v + half * a2
    a3 = _accel(x + half * v2, v3, f_mid, sigma, p)
    v4 = v + tau * a3
    a4 = _accel(x + tau * v3, v4, f0 + df_dt * tau, sigma, p)
    sixth = tau / 6.0
    return (x + sixth * (v + 2.0 * v2 + 2.0 * v3 + v4), v + sixth * (a1 + 2.0 * a2 + 2.0 * a3 + a4))


@njit(cache=True)
def _slide(x, v, a0, f0, df_dt, tau, sigma, p):
    """State after sliding for tau in direction sigma: closed form or RK4, per the path.

    a0: the acceleration at the start (`_rk4`'s a1). On NONLINEAR 2 the closed form where the
    speed stays above STRIBECK_FLAT_RATIO * vs.
    """
    if p[NONLINEAR] == 2.0:
        flat = p[STRIBECK_FLAT_RATIO] * p[STRIBECK_V]
        if sigma * v >= flat:
            xe, ve = _kinetic_slide(x, v, f0, df_dt, tau, sigma, p)
            if sigma * ve >= flat:
                return xe, ve
        return _rk4(x, v, a0, f0, df_dt, tau, sigma, p)
    if p[NONLINEAR] != 0.0:
        return _rk4(x, v, a0, f0, df_dt, tau, sigma, p)
    return _kinetic_slide(x, v, f0, df_dt, tau, sigma, p)


@njit(cache=True)
def _kinetic_slide(x, v, f0, df_dt, tau, sigma, p):
    """State after sliding for tau against the kinetic friction alone (closed form)."""
    u0 = f0 - sigma * (p[FRICTION_POS] if sigma > 0 else p[FRICTION_NEG])
    return _closed_form(x, v, u0, df_dt, tau, p[MASS], p[DAMPING], p[STIFFNESS])


@njit(cache=True)
def _cubic(c0, c1, c2, c3, t):
    return c0 + t * (c1 + t * (c2 + t * c3))


@njit(cache=True)
def _first_stop(p0, d0, p1, d1, length):
    """First time in [0, length] where the Hermite cubic of (p, p') reaches <= 0, else -1.

    p is the velocity in the sliding direction (p0 >= 0); d0, d1 its slopes at the ends. The
    cubic is split at its stationary points into monotone pieces, searched in order.
    """
    if p0 == 0.0 and d0 < 0.0:
        d0 = 0.0  # a mass leaving rest accelerates the way it slides (rounding aside)
    c0 = p0
    c1 = length * d0
    c2 = 3.0 * (p1 - p0) - length * (2.0 * d0 + d1)
    c3 = 2.0 * (p0 - p1) + length * (d0 + d1)
    # Stationary points: roots of 3 c3 t^2 + 2 c2 t + c1 inside (0, 1), ascending.
    bounds = np.empty(3)
    count = 0
    qa = 3.0 * c3
    qb = 2.0 * c2
    if qa != 0.0:
        disc = qb * qb - 4.0 * qa * c1
        if disc > 0.0:
            root = math.sqrt(disc)
            r1 = (-qb - root) / (2.0 * qa)
            r2 = (-qb + root) / (2.0 * qa)
            if r1 > r2:
                r1, r2 = r2, r1
            if 0.0 < r1 < 1.0:
                bounds[count] = r1
                count += 1
            if 0.0 < r2 < 1.0:
                bounds[count] = r2
                count += 1
    elif qb != 0.0:
        r1 = -c1 / qb
        if 0.0 < r1 < 1.0:
            bounds[count] = r1
            count += 1
    bounds[count] = 1.0
    count += 1
    t_lo = 0.0
    p_lo = c0
    for j in range(count):
        t_hi = bounds[j]
        p_hi = _cubic(c0, c1, c2, c3, t_hi)
        if p_hi <= 0.0:
            if p_lo <= 0.0:
                return t_lo * length
            for _ in range(60):  # bisection on a monotone piece: p(t_lo) > 0 >= p(t_hi)
                t_mid = 0.5 * (t_lo + t_hi)
                if t_mid <= t_lo or t_mid >= t_hi:
                    break
                if _cubic(c0, c1, c2, c3, t_mid) > 0.0:
                    t_lo = t_mid
                else:
                    t_hi = t_mid
            return t_hi * length
        t_lo = t_hi
        p_lo = p_hi
    return -1.0


@njit(cache=True)
def _polish_stop(x, v, a0, f0, df_dt, tau, length, sigma, p):
    """Newton steps on the path's own trajectory for the instant its velocity is zero.

    a0: the acceleration at the start of the path (`_slide`).
    """
    for _ in range(4):
        xe, ve = _slide(x, v, a0, f0, df_dt, tau, sigma, p)
        ae = _accel(xe, ve, f0 + df_dt * tau, sigma, p)
        if ae == 0.0:
            break
        step = ve / ae
        trial = tau - step
        if not 0.0 < trial <= length:
            break
        tau = trial
        if abs(step) <= 1e-15 * length:
            break
    return tau


@njit(cache=True)
def _interval(x, v, mode, f0, f1, t0, rest_time, p, carried_a, carried_f):
    """Advance one sample interval [t0, t0 + h] with all events located inside it.

    Returns the end state (x, v, mode, rest_time) and (a, f): the acceleration at that state
    under force f, as the last segment computed it (f NaN where it computed none). The force
    is f0 + (f1 - f0) s / h. carried_a, carried_f: the (a, f) the previous interval returned,
    its state this one's: a segment starting under the very same force takes that a instead
    of evaluating it again (the same numbers, one friction evaluation fewer a sample).
    """
    h = p[STEP]
    df_dt = (f1 - f0) / h
    segment = h / p[SUBSTEPS]
    s = 0.0
    for _ in range(MAX_EVENTS_PER_INTERVAL):
        if mode == 0:
            spring = _spring(x, p)
            g_end = f1 - spring
            direction = _break_direction(g_end, p)
            if direction == 0:
                return x, 0.0, 0, rest_time, 0.0, np.nan
            # g is linear in time at rest: it leaves the band where it crosses the edge.
            g_now = f0 + df_dt * s - spring
            edge = (
                p[FRICTION_POS] + p[STATIC_EXCESS]
                if direction > 0
                else -(p[FRICTION_NEG] + p[STATIC_EXCESS])
            )
            # Already at the edge or past it (a rest entered in this interval with the force
            # constant over it, g_now == g_end: 0/0 had raised ZeroDivisionError): it breaks
            # away now, never earlier than s.
            if (edge - g_now) * direction > 0.0:
                s = min(h, s + (h - s) * (edge - g_now) / (g_end - g_now))
            mode = direction
            v = 0.0
            rest_time = np.nan
            carried_f = np.nan
            if s >= h:
                return x, v, mode, rest_time, 0.0, np.nan
            continue
        f_start = f0 + df_dt * s
        if f_start == carried_f and math.copysign(1.0, f_start) == math.copysign(1.0, carried_f):
            a0 = carried_a
        else:
            a0 = _accel(x, v, f_start, mode, p)
        d0 = mode * a0
        end = min(h, s + segment)
        if p[STATIC_EXCESS] != 0.0 and abs(v) < p[STRIBECK_ZONE_RATIO] * p[STRIBECK_V]:
            # Near zero speed the Stribeck excess changes as fast as the speed crosses vs:
            # at |a| (or, leaving rest with a = 0, at the jerk j: v = j t^2 / 2). Resolve it.
            jerk = (df_dt - p[STIFFNESS] * v - p[DAMPING] * mode * d0) / p[MASS]
            speed_rate = abs(d0) + math.sqrt(0.5 * p[STRIBECK_V] * abs(jerk))
            if speed_rate > 0.0:
                end = min(end, s + max(STRIBECK_STEP * p[STRIBECK_V] / speed_rate, h / 1024.0))
        length = end - s
        x1, v1 = _slide(x, v, a0, f_start, df_dt, length, mode, p)
        f_end = f0 + df_dt * end
        a1 = _accel(x1, v1, f_end, mode, p)
        d1 = mode * a1
        p1 = mode * v1
        tau = -1.0
        if p1 <= 0.0 or d0 < 0.0 < d1:
            tau = _first_stop(mode * v, d0, p1, d1, length)
        if tau < 0.0:
            x = x1
            v = v1
            s = end
            carried_a = a1
            carried_f = f_end
            if s >= h:
                return x, v, mode, rest_time, a1, f_end
            continue
        tau = _polish_stop(x, v, a0, f_start, df_dt, tau, length, mode, p)
        x, _ = _slide(x, v, a0, f_start, df_dt, tau, mode, p)
        v = 0.0
        s = s + tau
        mode = _break_direction(f0 + df_dt * s - _spring(x, p), p)
        carried_f = np.nan
        if mode == 0:
            rest_time = t0 + s
        if s >= h:
            return x, v, mode, rest_time, 0.0, np.nan
    return x, 0.0, 0, (t0 + s if mode != 0 else rest_time), 0.0, np.nan


@njit(cache=True)
def _start(force, x_out, v_out, state, p):
    """Unpack the carried state; on the first call emit sample 0 (the initial condition).

    Returns (first loop index, x, v, mode, rest_time, last force, samples done before).
    """
    if state[STATE_INDEX] == 0.0 and force.shape[0] > 0:
        x = state[STATE_X]
        v = state[STATE_V]
        if v > 0.0:
            mode = 1
        elif v < 0.0:
            mode = -1
        else:
            mode = _break_direction(force[0] - _spring(x, p), p)
        state[STATE_MODE] = mode
        state[STATE_REST_TIME] = 0.0 if mode == 0 else np.nan
        state[STATE_FORCE] = force[0]
        x_out[0] = x
        v_out[0] = v
        first = 1
    else:
        first = 0
    return (
        first,
        state[STATE_X],
        state[STATE_V],
        int(state[STATE_MODE]),
        state[STATE_REST_TIME],
        state[STATE_FORCE],
        state[STATE_INDEX],
    )


@njit(cache=True)
def _rest_end(force, i, spring, band_neg, band_pos):
    """End of the stretch at rest that starts at sample i (which is in the band).

    Returns the first sample after i whose net force leaves the band, or the batch's end. The
    rig rests for most of a record, so this scan is most of a simulation's reading: whole
    blocks are tested without a branch per sample (the loop vectorizes); the block with a
    sample leaving the band is redone sample by sample up to that sample. The stretch is
    written afterwards, in one pass: testing and writing in one loop was slower.
    Every sample inside passes the sample-by-sample rule's test, so it gets what that rule
    gives it.
    """
    n = force.shape[0]
    stop = i + 1
    while stop + REST_BLOCK <= n:
        block = force[stop : stop + REST_BLOCK]  # a view indexed from 0: no wrap-around test
        inside = 0
        for k in range(REST_BLOCK):
            g = block[k] - spring
            inside += (band_neg <= g) & (g <= band_pos)
        if inside < REST_BLOCK:
            break
        stop += REST_BLOCK
    while stop < n:
        g = force[stop] - spring
        if not band_neg <= g <= band_pos:
            break
        stop += 1
    return stop


@njit(cache=True)
def _force_limit(n):
    """Largest force sample [N] a batch of n can hold with its sum sure to stay finite.

    A kernel flags a batch holding a sample beyond it (or a non-finite one) so that the caller
    runs the full check (`finite_samples`), which names the bad sample; below it the sum of
    the batch, the check's test, cannot overflow.
    """
    return 0.25 * MAX_FLOAT / max(n, 1)


@njit(cache=True, nogil=True)
def oscillator_exact(force, x_out, v_out, state, p):
    """Event-located solution over a force batch: closed form (linear) or RK4 (nonlinear).

    Writes the state at each sample into x_out, v_out and carries it over in `state`. Returns
    True if a force sample was not finite or beyond `_force_limit`: the caller must then check
    the batch (the outputs are of no use if the check fails). Every sample is tested as it is
    read, in the rest scan (a sample inside the band is finite and small) or on its own.
    """
    first, x, v, mode, rest_time, f0, index0 = _start(force, x_out, v_out, state, p)
    n = force.shape[0]
    limit = _force_limit(n)
    suspect = n > 0 and not abs(force[0]) <= limit
    h = p[STEP]
    # Sliding faster than this takes the exact matrix step: any speed on the closed-form
    # path, above STRIBECK_FLAT_RATIO * vs for a Stribeck contact alone, never on pure RK4.
    linear = p[NONLINEAR] == 0.0
    if linear:
        exact_above = 0.0
    elif p[NONLINEAR] == 2.0:
        exact_above = p[STRIBECK_FLAT_RATIO] * p[STRIBECK_V]
    else:
        exact_above = math.inf
    band_pos = p[FRICTION_POS] + p[STATIC_EXCESS]
    band_neg = -(p[FRICTION_NEG] + p[STATIC_EXCESS])
    band_size = max(band_pos, -band_neg)
    c = p[DAMPING]
    k = p[STIFFNESS]
    phi0, phi1, phi2, phi3 = p[PHI], p[PHI + 1], p[PHI + 2], p[PHI + 3]
    ga0, ga1 = p[GAMMA_U0], p[GAMMA_U0 + 1]
    gb0, gb1 = p[GAMMA_DU], p[GAMMA_DU + 1]
    i = first
    zeroed = first  # v_out[i:zeroed] is zero already: written ahead while sliding
    # The acceleration the last interval ended with, and the force it is under (`_interval`;
    # NaN: none carried, since the state has moved on since).
    carried_a = 0.0
    carried_f = np.nan
    while i < n:
        f1 = force[i]
        suspect |= not abs(f1) <= limit
        if mode == 0:
            spring = _spring(x, p)  # x is fixed at rest
            g = f1 - spring
            if band_neg <= g <= band_pos:  # stays at rest: the net force is linear in time
                stop = _rest_end(force, i, spring, band_neg, band_pos)
                x_out[i:stop] = x
                v_out[max(i, zeroed) : stop] = 0.0
                suspect |= not abs(spring) + band_size <= 0.5 * limit
                f0 = force[stop - 1]
                i = stop
                continue
        elif linear or mode * v >= exact_above:
            # Sliding one way with no event: one exact matrix step a sample, until a sample
            # whose interval holds a reversal or a stop, or nears rest on NONLINEAR 2 (left
            # to `_interval` below).
            sigma = float(mode)
            friction = sigma * (p[FRICTION_POS] if mode > 0 else p[FRICTION_NEG])
            zeroed = max(zeroed, i + 1)
            carried_f = np.nan
            while True:
                u0 = f0 - friction
                du = f1 - f0
                x1 = phi0 * x + phi1 * v + ga0 * u0 + gb0 * du
                v1 = phi2 * x + phi3 * v + ga1 * u0 + gb1 * du
                if not sigma * v1 > exact_above:
                    break
                d0 = sigma * (u0 - c * v - k * x)
                d1 = sigma * (u0 + du - c * v1 - k * x1)
                if d0 < 0.0 < d1:  # the velocity may dip to zero inside (signs of m a)
                    break
                x = x1
                v = v1
                x_out[i] = x
                v_out[i] = v
                # The step waits on the previous one's result (a chain of dependent multiplies
                # and adds): meanwhile the store units zero the velocity of samples ahead, the
                # rest that most likely follows the motion.
                if zeroed + ZERO_AHEAD <= n:
                    ahead = v_out[zeroed:]
                    for t in range(ZERO_AHEAD):
                        ahead[t] = 0.0
                    zeroed += ZERO_AHEAD
                f0 = f1
                i += 1
                if i == n:
                    break
                f1 = force[i]
                suspect |= not abs(f1) <= limit
            if i == n:
                break
        t0 = (index0 + i - 1) * h
        x, v, mode, rest_time, carried_a, carried_f = _interval(
            x, v, mode, f0, f1, t0, rest_time, p, carried_a, carried_f
        )
        x_out[i] = x
        v_out[i] = v
        f0 = f1
        i += 1
    _store(state, x, v, mode, rest_time, f0, index0 + n)
    return suspect


@njit(cache=True, nogil=True)
def oscillator_euler(force, x_out, v_out, state, p):
    """The paper's fixed-step method: acceleration each step, then Euler updates.

    Velocity first, then displacement with the new velocity (semi-implicit Euler, as in the
    time-domain code of Schmitz & Smith's Mechanical Vibrations), force held at the step start.
    When the velocity reaches or crosses zero, the stick test decides rest or reversal.
    Returns True if a force sample was not finite or too large, as `oscillator_exact` does.
    """
    first, x, v, mode, rest_time, f0, index0 = _start(force, x_out, v_out, state, p)
    n = force.shape[0]
    limit = _force_limit(n)
    suspect = n > 0 and not abs(force[0]) <= limit
    h = p[STEP]
    for i in range(first, n):
        f1 = force[i]
        suspect |= not abs(f1) <= limit
        if mode == 0:
            mode = _break_direction(f0 - _spring(x, p), p)
            if mode != 0:
                rest_time = np.nan
        if mode != 0:
            v_new = v + h * _accel(x, v, f0, mode, p)
            x = x + h * v_new
            if mode * v_new <= 0.0:
                direction = _break_direction(f1 - _spring(x, p), p)
                if direction == 0:
                    v = 0.0
                    mode = 0
                    rest_time = (index0 + i) * h
                else:
                    v = v_new
                    mode = direction if v_new == 0.0 else (1 if v_new > 0.0 else -1)
            else:
                v = v_new
        x_out[i] = x
        v_out[i] = v
        f0 = f1
    _store(state, x, v, mode, rest_time, f0, index0 + n)
    return suspect


@njit(cache=True)
def _store(state, x, v, mode, rest_time, force_last, index):
    state[STATE_X] = x
    state[STATE_V] = v
    state[STATE_MODE] = mode
    state[STATE_REST_TIME] = rest_time
    state[STATE_FORCE] = force_last
    state[STATE_INDEX] = index


@njit(cache=True, nogil=True)
def add_linear_mode(
    force, force_before, first_call, x_out, v_out, mode, history, whole, fraction, offset
):
    """Add a decoupled linear mode driven by the same force (exact first-order-hold steps).

    `force_before` is the sample preceding force[0]; on the first call sample 0 is the
    mode's initial state instead. The vibrometer's terms follow in the same pass: with a
    `history` (see `delay_in_place`; an empty one for no delay) the summed velocity is then
    delayed, and a non-zero `offset` [m/s] added. The mode's step waits on the previous
    one's result (a chain of dependent multiplies and adds), and the delay's loads and stores
    fit in the wait; the summed velocities of the last whole + 2 samples are kept in a ring.
    Each sample gets the very operations of the separate passes, in their order.
    """
    n = force.shape[0]
    size = history.shape[0]
    delayed = size > 0
    keep = 1.0 - fraction
    ring_size = 1
    while ring_size < size + 1:
        ring_size *= 2
    mask = ring_size - 1
    ring = np.empty(ring_size)  # summed velocity of sample j at ring[(j + size) & mask]
    ring[:size] = history
    x = mode[MODE_X]
    v = mode[MODE_V]
    phi0, phi1 = mode[MODE_PHI], mode[MODE_PHI + 1]
    phi2, phi3 = mode[MODE_PHI + 2], mode[MODE_PHI + 3]
    ga0, ga1 = mode[MODE_GAMMA_U0], mode[MODE_GAMMA_U0 + 1]
    gb0, gb1 = mode[MODE_GAMMA_DU], mode[MODE_GAMMA_DU + 1]
    f0 = force_before
    for i in range(n):
        if i == 0 and first_call:
            f0 = force[0]
        else:
            f1 = force[i]
            du = f1 - f0
            x, v = (
                phi0 * x + phi1 * v + ga0 * f0 + gb0 * du,
                phi2 * x + phi3 * v + ga1 * f0 + gb1 * du,
            )
            f0 = f1
        x_out[i] += x
        summed = v_out[i] + v
        if delayed:
            ring[(i + size) & mask] = summed
            summed = keep * ring[(i + 1) & mask] + fraction * ring[i & mask]
        if offset != 0.0:
            summed += offset
        v_out[i] = summed
    for j in range(size):
        history[j] = ring[(n + j) & mask]
    mode[MODE_X] = x
    mode[MODE_V] = v


@njit(cache=True, nogil=True)
def delay_in_place(signal, history, whole, fraction):
    """Delay `signal` by (whole + fraction) samples, linear between samples, in place.

    `history` holds the whole + 1 samples before this batch (oldest first) and is updated.
    Sample i becomes (1 - fraction) signal[i - whole] + fraction signal[i - whole - 1]. The
    batch is done from its end in chunks: a chunk's sources, which lie below its end and so
    are not yet overwritten, are copied to a small buffer first, so that the chunk is one
    branch-free loop (it vectorizes); the first whole + 1 samples read the history.
    """
    n = signal.shape[0]
    size = history.shape[0]
    keep = 1.0 - fraction
    tail = np.empty(size)
    for j in range(size):
        src = n - size + j
        tail[j] = signal[src] if src >= 0 else history[src + size]
    sources = np.empty(DELAY_CHUNK + 1)
    end = n
    while end > size:
        begin = max(size, end - DELAY_CHUNK)
        count = end - begin
        sources[: count + 1] = signal[begin - size : end - whole]
        chunk = signal[begin:end]
        for t in range(count):
            chunk[t] = keep * sources[t + 1] + fraction * sources[t]
        end = begin
    for i in range(min(n, size) - 1, -1, -1):  # backwards: reads only indices not yet written
        j = i - whole
        a = signal[j] if j >= 0 else history[size + j]
        b = signal[j - 1] if j >= 1 else history[size + j - 1]
        signal[i] = keep * a + fraction * b
    history[:] = tail
