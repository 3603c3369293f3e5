"""Damaged impact records for the damaged-hit matrix (test_damage.py, bench_damage.py).

Each hit is a lab-like record built from `fmm_ros.sim.excitation` pieces (the pulse shape and
the physics core's plant), never from the product's flag code: a hand-swung hit at a paper
level, its contact 0.7-1.4 times the tip's, lab noise drawn per record (force 0.05-0.5 N,
velocity 3e-5-2e-4 m/s), and on some records a 16-bit converter (quantisation), a 50 Hz hum
and sensor offsets. A fault is then done to it as the lab would suffer it:

- clipped: the force converter's rail at 50-97 % of the hit's peak (samples equal the rail);
- double_hit: a second hammer pulse (10-100 % of the first, 5-300 ms later) that drives the
  plant too, as a bouncing hammer does;
- dead_sensor: the vibrometer gives only its noise (plus its offset and any hum);
- disconnected: the vibrometer input reads a constant (0 V, or the offset), quantised;
- saturation: the vibrometer's range at 40-95 % of the hit's peak velocity;
- nan_burst: 1-500 samples of one channel NaN or infinite (a corrupt transfer);
- dropped_stretch: 50-5000 samples of one channel replaced by zeros or by the last value
  held (a DAQ buffer overrun), somewhere in the motion.

`session(fault, seed, damaged)` gives three hits (low, medium, high) with the fault done to
the hits whose positions are in `damaged`, and the true mu. `worlds_session` does the same
with the independent generator (test/worlds: its plant, hand-swung hits, DAQ chain with
anti-alias filters, hum, drift and a 16-bit converter, and its own damage kinds), each record
streamed by sample index as the live capture and bag replay see it.
"""

import dataclasses
from dataclasses import dataclass

import numpy as np

from fmm_ros.constants import PAPER_LEVELS, PAPER_MU
from fmm_ros.core.physics.model import simulate
from fmm_ros.core.signal.records import ImpactRecord
from fmm_ros.sim.excitation import hammer_pulse, level_peak_force_n, tip_contact_duration_s

RATE_HZ = 10_000.0
# Long enough for the FMM to come to rest after the hardest hit at mu ~ 0.1 (about 4 s) plus
# the 0.5 s the unsettled check looks at.
DURATION_S = 6.0
FAULTS = (
    'clipped',
    'double_hit',
    'dead_sensor',
    'disconnected',
    'saturation',
    'nan_burst',
    'dropped_stretch',
)
# A 16-bit converter over these ranges: 0.15 N and 1.5e-5 m/s steps.
FORCE_RANGE_N = 5000.0
VELOCITY_RANGE_M_S = 0.5
HUM_HZ = 50.0


@dataclass(frozen=True)
class Hit:
    """One hit as recorded, and what was done to it."""

    record: ImpactRecord
    fault: str  # '' when clean
    detail: str


def quantise(values: np.ndarray, full_range: float) -> np.ndarray:
    """A 16-bit converter over +-full_range: rounded to its step, held at its rails."""
    step = 2 * full_range / 2**16
    return np.clip(np.round(values / step) * step, -full_range, full_range - step)


def clean_hit(peak_force_n: float, rng: np.random.Generator, mu: float):
    """Force [N], velocity [m/s], lab options and the plant's clean response of one hit."""
    n = round(DURATION_S * RATE_HZ)
    contact_s = tip_contact_duration_s(peak_force_n) * rng.uniform(0.7, 1.4)
    start_s = rng.uniform(0.02, 0.3) + rng.uniform(0, 1) / RATE_HZ
    pulse = hammer_pulse(
        peak_force_n,
        contact_s,
        RATE_HZ,
        DURATION_S,
        start_s=start_s,
        rise_fraction=rng.uniform(0.3, 0.6),
    )
    lab = {
        'force_noise_n': float(np.exp(rng.uniform(np.log(0.05), np.log(0.5)))),
        'velocity_noise_m_s': float(np.exp(rng.uniform(np.log(3e-5), np.log(2e-4)))),
        'quantised': bool(rng.random() < 0.5),
        'hum_m_s': float(rng.uniform(0, 1e-4)) if rng.random() < 0.3 else 0.0,
        'force_offset_n': float(rng.normal(0, 0.5)),
        'velocity_offset_m_s': float(rng.normal(0, 2e-4)),
        'hum_phase': float(rng.uniform(0, 2 * np.pi)),
        'contact_s': contact_s,
        'start_s': start_s,
    }
    assert pulse.size == n
    return pulse, lab


