"""A simulated impact-test session as one continuous recording, and as a bag.

Hits at the paper's levels, one every `spacing_s`, drive the friction oscillator (physics
core) as one continuous record, so the rig's state carries from hit to hit as on the real
machine; both channels get sensor noise. This is what the analysis, replay and benchmarks
are exercised on when there is no rig (or no ROS graph) at hand.
"""

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fmm_ros.constants import PAPER_LEVELS, PAPER_MU, SAMPLE_RATE_HZ
from fmm_ros.core.physics.model import simulate
from fmm_ros.core.physics.rig import FMM_RIG, Rig
from fmm_ros.errors import BadInputError
from fmm_ros.io.bags.writer import BagWriter
from fmm_ros.sim.excitation import (
    hammer_pulse,
    level_peak_force_n,
    tip_contact_duration_s,
)

PAPER_LEVEL_ORDER = tuple(level.name for level in PAPER_LEVELS)


@dataclass(frozen=True)
class SimulatedSession:
    """Force [N] and velocity [m/s] of a session, and the truth behind each hit."""

    force_n: np.ndarray
    velocity_m_s: np.ndarray
    sample_rate_hz: float
    hit_levels: tuple[str, ...]
    hit_start_indices: np.ndarray
    hit_peak_force_n: np.ndarray
    mu: float

    @property
    def duration_s(self) -> float:
        """Length of the session [s]."""
        return self.force_n.size / self.sample_rate_hz


def simulated_session(
    hits_per_level: int = 10,
    *,
    spacing_s: float = 33.0,
    levels: Sequence[str] = PAPER_LEVEL_ORDER,
    seed: int = 0,
    mu: float = PAPER_MU,
    pretrigger_s: float = 0.1,
    sample_rate_hz: float = SAMPLE_RATE_HZ,
    force_noise_std_n: float = 0.05,
    velocity_noise_std_m_s: float = 1e-5,
    rig: Rig = FMM_RIG,
) -> SimulatedSession:
    """hits_per_level hits of each level in turn, each pretrigger_s into its spacing_s slot.

    The recording runs pretrigger_s past the last slot, so that a record as long as the
    slot, started at its hit, is complete (the paper's 33 s records, hits 33 s apart). rig:
    the plant's constants (another normal force, say).
    """
    if hits_per_level < 1:
        raise BadInputError(f'hits_per_level must be at least 1, got {hits_per_level}')
    rng = np.random.default_rng(seed)
    slot = int(round(spacing_s * sample_rate_hz))
    order = tuple(level for level in levels for _ in range(hits_per_level))
    force = np.zeros(slot * len(order) + int(round(pretrigger_s * sample_rate_hz)))
    starts, peaks = [], []
    for k, level in enumerate(order):
        peak = level_peak_force_n(level, rng)
        start_s = pretrigger_s + rng.uniform(0.0, 1.0) / sample_rate_hz
        force[k * slot : (k + 1) * slot] = hammer_pulse(
            peak, tip_contact_duration_s(peak), sample_rate_hz, spacing_s, start_s=start_s
        )
        starts.append(k * slot + int(np.ceil(start_s * sample_rate_hz)))
        peaks.append(peak)
    velocity = simulate(force, sample_rate_hz, rig=rig, mu=mu).velocity_m_s
    force += rng.normal(0.0, force_noise_std_n, force.size)
    velocity = velocity + rng.normal(0.0, velocity_noise_std_m_s, velocity.size)
    return SimulatedSession(
        force, velocity, sample_rate_hz, order, np.array(starts), np.array(peaks), mu
    )


def write_session_bag(
    path: str | Path, session: SimulatedSession, *, storage: str = 'mcap', time_origin_ns: int = 0
) -> Path:
    """The session as the recorder would have stored it: 500-sample batches, both channels."""
    with BagWriter(path, storage=storage, time_origin_ns=time_origin_ns) as writer:
        writer.write_signals(session.force_n, session.velocity_m_s, session.sample_rate_hz)
    return Path(path)
