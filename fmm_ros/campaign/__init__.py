"""Campaigns: many sessions under conditions a lab chooses, compared with honest intervals.

A table of sessions (`table`), each an independent task run on Dask with a cache (`session`,
`cache`, `tasks`), compared across conditions with a random-effects model (`stats`,
`compare`), written as tidy tables and JSON (`results`) and an HTML page (`report`). ROS-free.

The names below are imported on first use (PEP 562): a Dask worker imports this package to
run `tasks.run_cached_session` and needs neither the statistics nor the figures, whose imports
(scipy.stats, matplotlib) cost it 2.3 s at start.
"""

from fmm_ros._lazy import lazy_exports

_EXPORTS = {
    'SERIAL': 'tasks',
    'CampaignComparison': 'compare',
    'CampaignResult': 'results',
    'CampaignTable': 'table',
    'MetaRegression': 'stats',
    'SessionMu': 'compare',
    'SessionOutcome': 'session',
    'SessionSpec': 'session',
    'compare_sessions': 'compare',
    'meta_regression': 'stats',
    'read_campaign_table': 'table',
    'run_campaign': 'results',
    'run_cached_session': 'tasks',
    'run_sessions': 'tasks',
    'tidy_tables': 'results',
    'to_json': 'results',
    'write_campaign_report': 'report',
    'write_json': 'results',
    'write_tables': 'results',
}

__all__ = sorted(_EXPORTS)
__getattr__ = lazy_exports(__name__, _EXPORTS)
