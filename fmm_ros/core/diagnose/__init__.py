"""The discrepancy workflow: where the model and a measurement disagree, and what the model lacks.

`workflow` (`diagnose`: base fit, forward selection of effects, backward check, verdict),
`result` (the `Diagnosis` it returns), `session_model` (a model of every hit as the selection
grows it), `screen` (the linearised step that ranks candidates before any refit), `starts`
(the probes each candidate is screened and refitted from), `gaps` (the misfit beyond the noise,
before and after; where a record's motion ends), `where` (where a model misses), `drift` (per-hit
mu and its trend in hit order), `friction_map` (mu against speed and position by inverse
dynamics), `signatures` (plain functions on arrays that point at causes).
"""

from fmm_ros.constants import MU_DRIFT
from fmm_ros.core.diagnose.drift import MuTrend
from fmm_ros.core.diagnose.friction_map import FrictionCurve, FrictionMap
from fmm_ros.core.diagnose.result import (
    Candidate,
    Diagnosis,
    NamedEffect,
    ParameterEstimate,
    ResidualLocation,
    Where,
)
from fmm_ros.core.diagnose.workflow import EFFECTS, NONE, UNEXPLAINED, VOCABULARY, diagnose

__all__ = [
    'EFFECTS',
    'MU_DRIFT',
    'NONE',
    'UNEXPLAINED',
    'VOCABULARY',
    'Candidate',
    'Diagnosis',
    'FrictionCurve',
    'FrictionMap',
    'MuTrend',
    'NamedEffect',
    'ParameterEstimate',
    'ResidualLocation',
    'Where',
    'diagnose',
]
