"""Synthetic data for tests, benchmarks, the simulated rig and the demo.

Hammer pulses and impact records (`excitation`), the paper's session as a hit schedule and force
streams (`hammer`), a whole session as arrays or a bag (`session`), and sessions with one effect
hidden in them, the diagnosis's proof data (`hidden_effects`).
"""

from fmm_ros._lazy import lazy_exports

_EXPORTS = {
    'hidden_effect_case': 'hidden_effects',
    'impact_record': 'excitation',
    'simulated_session': 'session',
    'write_session_bag': 'session',
}

__all__ = sorted(_EXPORTS)
__getattr__ = lazy_exports(__name__, _EXPORTS)
