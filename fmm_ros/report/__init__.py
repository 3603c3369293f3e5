"""Reports: the figures and the HTML page a lab wants after a session (issue 9).

ROS-free like the core (numpy, scipy, matplotlib without pyplot). `build_report` writes a
session's page from its impact records; `build_paper_report` reproduces the paper's
simulation figures (Figs. 2-10) from the physics core.
"""

from fmm_ros.report.model import FrictionSummary, ModelOverlay, fit_accepted_impacts
from fmm_ros.report.session import FLAG_MEANINGS, build_report

__all__ = ['FLAG_MEANINGS', 'FrictionSummary', 'ModelOverlay', 'build_report',
           'fit_accepted_impacts']
