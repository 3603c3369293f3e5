"""A closed-loop positioning axis, written for the tests and sharing nothing with fmm_ros.

The plant is a mass on a frictional guide with a constant load force,

    M v' = u - d - (Fv v + Fc)  moving forward,   M v' = u - d - (Fv v - Fc)  moving back,

with direction-dependent friction (Fv+/Fc+, Fv-/Fc-) and a stick rule at standstill (the
guide holds while |u - d| <= Fc of the direction it would start in). It is driven by a
cascaded PD controller, as the EMPS benchmark's: u = g (kp kv (r - x_enc) - kv v_enc), held
for each 1 ms control period, saturated, with v_enc from the encoder by a first difference of
its two-sample mean. Between control ticks the motion is solved exactly: the velocity relaxes
exponentially towards its sliding limit, a reversal or a stop is located in closed form, and
the contact then sticks or slides off the other way.

The reference moves between random positions along minimum-jerk paths of random durations,
so speeds and accelerations cover a range and both directions. The drive force is recorded
as the controller's output plus white measurement noise and a cogging ripple the controller
does not know; the position through an encoder of a given step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Axis:
    """Plant constants (SI) of the simulated axis."""

    mass_kg: float = 14.0
    viscous_positive: float = 60.0
    viscous_negative: float = 60.0
    coulomb_positive: float = 9.0
    coulomb_negative: float = 9.0
    load_n: float = 1.5


@dataclass(frozen=True)
class AxisRun:
    """One simulated record: time, measured force and position, and the true velocity."""

    time_s: np.ndarray
    force_n: np.ndarray
    position_m: np.ndarray
    velocity_m_s: np.ndarray
    acceleration_m_s2: np.ndarray


def _reference(rng: np.random.Generator, duration_s: float, rate_hz: float) -> np.ndarray:
    """Minimum-jerk moves between random points of a 0.2 m travel, with short dwells."""
    t = np.arange(int(duration_s * rate_hz)) / rate_hz
    path = np.zeros_like(t)
    start_t, start_x = 0.0, 0.1
    while start_t < duration_s:
        move_s = rng.uniform(0.4, 1.6)
        target = rng.uniform(0.0, 0.2)
        dwell_s = rng.uniform(0.0, 0.3)
        inside = (t >= start_t) & (t < start_t + move_s)
        s = (t[inside] - start_t) / move_s
        path[inside] = start_x + (target - start_x) * (10 * s**3 - 15 * s**4 + 6 * s**5)
        rest = (t >= start_t + move_s) & (t < start_t + move_s + dwell_s)
        path[rest] = target
        start_t, start_x = start_t + move_s + dwell_s, target
    return path


def _slide(
    axis: Axis, x: float, v: float, u: float, direction: float, span: float
) -> tuple[float, float, float]:
    """Slide in `direction` for up to `span` s: (x, v, time used); stops exactly at v = 0."""
    if direction > 0:
        fv, fc = axis.viscous_positive, axis.coulomb_positive
    else:
        fv, fc = axis.viscous_negative, -axis.coulomb_negative
    tau = axis.mass_kg / fv
    v_limit = (u - axis.load_n - fc) / fv
    used = span
    if v_limit * direction < 0.0 or v_limit == 0.0:
        # heading for standstill: the time at which v reaches zero
        stop = tau * math.log((v_limit - v) / v_limit) if v != 0.0 else 0.0
        used = min(span, stop)
    decay = math.exp(-used / tau)
    x_new = x + v_limit * used + (v - v_limit) * tau * (1.0 - decay)
    v_new = v_limit + (v - v_limit) * decay
    if used < span:
        v_new = 0.0
    return x_new, v_new, used


def _advance(axis: Axis, x: float, v: float, u: float, period: float) -> tuple[float, float]:
    """Exact motion over one control period with u held."""
    left = period
    while left > 1e-15:
        if v == 0.0:
            net = u - axis.load_n
            if -axis.coulomb_negative <= net <= axis.coulomb_positive:
                return x, 0.0  # sticks for the rest of the period
            direction = 1.0 if net > 0 else -1.0
        else:
            direction = 1.0 if v > 0 else -1.0
        x, v, used = _slide(axis, x, v, u, direction, left)
        left -= used
        if used == 0.0:
            v = 0.0
    return x, v


def simulate_axis(
    axis: Axis,
    *,
    seed: int,
    duration_s: float = 20.0,
    rate_hz: float = 1000.0,
    encoder_step_m: float = 1e-6,
    force_noise_n: float = 0.5,
    ripple_n: float = 1.0,
) -> AxisRun:
    """A closed-loop record of `axis` following random moves (see the module doc)."""
    rng = np.random.default_rng(seed)
    reference = _reference(rng, duration_s, rate_hz)
    period = 1.0 / rate_hz
    kp, kv, gain, limit = 160.0, 240.0, 0.5, 400.0
    n = reference.size
    force = np.empty(n)
    position = np.empty(n)
    velocity = np.empty(n)
    acceleration = np.empty(n)
    x, v = reference[0], 0.0
    encoded_prev = mean_prev = encoder_step_m * round(x / encoder_step_m)
    ripple_phase = rng.uniform(0, 2 * math.pi)
    for i in range(n):
        encoded = encoder_step_m * round(x / encoder_step_m)
        mean = 0.5 * (encoded + encoded_prev)
        v_enc = (mean - mean_prev) / period
        encoded_prev, mean_prev = encoded, mean
        u = gain * (kp * kv * (reference[i] - encoded) - kv * v_enc)
        u = min(max(u, -limit), limit)
        applied = u + ripple_n * math.sin(2 * math.pi * x / 0.005 + ripple_phase)
        force[i] = u + rng.normal(0.0, force_noise_n)
        position[i] = encoded
        velocity[i] = v
        if v > 0:
            friction = axis.viscous_positive * v + axis.coulomb_positive
        elif v < 0:
            friction = axis.viscous_negative * v - axis.coulomb_negative
        else:
            friction = 0.0
        acceleration[i] = (applied - axis.load_n - friction) / axis.mass_kg if v != 0 else 0.0
        x, v = _advance(axis, x, v, applied, period)
    return AxisRun(np.arange(n) * period, force, position, velocity, acceleration)
