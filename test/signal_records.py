"""Records the signal-core tests can make exactly: hammer pulses and linear-oscillator responses.

The velocity of a linear oscillator m x'' + c x' + k x = f to a sampled force is computed with
the first-order-hold discretisation of V/F = s / (m s^2 + c s + k), which is exact for a force
that is linear between samples, so the DFT ratio of such a record matches the analytic FRF up
to leakage and the (tiny, at 2 Hz and 10 kHz) difference between interpolated and true pulses.
"""

import numpy as np
import scipy.signal

# The FMM flexure without friction (paper, Sec. 4).
MASS_KG = 10.391
DAMPING_N_S_PER_M = 0.275
STIFFNESS_N_PER_M = 1982.0


def half_sine(n_samples, sample_rate_hz, start_index, peak_n, duration_s):
    """A half-sine hammer pulse starting at `start_index`."""
    t_s = (np.arange(n_samples) - start_index) / sample_rate_hz
    force = np.zeros(n_samples)
    inside = (t_s >= 0) & (t_s <= duration_s)
    force[inside] = peak_n * np.sin(np.pi * t_s[inside] / duration_s)
    return force


def damping_for_ratio(zeta, mass_kg=MASS_KG, stiffness_n_per_m=STIFFNESS_N_PER_M):
    """Viscous damping [N*s/m] giving damping ratio `zeta`."""
    return 2 * zeta * np.sqrt(stiffness_n_per_m * mass_kg)


def linear_velocity(
    force_n, sample_rate_hz, damping_n_s_per_m, mass_kg=MASS_KG, stiffness_n_per_m=STIFFNESS_N_PER_M
):
    """Velocity [m/s] of the linear oscillator driven by `force_n`, starting at rest."""
    num, den, _ = scipy.signal.cont2discrete(
        ([1.0, 0.0], [mass_kg, damping_n_s_per_m, stiffness_n_per_m]),
        1.0 / sample_rate_hz,
        method='foh',
    )
    return scipy.signal.lfilter(num.ravel(), den, force_n)


def analytic_mobility(
    frequency_hz,
    damping_n_s_per_m,
    mass_kg=MASS_KG,
    stiffness_n_per_m=STIFFNESS_N_PER_M,
    extra_decay_per_s=0.0,
):
    """V/F of the linear oscillator at s = i*omega + extra_decay_per_s [m/(N*s)]."""
    s = 2j * np.pi * np.asarray(frequency_hz) + extra_decay_per_s
    return s / (mass_kg * s**2 + damping_n_s_per_m * s + stiffness_n_per_m)


def hits(n_samples, sample_rate_hz, hits_at, zeta=0.05, duration_s=0.004):
    """Force and velocity of a settled (zeta) oscillator hit by (index, peak_n) pulses."""
    force = np.zeros(n_samples)
    for index, peak_n in hits_at:
        force += half_sine(n_samples, sample_rate_hz, index, peak_n, duration_s)
    velocity = linear_velocity(force, sample_rate_hz, damping_for_ratio(zeta))
    return force, velocity
