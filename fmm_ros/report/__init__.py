"""Reports: the figures and the HTML page a lab wants after a session.

ROS-free like the core (numpy, scipy, matplotlib without pyplot), and it only draws:
`build_report` writes the page of a `SessionResult` computed by `fmm_ros.workflows.session`
(`process_session` for files and bags, `process_records` for records in hand);
`build_paper_report` (in `paper`) reproduces the paper's simulation figures (Figs. 2-10).
"""

from fmm_ros._lazy import lazy_exports

_EXPORTS = {
    'FLAG_MEANINGS': 'session',
    'build_report': 'session',
}

__all__ = sorted(_EXPORTS)
__getattr__ = lazy_exports(__name__, _EXPORTS)
