"""Output-error identification: mu, damping and model terms from measured force and velocity.

`conditioning` (one record -> the gated force and untouched velocity a fit drives the model
with), `output_error` (a parameter vector -> residuals, and the fit's uncertainty), `lsq`
(Levenberg-Marquardt for tall block-structured problems), `friction` (`fit_model`,
`fit_friction`: the paper's Sec. 5 question), `rig` (`identify_rig`, `fit_free_decay`: Sec. 4).
"""

from fmm_ros.core.identify.conditioning import (
    FIT_FAILURES,
    ConditionedImpact,
    FitError,
    as_conditioned,
    condition_impact,
    cropped_impact,
    velocity_noise_std,
)
from fmm_ros.core.identify.friction import (
    MU_BOUNDS,
    FrictionFit,
    ModelFit,
    energy_balance_mu,
    fit_friction,
    fit_model,
)
from fmm_ros.core.identify.rig import (
    FreeDecayFit,
    RigIdentification,
    fit_free_decay,
    identify_rig,
)

__all__ = [
    'FIT_FAILURES',
    'MU_BOUNDS',
    'ConditionedImpact',
    'FitError',
    'FreeDecayFit',
    'FrictionFit',
    'ModelFit',
    'RigIdentification',
    'as_conditioned',
    'condition_impact',
    'cropped_impact',
    'energy_balance_mu',
    'fit_free_decay',
    'fit_friction',
    'fit_model',
    'identify_rig',
    'velocity_noise_std',
]
