"""The FMM as a friction oscillator: Eq. 3 of the paper, its composable terms, and integrators."""

from fmm_ros.core.physics.model import (
    INTEGRATORS,
    OscillatorStream,
    Simulation,
    coulomb_peak_mobility,
    free_vibration,
    record_length,
    simulate,
)
from fmm_ros.core.physics.rig import FMM_RIG, Rig
from fmm_ros.core.physics.terms import (
    EFFECT_SIZE,
    MODEL_TERMS,
    ModelTerm,
    Parameter,
    model_term,
    parse_model_term,
)

__all__ = [
    'EFFECT_SIZE',
    'FMM_RIG',
    'INTEGRATORS',
    'MODEL_TERMS',
    'ModelTerm',
    'OscillatorStream',
    'Parameter',
    'Rig',
    'Simulation',
    'coulomb_peak_mobility',
    'free_vibration',
    'model_term',
    'parse_model_term',
    'record_length',
    'simulate',
]
