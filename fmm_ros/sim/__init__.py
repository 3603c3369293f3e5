"""Synthetic data for tests, benchmarks, the simulated rig and the demo.

Hammer pulses and impact records (`excitation`), the paper's session as a hit schedule and force
streams (`hammer`), a whole session as arrays or a bag (`session`), and sessions with one effect
hidden in them, the diagnosis's proof data (`hidden_effects`).
"""

from fmm_ros.sim.excitation import impact_record
from fmm_ros.sim.hidden_effects import hidden_effect_case
from fmm_ros.sim.session import simulated_session, write_session_bag

__all__ = ['hidden_effect_case', 'impact_record', 'simulated_session', 'write_session_bag']
