"""Pipelines over the core.

A bag through capture and analysis (`replay`), and a session's accepted impacts through the fit
and the diagnosis (`session`).
"""

from fmm_ros.workflows.replay import bag_impact_records, replay_bag
from fmm_ros.workflows.session import (
    FrictionSummary,
    SessionDiagnosis,
    analyse_records,
    diagnose_accepted_impacts,
    fit_accepted_impacts,
    select_records,
)

__all__ = [
    'FrictionSummary',
    'SessionDiagnosis',
    'analyse_records',
    'bag_impact_records',
    'diagnose_accepted_impacts',
    'fit_accepted_impacts',
    'replay_bag',
    'select_records',
]
