"""Reports: the figures and the HTML page a lab wants after a session (issue 9).

ROS-free like the core (numpy, scipy, matplotlib without pyplot), and it only draws:
`build_report` writes the page of a `SessionResult` computed by `fmm_ros.workflows.session`
(`process_session` for files and bags, `run_session` for records in hand);
`build_paper_report` (in `paper`) reproduces the paper's simulation figures (Figs. 2-10).
"""

from fmm_ros.report.session import FLAG_MEANINGS, build_report

__all__ = ['FLAG_MEANINGS', 'build_report']
