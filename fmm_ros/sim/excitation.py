"""Hammer force records for simulators and tests: ideal pulses, realistic hits, impact records.

Pulses are sampled from their continuous shape at t_i = i / sample_rate_hz; read as linear
between samples (the physics core's assumption) their area is the trapezoid-rule impulse.
Everything random takes a numpy Generator or a seed, so a record is reproducible.

The paper's hammer levels (Sec. 4-5): 450 / 1000 / 1450 N peaks, accepted within +-50 N, with
mean impulses 0.98 / 1.42 / 1.64 N*s. A half-sine of peak F and impulse I lasts pi I / (2 F):
3.4 / 2.2 / 1.8 ms; the rubber tip stiffens as it is hit harder.
"""

import math
from dataclasses import dataclass

import numpy as np

from fmm_ros.constants import PAPER_LEVELS, PAPER_MU, RECORD_DURATION_S, SAMPLE_RATE_HZ, PaperLevel
from fmm_ros.core._checks import require_finite, require_non_negative, require_positive
from fmm_ros.core.physics.model import Simulation, record_length, simulate
from fmm_ros.core.physics.rig import FMM_RIG, Rig
from fmm_ros.core.physics.terms import ModelTerm
from fmm_ros.errors import BadInputError


def paper_level(name: str) -> PaperLevel:
    """The paper's hammer level of this name ('low', 'medium', 'high'); ValueError otherwise."""
    for level in PAPER_LEVELS:
        if level.name == name:
            return level
    known = ', '.join(level.name for level in PAPER_LEVELS)
    raise BadInputError(f'unknown hammer level {name!r}; known: {known}')


def level_contact_duration_s(level: PaperLevel) -> float:
    """Duration of the half-sine with a paper level's peak and impulse [s]."""
    return half_sine_duration_s(level.peak_force_n, level.impulse_n_s)


def half_sine_duration_s(peak_force_n: float, impulse_n_s: float) -> float:
    """Contact duration T of a half-sine pulse: its impulse is 2 F T / pi, so T = pi I / (2 F)."""
    require_positive('peak_force_n', peak_force_n)
    require_positive('impulse_n_s', impulse_n_s)
    return math.pi * impulse_n_s / (2.0 * peak_force_n)


def _fit_tip_law() -> tuple[float, float]:
    """Least-squares power law T = a F^b through the paper's three (peak, duration) levels."""
    peaks = np.log([level.peak_force_n for level in PAPER_LEVELS])
    durations = np.log([level_contact_duration_s(level) for level in PAPER_LEVELS])
    exponent, log_scale = np.polyfit(peaks, durations, 1)
    return math.exp(log_scale), exponent


_TIP_SCALE_S, TIP_EXPONENT = _fit_tip_law()


def tip_contact_duration_s(peak_force_n: float) -> float:
    """Contact duration of the paper's hammer tip at a peak force [s].

    A power law T = a F^b fitted to the three levels (b is about -0.56: the rubber tip stiffens
    with force); it reproduces their 3.4 / 2.2 / 1.8 ms within 2 %.
    """
    require_positive('peak_force_n', peak_force_n)
    return _TIP_SCALE_S * peak_force_n**TIP_EXPONENT


def level_peak_force_n(
    level: str, rng: np.random.Generator | int, spread_std_n: float = 30.0
) -> float:
    """A hand-swung hit aimed at a paper level: its nominal peak plus normal scatter [N]."""
    nominal = paper_level(level).peak_force_n
    require_non_negative('spread_std_n', spread_std_n)
    peak = nominal + np.random.default_rng(rng).normal(0.0, spread_std_n)
    return max(float(peak), 1.0)


def half_sine_pulse(
    peak_force_n: float,
    contact_duration_s: float,
    sample_rate_hz: float,
    duration_s: float,
    *,
    start_s: float = 0.0,
) -> np.ndarray:
    """F sin(pi (t - start) / T) for start <= t <= start + T, zero elsewhere [N]."""
    return hammer_pulse(
        peak_force_n,
        contact_duration_s,
        sample_rate_hz,
        duration_s,
        start_s=start_s,
        rise_fraction=0.5,
    )


def hammer_pulse(
    peak_force_n: float,
    contact_duration_s: float,
    sample_rate_hz: float,
    duration_s: float,
    *,
    start_s: float = 0.0,
    rise_fraction: float = 0.45,
) -> np.ndarray:
    """A realistic, slightly asymmetric hammer pulse [N].

    A quarter sine rises to the peak over rise_fraction of the contact, a quarter cosine falls
    over the rest (a tip loads faster than it unloads). The impulse stays 2 F T / pi whatever
    the asymmetry; rise_fraction 0.5 is the symmetric half-sine.
    """
    require_positive('peak_force_n', peak_force_n)
    require_positive('contact_duration_s', contact_duration_s)
    if not 0.0 < rise_fraction < 1.0:
        raise BadInputError(f'rise_fraction must be between 0 and 1, got {rise_fraction}')
    time_s = _pulse_window(contact_duration_s, sample_rate_hz, duration_s, start_s)
    rise_s = rise_fraction * contact_duration_s
    local = time_s - start_s
    inside = (local >= 0.0) & (local <= contact_duration_s)
    phase = np.where(
        local < rise_s,
        0.5 * local / rise_s,
        0.5 + 0.5 * (local - rise_s) / (contact_duration_s - rise_s),
    )
    return np.where(inside, peak_force_n * np.sin(np.pi * np.clip(phase, 0.0, 1.0)), 0.0)


