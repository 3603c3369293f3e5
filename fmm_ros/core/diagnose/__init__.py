"""The discrepancy workflow: where the model and a measurement disagree, and what the model lacks.

`workflow` (`diagnose`: base fit, forward selection of effects, backward check, verdict),
`result` (the `Diagnosis` it returns), `session_model` (a model of every hit as the selection
grows it), `screen` (the linearised step that ranks candidates before any refit), `starts`
(the probes each candidate is screened and refitted from), `gaps` (the misfit beyond the noise,
before and after; where a record's motion ends), `where` (where a model misses), `drift` (per-hit
mu and its trend in hit order), `friction_map` (mu against speed and position by inverse
dynamics), `signatures` (plain functions on arrays that point at causes).
"""

from fmm_ros._lazy import lazy_exports
from fmm_ros.constants import MU_DRIFT as MU_DRIFT

_EXPORTS = {
    'Candidate': 'result',
    'Diagnosis': 'result',
    'EFFECTS': 'vocabulary',
    'FrictionCurve': 'friction_map',
    'FrictionMap': 'friction_map',
    'MuTrend': 'drift',
    'NONE': 'vocabulary',
    'NamedEffect': 'result',
    'ParameterEstimate': 'result',
    'ResidualLocation': 'result',
    'UNEXPLAINED': 'vocabulary',
    'VOCABULARY': 'vocabulary',
    'Where': 'result',
    'diagnose': 'workflow',
}

__all__ = sorted([*_EXPORTS, 'MU_DRIFT'])
__getattr__ = lazy_exports(__name__, _EXPORTS)
