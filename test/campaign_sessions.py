"""Campaigns of session mu drawn from a random-effects model: the statistics' test data.

No physics: each session's mu is its condition's plus a between-session draw N(0, tau^2) plus
its fit's error N(0, sigma_i^2), sigma_i spread over about a decade around a median (a
session's fit error depends on its hits). Thousands of campaigns cost seconds, so the
intervals' coverage and the false-positive rate can be counted. Used by
test_campaign_stats.py and benchmarks/bench_campaign.py.
"""

import math

from fmm_ros.campaign.compare import SessionMu
from fmm_ros.campaign.table import NUMBER, TEXT, Column

LUBRICANTS = {'A': 0.113, 'B': 0.101, 'C': 0.113}
"""mu of each lubricant at the reference load: B is 0.012 below A, C equal to A."""
LOADS_N = (6.6708, 9.81)
COLUMNS = (Column('lubricant', TEXT), Column('normal_force_n', NUMBER))
BY = ('lubricant', 'normal_force_n')


def random_effects_campaign(
    rng, sessions_per_condition, tau, sigma_median, load_slope_per_n=0.0
) -> list[SessionMu]:
    """Every lubricant at every load, sessions_per_condition sessions each."""
    sessions = []
    for lubricant, mu in LUBRICANTS.items():
        for load in LOADS_N:
            for number in range(sessions_per_condition):
                sigma = sigma_median * math.exp(rng.normal(0.0, 0.8))
                value = (
                    mu
                    + load_slope_per_n * (load - LOADS_N[0])
                    + rng.normal(0.0, tau)
                    + rng.normal(0.0, sigma)
                )
                sessions.append(
                    SessionMu(
                        f'{lubricant}{load}{number}',
                        {'lubricant': lubricant, 'normal_force_n': load},
                        value,
                        sigma**2,
                        10,
                    )
                )
    return sessions
