"""The diagnosis fits effect sizes within physical ranges, says when a fit ends on a bound and
when these records cannot show an effect at all.

Stiction far beyond the old 0-0.1 range is drawn on the held-out `events` world (its own
DOP853 physics, half-sine and Hertzian hits, starts at the centre); nothing was changed after
these cases were first run. The unobservable statement is checked on the product's own clean
session with fitted starts (`hidden_effects`, a tuning generator).
"""

import json

import numpy as np
import pytest
from heldout.lab import EVENTS, Effects, session

from fmm_ros.core.diagnose import UNEXPLAINED, diagnose
from fmm_ros.core.physics.terms import (
    MODEL_TERMS,
    STATIC_EXCESS_PER_MU,
    STRIBECK_EXPONENT_RANGE,
    physical_ranges,
)
from fmm_ros.sim.hidden_effects import hidden_effect_case
from fmm_ros.workflows.results import diagnosis_dict


def test_the_ranges_come_from_mu_the_peak_speed_and_the_period():
    ranges = physical_ranges(0.12, 0.3, 1.0 / 2.2)
    assert ranges['stribeck.mu_static_excess'] == (0.0, pytest.approx(STATIC_EXCESS_PER_MU * 0.12))
    assert ranges['asymmetric_friction.mu_difference'] == (-0.12, 0.12)
    assert ranges['velocity_offset.offset_m_s'] == (pytest.approx(-0.03), pytest.approx(0.03))
    assert ranges['sensor_delay.delay_s'] == (0.0, pytest.approx(0.25 / 2.2))
    low, high = MODEL_TERMS['stribeck'].bounds(ranges)
    assert list(low) == [0.0, 1e-4, STRIBECK_EXPONENT_RANGE[0]]
    assert high[0] == pytest.approx(0.36) and high[2] == STRIBECK_EXPONENT_RANGE[1]
    # without ranges, the declared bounds (what `fmm fit` and the proof data use)
    assert MODEL_TERMS['stribeck'].bounds()[1][0] == 0.1


@pytest.mark.parametrize(
    ('mu', 'excess', 'speed_m_s', 'seed'),
    [
        (0.167, 0.14, 3e-3, 0),  # static/kinetic 1.84: a dry contact
        (0.1, 0.2, 2e-3, 1),  # stiction excess twice mu
    ],
)
def test_stiction_far_beyond_the_old_range_is_named_stribeck(mu, excess, speed_m_s, seed):
    rng = np.random.default_rng([45, seed])
    effects = Effects(static_excess=excess, stribeck_speed_m_s=speed_m_s)
    records = session(EVENTS, effects, mu, rng, (450.0, 1000.0, 1450.0))
    result = diagnose(records)
    assert result.named_effects == ('stribeck',), result.verdict
    assert UNEXPLAINED not in result.named_effects
    assert result.gap_after <= 0.5 * result.gap_before
    fitted = {p.name: p for p in result.missing_effects[0].parameters}
    assert fitted['stribeck.mu_static_excess'].value == pytest.approx(excess, rel=0.05)
    assert not fitted['stribeck.mu_static_excess'].at_bound
    assert fitted['stribeck.stribeck_velocity_m_s'].value == pytest.approx(speed_m_s, rel=0.15)
    # the world's contact is Gaussian (delta 2): the JSON says whether its shape ends on the
    # bound; the verdict speaks only of a size on its bound, not of a shape
    exponent = fitted['stribeck.stribeck_exponent']
    assert exponent.value >= 1.8
    document = json.loads(json.dumps(diagnosis_dict(result)))
    at_bound = document['missing_effects'][0]['parameter_at_bound']
    assert at_bound['stribeck.stribeck_exponent'] is exponent.at_bound
    assert 'stribeck_exponent' not in result.verdict


def test_an_effect_whose_limit_is_beyond_its_physical_range_is_stated_unobservable():
    """With fitted starts an asymmetry shows only from mu+ - mu- of order 1, beyond +-mu."""
    records = hidden_effect_case('none', np.random.default_rng([8, 2]), duration_s=8.0).records
    result = diagnose(records, fit_initial_position=True)
    assert result.missing_effect == 'none'
    asymmetry = next(c for c in result.candidates if c.effect == 'asymmetric_friction')
    assert asymmetry.detection_limit > result.mu
    assert asymmetry.unobservable.startswith('these records cannot show asymmetric friction')
    assert 'chained starts or a position sensor would' in result.verdict
    document = diagnosis_dict(result)
    entry = next(c for c in document['candidates'] if c['effect'] == 'asymmetric_friction')
    assert entry['unobservable'] == asymmetry.unobservable
    # from the centre the same records show an asymmetry of a few per cent of mu
    centred = diagnose(records)
    assert 'cannot show asymmetric friction' not in centred.verdict
