"""Pipelines over the core and the file formats, and the one home of result serialisation.

`inputs` reads what a lab hands over (lab files and bags) as impact records; `replay` runs a
bag through the analyzer's capture and analysis; `session` takes one session's inputs through
analysis, the friction fit and the diagnosis (`process_session`), with the model run for every
hit (`model`); `results` holds the one result type of a friction fit and the JSON of every
result.
"""

from fmm_ros._lazy import lazy_exports

_EXPORTS = {
    'FitOptions': 'session',
    'FrictionResult': 'results',
    'InputOptions': 'inputs',
    'ModelComparison': 'model',
    'ModelOverlay': 'model',
    'SessionDiagnosis': 'session',
    'SessionInputs': 'inputs',
    'SessionOptions': 'session',
    'SessionResult': 'session',
    'analyse': 'session',
    'analysis_dict': 'results',
    'bag_impact_records': 'replay',
    'compare_model': 'model',
    'diagnose_impacts': 'session',
    'diagnosis_dict': 'results',
    'fit_impacts': 'session',
    'impact_ids': 'session',
    'overlay_of': 'session',
    'process_session': 'session',
    'read_inputs': 'inputs',
    'replay_bag': 'replay',
    'process_records': 'session',
    'select_records': 'session',
    'selection_dict': 'results',
}

__all__ = sorted(_EXPORTS)
__getattr__ = lazy_exports(__name__, _EXPORTS)
