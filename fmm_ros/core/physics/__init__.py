"""The FMM as a friction oscillator: Eq. 3 of the paper, its composable terms, and integrators."""

from fmm_ros._lazy import lazy_exports

_EXPORTS = {
    'EFFECT_SIZE': 'terms',
    'FMM_RIG': 'rig',
    'INTEGRATORS': 'rig',
    'MODEL_TERMS': 'terms',
    'ModelTerm': 'terms',
    'OscillatorStream': 'model',
    'Parameter': 'terms',
    'Rig': 'rig',
    'Simulation': 'model',
    'coulomb_peak_mobility': 'model',
    'free_vibration': 'model',
    'model_term': 'terms',
    'parse_model_term': 'terms',
    'record_length': 'model',
    'simulate': 'model',
    'size_parameter': 'terms',
}

__all__ = sorted(_EXPORTS)
__getattr__ = lazy_exports(__name__, _EXPORTS)
