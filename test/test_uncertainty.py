"""Honest mu and honest errors on sessions of the independent generator.

A few sessions of each harsh scenario (`calibration`): hard-tipped hits sampled at 10 and 5 kHz
through a lab's chain (anti-alias filter, hum, offsets, a drifting vibrometer zero, 16 bits),
every hit starting where friction left the rig. `benchmarks/bench_uncertainty.py` runs 100+
sessions of each; here a handful, against bounds that honest errors pass with room and the
exact-force fit (`calibration.todays_fit`) fails on the same records.
"""

import numpy as np
import pytest
from calibration import SCENARIOS, calibrate, honest_fit, todays_fit

pytestmark = pytest.mark.slow

SESSIONS = 8


@pytest.mark.parametrize(
    'scenario', [s for s in SCENARIOS if s.sharp], ids=lambda s: s.name.replace(' ', '_')
)
def test_mu_and_its_error_are_honest_where_the_old_fit_was_not(scenario):
    sessions = [scenario.session(seed) for seed in range(SESSIONS)]
    results = calibrate(sessions, {'today': todays_fit, 'now': honest_fit})
    now, today = results['now'], results['today']
    # mu within 0.01 % (the issue asks 0.5 %), within 3 standard errors in every session and
    # within 2 in nearly all; one mu is never refused at p < 0.001 (the bound).
    assert now.worst < 1e-4
    assert np.all(np.abs(now.z) < 3.0) and now.coverage >= (SESSIONS - 1) / SESSIONS
    assert now.strict_rejection == 0.0 and now.rejection <= 2 / SESSIONS
    # The fit before, on the same records: its errors cover three sessions in four or fewer,
    # and it refuses one true mu at p < 0.001 in a quarter of them or more (half at 10 kHz
    # through the real chain, most at 5 kHz).
    assert today.coverage <= 0.75 and today.strict_rejection >= 0.25
