"""Output-error identification: mu, damping and model terms from measured force and velocity.

`spec` (`FitSpec`: what a fit frees and how it runs), `conditioning` (one record -> the
gated force and untouched velocity a fit drives the model with), `output_error` (a parameter
vector -> residuals, and the fit's uncertainty), `lsq` (Levenberg-Marquardt for tall
block-structured problems), `friction` (`fit_model`, `fit_friction`: the paper's Sec. 5
question), `rig` (`identify_rig`, `fit_free_decay`: Sec. 4).
"""

from fmm_ros._lazy import lazy_exports

_EXPORTS = {
    'FRICTION_FIT': 'spec',
    'FitSpec': 'spec',
    'ConditionedImpact': 'conditioning',
    'FreeDecayFit': 'rig',
    'FrictionFit': 'friction',
    'MU_BOUNDS': 'spec',
    'ModelFit': 'friction',
    'RigIdentification': 'rig',
    'as_conditioned': 'conditioning',
    'condition_impact': 'conditioning',
    'cropped_impact': 'conditioning',
    'energy_balance_mu': 'friction',
    'fit_free_decay': 'rig',
    'fit_friction': 'friction',
    'fit_model': 'friction',
    'identify_rig': 'rig',
    'velocity_noise_std': 'conditioning',
}

__all__ = sorted(_EXPORTS)
__getattr__ = lazy_exports(__name__, _EXPORTS)
