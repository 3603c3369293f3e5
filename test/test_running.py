"""The running friction estimate: each impact fitted alone, the session's mu as they come in."""

import math

import numpy as np
import pytest
import scipy.stats
from fit_records import lab_levels

from fmm_ros.core import identify as fit
from fmm_ros.core.identify.running import RunningFriction, running_estimates


def test_weighted_mean_error_and_chi2_per_impact_and_level():
    mus, errors = [0.110, 0.114, 0.113, 0.112], [1e-3, 2e-3, 1e-3, 4e-3]
    levels = ['low', 'high', 'low', 'high']
    estimates = running_estimates([4, 5, 6, 7], levels, mus, errors)
    assert [e.count for e in estimates] == [1, 2, 3, 4]
    assert math.isnan(estimates[0].consistency_p_value)
    last = estimates[-1]
    weights = 1 / np.square(errors)
    mean = np.sum(weights * mus) / np.sum(weights)
    chi2 = np.sum(weights * (np.array(mus) - mean) ** 2)
    assert last.mu == pytest.approx(mean) and last.mu_stderr == pytest.approx(weights.sum() ** -0.5)
    assert last.consistency_chi2 == pytest.approx(chi2)
    assert last.consistency_p_value == pytest.approx(scipy.stats.chi2.sf(chi2, 3))
    assert (last.impact_id, last.impact_mu, last.impact_mu_stderr) == (7, 0.112, 4e-3)
    low, high = last.levels
    assert (low.level, low.count, high.level, high.count) == ('low', 2, 'high', 2)
    assert low.mu == pytest.approx(0.1115) and low.mu_stderr == pytest.approx(1e-3 / math.sqrt(2))
    with pytest.raises(ValueError, match='impact 9: mu 0.1 \\+- 0.0 cannot be weighted'):
        RunningFriction().add(9, 'low', 0.1, 0.0)


def test_the_running_mu_is_the_joint_fit_to_well_within_its_error():
    records = lab_levels(21, mu=0.113)
    joint = fit.fit_friction(records, fit_initial_position=True)
    own = [fit.fit_friction([record], fit_initial_position=True) for record in records]
    last = running_estimates(
        [0, 1, 2], ['low', 'medium', 'high'], [f.mu for f in own], [f.mu_stderr for f in own]
    )[-1]
    assert last.mu == pytest.approx(joint.mu, abs=0.2 * joint.mu_stderr)
    assert last.mu_stderr == pytest.approx(joint.mu_stderr, rel=0.1)
    assert last.consistency_p_value == pytest.approx(joint.consistency_p_value, abs=0.1)
