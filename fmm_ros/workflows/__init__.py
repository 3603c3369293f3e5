"""Pipelines over the core and the file formats, and the one home of result serialisation.

`inputs` reads what a lab hands over (lab files and bags) as impact records; `replay` runs a
bag through the analyzer's capture and analysis; `session` takes one session's inputs through
analysis, the friction fit and the diagnosis (`process_session`), with the model run for every
hit (`model`); `results` holds the one result type of a friction fit and the JSON of every
result.
"""

from fmm_ros.workflows.inputs import InputOptions, SessionInputs, read_inputs
from fmm_ros.workflows.model import ModelComparison, ModelOverlay, compare_model
from fmm_ros.workflows.replay import bag_impact_records, replay_bag
from fmm_ros.workflows.results import (
    FrictionResult,
    analysis_dict,
    diagnosis_dict,
    selection_dict,
)
from fmm_ros.workflows.session import (
    FitOptions,
    SessionDiagnosis,
    SessionOptions,
    SessionResult,
    analyse,
    diagnose_impacts,
    fit_impacts,
    overlay_of,
    process_session,
    run_session,
    select_records,
)

__all__ = [
    'FitOptions',
    'FrictionResult',
    'InputOptions',
    'ModelComparison',
    'ModelOverlay',
    'SessionDiagnosis',
    'SessionInputs',
    'SessionOptions',
    'SessionResult',
    'analyse',
    'analysis_dict',
    'bag_impact_records',
    'compare_model',
    'diagnose_impacts',
    'diagnosis_dict',
    'fit_impacts',
    'overlay_of',
    'process_session',
    'read_inputs',
    'replay_bag',
    'run_session',
    'select_records',
    'selection_dict',
]
