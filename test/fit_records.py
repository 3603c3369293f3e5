"""Lab-like simulated impacts for the fitting tests: random hit shapes, pre-trigger, late trigger.

The noise is the issues' lab level (0.2 N on force, 1e-4 m/s on velocity). Each hit's peak
scatters about its paper level, its contact lasts 0.7-1.4 times the paper tip's, its rise takes
30-60 % of the contact (skew), and it starts after a random pre-trigger plus a random trigger
delay of up to 40 samples and a fraction of one: nothing the fitter may know.
"""

import numpy as np

from fmm_ros.constants import PAPER_LEVELS
from fmm_ros.core.physics.rig import FMM_RIG
from fmm_ros.sim.excitation import (
    impact_record,
    level_peak_force_n,
    tip_contact_duration_s,
)

FORCE_NOISE_N = 0.2
VELOCITY_NOISE_M_S = 1e-4
LEVELS = tuple(level.name for level in PAPER_LEVELS)


def lab_impact(
    peak_force_n,
    seed,
    *,
    mu,
    rig=FMM_RIG,
    effects=(),
    duration_s=33.0,
    force_noise_std_n=FORCE_NOISE_N,
    velocity_noise_std_m_s=VELOCITY_NOISE_M_S,
):
    """One simulated impact with a random hit shape and an unknown hit position."""
    rng = np.random.default_rng(seed)
    pretrigger_s = rng.uniform(0.01, 0.5)
    trigger_delay_s = rng.integers(0, 41) / 10_000.0
    return impact_record(
        peak_force_n,
        rng,
        mu=mu,
        rig=rig,
        effects=effects,
        duration_s=duration_s,
        pretrigger_s=pretrigger_s + trigger_delay_s,
        contact_duration_s=tip_contact_duration_s(peak_force_n) * rng.uniform(0.7, 1.4),
        rise_fraction=rng.uniform(0.3, 0.6),
        force_noise_std_n=force_noise_std_n,
        velocity_noise_std_m_s=velocity_noise_std_m_s,
    )


def lab_levels(seed, *, mu, levels=LEVELS, **options):
    """One lab impact at each paper level (peaks scattered as a hand swing scatters them)."""
    rng = np.random.default_rng(seed)
    return [
        lab_impact(level_peak_force_n(level, rng), int(rng.integers(2**31)), mu=mu, **options)
        for level in levels
    ]
