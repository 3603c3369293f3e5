"""FMM sessions measured by an accelerometer, from a generator independent of the product.

Not the product's simulator: the FMM's
oscillator with Coulomb friction solved piecewise in closed form (between two velocity
reversals the motion is the damped linear oscillator about a centre shifted by the friction
force; the velocity zeros are where the friction turns, or the rig sticks when the spring
cannot beat it), driven by a half-sine hammer pulse integrated with fine RK4 steps. The
accelerometer reads m x'' exactly at each sample, plus white noise and an offset that the
product must take off before integrating; the force sensor adds its own noise.
"""

import dataclasses

import numpy as np

from fmm_ros.core.physics.rig import FMM_RIG

RATE_HZ = 10_000.0
SECONDS = 8.0
ACCELERATION_NOISE_M_S2 = 0.005
FORCE_NOISE_N = 0.2
PULSE_STEPS = 200
"""RK4 steps per sample while the hammer pushes."""


def _friction_acceleration(x, v, force, mu, rig):
    """Acceleration of the sliding rig, or 0 when it sticks (v = 0, spring + hammer <= mu N)."""
    net = force - rig.stiffness_n_per_m * x - rig.damping_n_s_per_m * v
    if v == 0.0 and abs(net) <= mu * rig.normal_force_n:
        return 0.0
    direction = np.sign(v) if v != 0.0 else np.sign(net)
    return (net - direction * mu * rig.normal_force_n) / rig.mass_kg


def fmm_accelerometer_record(peak_n, pulse_s, hit_at_s, mu, x0_m, rig=FMM_RIG):
    """Force [N] and acceleration [m/s^2] samples of one hit on the FMM (module doc)."""
    n = int(SECONDS * RATE_HZ)
    time_s = np.arange(n) / RATE_HZ
    force = np.where(
        (time_s > hit_at_s) & (time_s < hit_at_s + pulse_s),
        peak_n * np.sin(np.pi * np.clip((time_s - hit_at_s) / pulse_s, 0, 1)),
        0.0,
    )
    acceleration = np.zeros(n)
    first = int(np.ceil(hit_at_s * RATE_HZ))
    last = int(np.ceil((hit_at_s + pulse_s) * RATE_HZ))
    x, v = x0_m, 0.0
    h = 1.0 / (RATE_HZ * PULSE_STEPS)

    def hammer(t):
        return (
            peak_n * np.sin(np.pi * (t - hit_at_s) / pulse_s)
            if hit_at_s < t < hit_at_s + pulse_s
            else 0.0
        )

    t = first / RATE_HZ
    for index in range(first, last):
        acceleration[index] = _friction_acceleration(x, v, hammer(t), mu, rig)
        for _ in range(PULSE_STEPS):  # RK4 on (x, v)
            k1 = (v, _friction_acceleration(x, v, hammer(t), mu, rig))
            k2 = (
                v + h / 2 * k1[1],
                _friction_acceleration(
                    x + h / 2 * k1[0], v + h / 2 * k1[1], hammer(t + h / 2), mu, rig
                ),
            )
            k3 = (
                v + h / 2 * k2[1],
                _friction_acceleration(
                    x + h / 2 * k2[0], v + h / 2 * k2[1], hammer(t + h / 2), mu, rig
                ),
            )
            k4 = (
                v + h * k3[1],
                _friction_acceleration(x + h * k3[0], v + h * k3[1], hammer(t + h), mu, rig),
            )
            x += h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
            v += h / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
            t += h
    _free_motion(acceleration, last, x, v, mu, rig)
    return force, acceleration


def _free_motion(acceleration, start, x, v, mu, rig):
    """Fill acceleration from sample `start` on: closed-form half cycles until the rig sticks."""
    omega_n = np.sqrt(rig.stiffness_n_per_m / rig.mass_kg)
    sigma = rig.damping_n_s_per_m / (2 * rig.mass_kg)
    omega_d = np.sqrt(omega_n**2 - sigma**2)
    friction_x = mu * rig.normal_force_n / rig.stiffness_n_per_m
    t0, index = start / RATE_HZ, start
    while index < acceleration.size:
        direction = np.sign(v) if v != 0.0 else -np.sign(x)
        if v == 0.0 and abs(x) <= friction_x:
            return  # stuck: no acceleration for the rest of the record
        centre = -direction * friction_x
        a_coef, b_coef = x - centre, (v + sigma * (x - centre)) / omega_d
        # v(tau) = exp(-sigma tau) R cos(omega_d tau + phi): its next zero ends the half cycle.
        phi = np.arctan2(a_coef * omega_d + sigma * b_coef, b_coef * omega_d - sigma * a_coef)
        tau_end = ((np.pi / 2 - phi) % np.pi) / omega_d
        if tau_end <= 0:
            tau_end += np.pi / omega_d
        stop = min(acceleration.size, int(np.floor((t0 + tau_end) * RATE_HZ)) + 1)
        tau = np.arange(index, stop) / RATE_HZ - t0
        decay = np.exp(-sigma * tau)
        y = decay * (a_coef * np.cos(omega_d * tau) + b_coef * np.sin(omega_d * tau))
        dy = decay * (
            (b_coef * omega_d - sigma * a_coef) * np.cos(omega_d * tau)
            - (a_coef * omega_d + sigma * b_coef) * np.sin(omega_d * tau)
        )
        acceleration[index:stop] = (
            -(rig.stiffness_n_per_m * y + rig.damping_n_s_per_m * dy) / rig.mass_kg
        )
        end_decay = np.exp(-sigma * tau_end)
        x = centre + end_decay * (
            a_coef * np.cos(omega_d * tau_end) + b_coef * np.sin(omega_d * tau_end)
        )
        v, t0, index = 0.0, t0 + tau_end, stop


def session(mu, seed, added_damping_n_s_per_m=0.0):
    """Three hits (the paper's levels) of one session: (force N, measured m/s^2) each.

    seed: an int or a numpy Generator. added_damping_n_s_per_m: viscous damping hidden on top
    of the rig's (the diagnosis should name it).
    """
    rng = np.random.default_rng(seed)
    rig = dataclasses.replace(
        FMM_RIG, damping_n_s_per_m=FMM_RIG.damping_n_s_per_m + added_damping_n_s_per_m
    )
    hits = []
    for peak in (450.0, 1000.0, 1450.0):
        force, acceleration = fmm_accelerometer_record(
            peak * rng.uniform(0.97, 1.03),  # within the paper's +-50 N of its level
            rng.uniform(0.0012, 0.0025),
            rng.uniform(0.2, 0.5) + rng.uniform(0, 1 / RATE_HZ),
            mu,
            rng.uniform(-0.8, 0.8) * mu * FMM_RIG.normal_force_n / FMM_RIG.stiffness_n_per_m,
            rig,
        )
        force = force + rng.normal(0, FORCE_NOISE_N, force.size)
        offset = rng.uniform(-0.02, 0.02)
        noise = rng.normal(0, ACCELERATION_NOISE_M_S2, force.size)
        hits.append((force, acceleration + noise + offset))
    return hits


def write_csv(path, force, acceleration):
    """A lab CSV of force and acceleration (columns named with their units)."""
    time_s = np.arange(force.size) / RATE_HZ
    np.savetxt(
        path,
        np.column_stack((time_s, force, acceleration)),
        delimiter=',',
        header='time_s,force_n,acceleration_m_s2',
        comments='',
        fmt='%.10g',
    )
    return path