def measured(
    pulse: np.ndarray, velocity_clean: np.ndarray, lab: dict, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """The DAQ's view of a clean force and velocity: offsets, hum, noise, converter."""
    t = np.arange(pulse.size) / RATE_HZ
    force = pulse + lab['force_offset_n'] + rng.normal(0, lab['force_noise_n'], pulse.size)
    velocity = (
        velocity_clean
        + lab['velocity_offset_m_s']
        + lab['hum_m_s'] * np.sin(2 * np.pi * HUM_HZ * t + lab['hum_phase'])
        + rng.normal(0, lab['velocity_noise_m_s'], pulse.size)
    )
    if lab['quantised']:
        force = quantise(force, FORCE_RANGE_N)
        velocity = quantise(velocity, VELOCITY_RANGE_M_S)
    return force, velocity


def damaged_hit(level_index: int, fault: str, rng: np.random.Generator, mu: float) -> Hit:
    """One hit at a paper level, with the fault done to it ('' for a clean hit)."""
    peak = level_peak_force_n(PAPER_LEVELS[level_index].name, rng)
    pulse, lab = clean_hit(peak, rng, mu)
    drive = pulse.copy()
    detail = ''
    if fault == 'double_hit':
        ratio, delay_s = rng.uniform(0.1, 1.0), rng.uniform(0.005, 0.3)
        second = hammer_pulse(
            ratio * peak,
            tip_contact_duration_s(ratio * peak),
            RATE_HZ,
            DURATION_S,
            start_s=lab['start_s'] + lab['contact_s'] + delay_s,
        )
        drive = drive + second
        detail = f'{ratio:.2f} x peak, {1e3 * delay_s:.0f} ms after the contact'
    velocity_clean = simulate(drive, RATE_HZ, mu=mu).velocity_m_s
    force, velocity = measured(drive, velocity_clean, lab, rng)
    n = force.size
    if fault == 'clipped':
        level = rng.uniform(0.5, 0.97)
        force = np.minimum(force, level * np.max(force))
        detail = f'rail at {100 * level:.0f} % of the peak'
    elif fault == 'dead_sensor':
        dead = velocity_clean * 0.0
        _, velocity = measured(pulse * 0.0, dead, lab, rng)
        detail = 'vibrometer noise only'
    elif fault == 'disconnected':
        velocity = np.full(n, rng.choice([0.0, lab['velocity_offset_m_s']]))
        if lab['quantised']:
            velocity = quantise(velocity, VELOCITY_RANGE_M_S)
        detail = 'vibrometer input constant'
    elif fault == 'saturation':
        level = rng.uniform(0.4, 0.95)
        limit = level * np.max(np.abs(velocity))
        velocity = np.clip(velocity, -limit, limit)
        detail = f'range at {100 * level:.0f} % of the peak velocity'
    elif fault == 'nan_burst':
        count = int(rng.integers(1, 501))
        at = int(rng.integers(0, n - count))
        channel = force if rng.random() < 0.5 else velocity
        channel[at : at + count] = rng.choice([np.nan, np.inf, -np.inf])
        detail = f'{count} samples from {at}'
    elif fault == 'dropped_stretch':
        count = int(rng.integers(50, 5001))
        hit_at = int(lab['start_s'] * RATE_HZ)
        at = int(rng.integers(hit_at + 100, min(n - count, hit_at + int(3 * RATE_HZ))))
        channel = force if rng.random() < 0.5 else velocity
        held = rng.random() < 0.5
        channel[at : at + count] = channel[at - 1] if held else 0.0
        detail = f'{count} samples {"held" if held else "zeroed"} from {at}'
    elif fault not in ('', 'double_hit'):
        raise ValueError(f'unknown fault {fault!r}; known: {", ".join(FAULTS)}')
    record = ImpactRecord(force, velocity, RATE_HZ, source=f'{fault or "clean"}_{level_index}')
    return Hit(record, fault, detail)


def session(fault: str, seed: int, damaged: tuple[int, ...] = (0, 1, 2)) -> tuple[list[Hit], float]:
    """Hits at the three paper levels, those at positions `damaged` with the fault; true mu."""
    rng = np.random.default_rng(seed)
    mu = float(PAPER_MU * rng.uniform(0.8, 1.2))
    return [
        damaged_hit(level, fault if level in damaged else '', rng, mu) for level in range(3)
    ], mu


# -- the same faults through the independent generator (test/worlds) ----------------------------

WORLDS_LEVELS = ('low', 'medium', 'high')


def worlds_damage(fault: str, rng: np.random.Generator) -> list:
    """The worlds damage doing `fault` (its own kinds, parameters drawn as ours are)."""
    import math

    from worlds import (
        DeadVibrometer,
        DoubleHit,
        DroppedSamples,
        ForceClip,
        NonFiniteBurst,
        VibrometerSaturation,
    )

    if fault == '':
        return []
    if fault == 'clipped':
        return [ForceClip(rng.uniform(0.4, 0.95))]
    if fault == 'double_hit':
        return [DoubleHit(rng.uniform(0.1, 0.9), rng.uniform(0.005, 0.3))]
    if fault == 'dead_sensor':
        return [DeadVibrometer(None)]
    if fault == 'disconnected':
        return [DeadVibrometer(float(rng.uniform(-0.01, 0.01)))]
    if fault == 'saturation':
        return [VibrometerSaturation(rng.uniform(0.02, 0.08))]
    if fault == 'nan_burst':
        return [
            NonFiniteBurst(
                str(rng.choice(['force', 'velocity'])),
                rng.uniform(0.0, 2.0),
                int(rng.integers(1, 500)),
                float(rng.choice([math.nan, math.inf, -math.inf])),
            )
        ]
    if fault == 'dropped_stretch':
        return [DroppedSamples(rng.uniform(0.0, 2.0), int(rng.integers(1, 2000)))]
    raise ValueError(f'unknown fault {fault!r}; known: {", ".join(FAULTS)}')


def streamed(record, source: str) -> ImpactRecord:
    """A worlds record as the live capture or a bag replay sees it: samples by their index.

    A dropped stretch is an index jump (the capture's gap), as a DAQ's sample counter shows
    it; the record ends where the acquisition ends.
    """
    from fmm_ros.core.signal.capture import ImpactCapture

    index = np.round(record.time_s * record.sample_rate_hz).astype(np.int64)
    runs = np.flatnonzero(np.diff(index) != 1) + 1
    capture = ImpactCapture()
    found = []
    for start, stop in zip(np.r_[0, runs], np.r_[runs, index.size], strict=True):
        found += capture.feed_both(
            int(index[start]),
            record.force_n[start:stop],
            record.velocity_m_s[start:stop],
            record.sample_rate_hz,
        )
    found += capture.end_acquisition()
    return dataclasses.replace(found[0], source=source)


def worlds_session(
    fault: str, seed: int, damaged: tuple[int, ...] = (0, 1, 2)
) -> tuple[list[Hit], float]:
    """session() with the independent generator: worlds' plant, hits, DAQ chain and damage."""
    from worlds import Coulomb, World, impact_record, random_pulse

    rng = np.random.default_rng(seed)
    mu = float(PAPER_MU * rng.uniform(0.8, 1.2))
    world = World(friction=Coulomb(mu))
    hits = []
    for level in range(3):
        kind = fault if level in damaged else ''
        damage = worlds_damage(kind, rng)
        record = impact_record(
            world,
            rng,
            pulse=random_pulse(rng, WORLDS_LEVELS[level]),
            duration_s=DURATION_S,
            damage=damage,
        )
        hits.append(
            Hit(
                streamed(record, f'{kind or "clean"}_{level}'),
                kind,
                repr(damage[0]) if damage else '',
            )
        )
    return hits, mu
