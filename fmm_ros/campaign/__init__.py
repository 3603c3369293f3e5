"""Campaigns: many sessions under conditions a lab chooses, compared with honest intervals.

A table of sessions (`table`), each an independent task run on Dask with a cache (`session`,
`cache`, `tasks`), compared across conditions with a random-effects model (`stats`,
`compare`), written as tidy tables and JSON (`results`) and an HTML page (`report`). ROS-free.
"""

from fmm_ros.campaign.compare import CampaignComparison, SessionMu, compare_sessions
from fmm_ros.campaign.report import write_campaign_report
from fmm_ros.campaign.results import (
    CampaignResult,
    run_campaign,
    tidy_tables,
    to_json,
    write_json,
    write_tables,
)
from fmm_ros.campaign.session import SessionOutcome, SessionSpec
from fmm_ros.campaign.stats import MetaRegression, meta_regression
from fmm_ros.campaign.table import CampaignTable, read_campaign_table
from fmm_ros.campaign.tasks import SERIAL, run_session, run_sessions

__all__ = [
    'SERIAL',
    'CampaignComparison',
    'CampaignResult',
    'CampaignTable',
    'MetaRegression',
    'SessionMu',
    'SessionOutcome',
    'SessionSpec',
    'compare_sessions',
    'meta_regression',
    'read_campaign_table',
    'run_campaign',
    'run_session',
    'run_sessions',
    'tidy_tables',
    'to_json',
    'write_campaign_report',
    'write_json',
    'write_tables',
]
