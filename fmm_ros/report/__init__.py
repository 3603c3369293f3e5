"""Reports: the figures and the HTML page a lab wants after a session (issue 9).

ROS-free like the core (numpy, scipy, matplotlib without pyplot). `report_session` analyses a
session's impact records, fits mu and writes its page (what `fmm report` and the demo run);
`build_report` writes the page from analyses and fits made elsewhere; `build_paper_report`
(in `paper`) reproduces the paper's simulation figures (Figs. 2-10) from the physics core.
"""

from fmm_ros.report.session import FLAG_MEANINGS, SessionReport, build_report, report_session
from fmm_ros.workflows.session import (
    FrictionSummary,
    ModelOverlay,
    SessionDiagnosis,
    diagnose_accepted_impacts,
    fit_accepted_impacts,
)

__all__ = [
    'FLAG_MEANINGS',
    'FrictionSummary',
    'ModelOverlay',
    'SessionDiagnosis',
    'SessionReport',
    'build_report',
    'diagnose_accepted_impacts',
    'fit_accepted_impacts',
    'report_session',
]
