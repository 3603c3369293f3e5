"""A simulated test campaign: session bags under known conditions, and the table listing them.

Each condition (a lubricant and a normal force) has a known mu; each session's plant mu is that
plus a draw of the session-to-session scatter (the contact changes between sessions), so the
campaign's statistics have a truth to recover at both levels. Sessions are continuous
recordings of hits at the paper's levels in turn (`session.simulated_session`), written as
the recorder writes bags, with the rig's normal force of their condition.
"""

from __future__ import annotations

import csv
import dataclasses
import datetime as dt
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fmm_ros.core.physics.rig import FMM_RIG
from fmm_ros.errors import BadInputError
from fmm_ros.sim.session import PAPER_LEVEL_ORDER, simulated_session, write_session_bag

CAMPAIGN_TABLE = 'campaign.csv'


@dataclass(frozen=True)
class SimulatedCampaign:
    """Where the table is, and the truth: each session's plant mu and each condition's."""

    table: Path
    session_mu: dict[str, float]
    """Plant mu of each session id."""
    condition_mu: dict[tuple[str, float], float]
    """mu of each (lubricant, normal force [N]) before the session scatter."""


def condition_mu(
    lubricant_mu: float, normal_force_n: float, load_slope_per_n: float = 0.0
) -> float:
    """The mu of a lubricant at a normal force: its mu at the FMM's load plus a linear trend."""
    return lubricant_mu + load_slope_per_n * (normal_force_n - FMM_RIG.normal_force_n)


def simulated_campaign(
    out_dir: str | Path,
    lubricants: Mapping[str, float],
    loads_n: Sequence[float],
    *,
    sessions_per_condition: int = 4,
    hits: int = 10,
    session_scatter: float = 0.002,
    load_slope_per_n: float = 0.0,
    spacing_s: float = 33.0,
    seed: int = 0,
    start_date: dt.date = dt.date(2026, 11, 2),
) -> SimulatedCampaign:
    """Write one bag a session under out_dir/sessions and the campaign table out_dir/campaign.csv.

    lubricants: name -> mu at the FMM's normal force; loads_n: the normal forces [N]. Hits
    cycle through the paper's levels; sessions are dated one a day in the order written.
    """
    if sessions_per_condition < 1 or hits < 1:
        raise BadInputError('a campaign needs at least one session a condition and one hit')
    out_dir = Path(out_dir)
    rng = np.random.default_rng(seed)
    levels = tuple(PAPER_LEVEL_ORDER[i % len(PAPER_LEVEL_ORDER)] for i in range(hits))
    rows, session_mu, truth = [], {}, {}
    day = 0
    for lubricant, base_mu in lubricants.items():
        for load in loads_n:
            mu = condition_mu(base_mu, load, load_slope_per_n)
            truth[(lubricant, float(load))] = mu
            for repeat in range(sessions_per_condition):
                session_id = f'{lubricant}_{load:g}N_{repeat + 1}'
                plant_mu = float(mu + rng.normal(0.0, session_scatter))
                session = simulated_session(
                    1,
                    levels=levels,
                    spacing_s=spacing_s,
                    seed=int(rng.integers(2**31)),
                    mu=plant_mu,
                    rig=dataclasses.replace(FMM_RIG, normal_force_n=float(load)),
                )
                write_session_bag(out_dir / 'sessions' / session_id, session)
                session_mu[session_id] = plant_mu
                rows.append(
                    {
                        'session': f'sessions/{session_id}',
                        'id': session_id,
                        'lubricant': lubricant,
                        'normal_force_n': f'{load:.10g}',
                        'date': (start_date + dt.timedelta(days=day)).isoformat(),
                        'operator': ('kb', 'tz')[day % 2],
                    }
                )
                day += 1
    table = out_dir / CAMPAIGN_TABLE
    with open(table, 'w', newline='', encoding='utf-8') as stream:
        writer = csv.DictWriter(stream, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    return SimulatedCampaign(table, session_mu, truth)
