"""The discrepancy workflow: where the model and a measurement disagree, and what the model lacks.

`workflow` (`diagnose`: base fit, candidates, decision), `result` (the `Diagnosis` it
returns), `gaps` (the misfit beyond the noise, before and after), `where` (where the base
model misses), `signatures` (plain functions on arrays that point at causes), `starts`
(where each candidate's refit begins).
"""

from fmm_ros.core.diagnose.result import Candidate, Diagnosis, ParameterEstimate, Where
from fmm_ros.core.diagnose.workflow import EFFECTS, NONE, VOCABULARY, diagnose

__all__ = [
    'EFFECTS',
    'NONE',
    'VOCABULARY',
    'Candidate',
    'Diagnosis',
    'ParameterEstimate',
    'Where',
    'diagnose',
]