def rectangular_pulse(
    force_n: float,
    pulse_duration_s: float,
    sample_rate_hz: float,
    duration_s: float,
    *,
    start_s: float = 0.0,
) -> np.ndarray:
    """Constant force over pulse_duration_s (paper Fig. 5), zero elsewhere [N].

    The pulse covers round(pulse_duration_s * rate) samples from the one nearest start_s, so
    read linear between samples (trapezoid rule) its impulse is exactly force_n * duration
    once it starts after the first sample.
    """
    require_positive('pulse_duration_s', pulse_duration_s)
    require_finite('force_n', force_n)
    time_s = _pulse_window(pulse_duration_s, sample_rate_hz, duration_s, start_s)
    first = round(start_s * sample_rate_hz)
    count = round(pulse_duration_s * sample_rate_hz)
    if count < 1:
        raise BadInputError(
            f'pulse_duration_s {pulse_duration_s:g} is shorter than one sample '
            f'at {sample_rate_hz:g} Hz'
        )
    force = np.zeros(time_s.size)
    force[first : first + count] = force_n
    return force


def _pulse_window(
    contact_s: float, sample_rate_hz: float, duration_s: float, start_s: float
) -> np.ndarray:
    """Sample times of a record, checked to hold the whole pulse."""
    n = record_length(duration_s, sample_rate_hz)
    require_non_negative('start_s', start_s)
    if start_s + contact_s > (n - 1) / sample_rate_hz:
        raise BadInputError(
            f'the pulse ({start_s:g} s + {contact_s:g} s) does not fit in the '
            f'{duration_s:g} s record'
        )
    return np.arange(n) / sample_rate_hz


@dataclass(frozen=True)
class SimulatedImpact:
    """One simulated hammer test: what the DAQ records, and the truth behind it."""

    force_n: np.ndarray
    """Measured force: the hammer pulse plus sensor noise [N]."""
    velocity_m_s: np.ndarray
    """Measured velocity: the model's vibrometer output plus sensor noise [m/s]."""
    sample_rate_hz: float
    trigger_index: int
    """First sample inside the contact."""
    peak_force_n: float
    contact_duration_s: float
    impulse_n_s: float
    """Impulse of the noise-free pulse, trapezoid rule (what an ideal analyzer finds)."""
    simulation: Simulation
    """The noise-free model response the measurement was made from."""

    @property
    def time_s(self) -> np.ndarray:
        """Sample times from the first sample [s]."""
        return self.simulation.time_s


def impact_record(
    peak_force_n: float,
    rng: np.random.Generator | int,
    *,
    rig: Rig = FMM_RIG,
    mu: float = PAPER_MU,
    effects: tuple[ModelTerm, ...] = (),
    sample_rate_hz: float = SAMPLE_RATE_HZ,
    duration_s: float = RECORD_DURATION_S,
    pretrigger_s: float = 0.1,
    contact_duration_s: float | None = None,
    rise_fraction: float = 0.45,
    force_noise_std_n: float = 0.05,
    velocity_noise_std_m_s: float = 1e-5,
    integrator: str = 'exact',
) -> SimulatedImpact:
    """A full simulated impact record: the model driven by a realistic hit, both channels noisy.

    The hit starts pretrigger_s into the record plus a random fraction of a sample (a hand
    swing is not synchronised with the sample clock); its duration follows the paper's tip
    (`tip_contact_duration_s`) unless given. The model is driven by the noise-free force; the
    returned channels add independent Gaussian noise of the given standard deviations.
    """
    rng = np.random.default_rng(rng)
    require_positive('sample_rate_hz', sample_rate_hz)
    require_non_negative('force_noise_std_n', force_noise_std_n)
    require_non_negative('velocity_noise_std_m_s', velocity_noise_std_m_s)
    require_non_negative('pretrigger_s', pretrigger_s)
    if contact_duration_s is None:
        contact_duration_s = tip_contact_duration_s(peak_force_n)
    start_s = pretrigger_s + rng.uniform(0.0, 1.0) / sample_rate_hz
    clean = hammer_pulse(
        peak_force_n,
        contact_duration_s,
        sample_rate_hz,
        duration_s,
        start_s=start_s,
        rise_fraction=rise_fraction,
    )
    response = simulate(
        clean, sample_rate_hz, rig=rig, mu=mu, effects=effects, integrator=integrator
    )
    force = clean + rng.normal(0.0, force_noise_std_n, clean.size)
    velocity = response.velocity_m_s + rng.normal(0.0, velocity_noise_std_m_s, clean.size)
    return SimulatedImpact(
        force_n=force,
        velocity_m_s=velocity,
        sample_rate_hz=sample_rate_hz,
        trigger_index=int(np.argmax(clean > 0.0)),
        peak_force_n=peak_force_n,
        contact_duration_s=contact_duration_s,
        impulse_n_s=float(np.trapezoid(clean) / sample_rate_hz),
        simulation=response,
    )
