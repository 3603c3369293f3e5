"""fmm_ros.core.diagnose: each hidden effect named, none on clean data, the gap halved.

The fixed-seed cases: three 33 s impacts at random levels, 0.2 N / 1e-4 m/s noise,
each effect hidden at 1-4x the velocity noise after the base fit (hidden_effects). The
diagnosis sees only force and velocity. Several effects at once, out-of-vocabulary effects and
mu drift are test_open_world.py; the randomised sweep is benchmarks/bench_diagnose.py.
"""

import json
import math

import numpy as np
import pytest

from fmm_ros.core.diagnose.starts import start_term
from fmm_ros.core.diagnose.workflow import EFFECTS, NONE, VOCABULARY, diagnose
from fmm_ros.core.identify.conditioning import as_conditioned
from fmm_ros.errors import FitError
from fmm_ros.sim.excitation import impact_record
from fmm_ros.sim.hidden_effects import HIDDEN_EFFECTS, hidden_effect_case
from fmm_ros.workflows.results import diagnosis_dict

pytestmark = pytest.mark.slow

SEED = 2019

# The parameter that sets each effect's size, and how close the refit must bring it.
SIZE = {
    'viscous_damping': 'damping_n_s_per_m',
    'stribeck': 'mu_static_excess',
    'asymmetric_friction': 'mu_difference',
    'cubic_stiffness': 'cubic_stiffness_n_per_m3',
    'velocity_offset': 'offset_m_s',
    'sensor_delay': 'delay_s',
    'second_mode': 'frequency_hz',
}


@pytest.fixture(scope='module')
def diagnoses():
    """One diagnosis per hidden effect (and none), shared by the tests below."""
    results = {}
    for index, effect in enumerate(HIDDEN_EFFECTS):
        case = hidden_effect_case(effect, np.random.default_rng([SEED, index]))
        results[effect] = (case, diagnose(case.records))
    return results


def test_the_vocabulary_is_the_issues():
    assert VOCABULARY == (
        'viscous_damping',
        'stribeck',
        'asymmetric_friction',
        'cubic_stiffness',
        'second_mode',
        'velocity_offset',
        'sensor_delay',
        'mu_drift',
        'none',
        'unexplained',
    )


@pytest.mark.parametrize('effect', HIDDEN_EFFECTS)
def test_the_hidden_effect_is_named(diagnoses, effect):
    case, result = diagnoses[effect]
    assert result.missing_effect == effect, (case.ratio, result.verdict)
    assert result.named_effects == (() if effect == NONE else (effect,))
    assert result.candidates[0].effect == effect or effect == NONE
    if effect != NONE:
        assert result.candidates[0].score <= result.required_score
        assert result.gap_after <= 0.5 * result.gap_before
        assert result.frf_gap_after < result.frf_gap_before


@pytest.mark.parametrize('effect', [e for e in HIDDEN_EFFECTS if e != NONE])
def test_the_named_effects_parameters_are_the_hidden_ones(diagnoses, effect):
    case, result = diagnoses[effect]
    estimates = {p.name: p for p in result.parameters}
    name = f'{effect}.{SIZE[effect]}'
    truth = getattr(case.term, SIZE[effect])
    estimate = estimates[name]
    assert estimate.value == pytest.approx(truth, rel=0.15), (estimate, case.term)
    assert 0.0 < estimate.stderr < 0.1 * abs(truth)
    assert estimates['mu'].value == pytest.approx(case.mu, rel=0.01)
    units = {p.name: p.unit for p in result.parameters}
    assert units['mu'] == '1'


def test_clean_data_names_none_and_every_candidate_falls_short(diagnoses):
    case, result = diagnoses[NONE]
    assert result.missing_effect == NONE
    assert result.gap_after == result.gap_before
    assert all(c.score > result.required_score for c in result.candidates)
    assert result.mu == pytest.approx(case.mu, rel=2e-3)
    assert [p.name for p in result.parameters] == ['mu']
    assert result.noise_std_m_s == pytest.approx(1e-4, rel=0.03)
    assert result.force_noise_std_n == pytest.approx(0.2, rel=0.05)


def test_where_points_at_the_signature_of_the_effect(diagnoses):
    offset = diagnoses['velocity_offset'][1].where
    assert offset.rest_velocity_m_s == pytest.approx(
        diagnoses['velocity_offset'][0].term.offset_m_s, abs=5 * offset.rest_velocity_stderr_m_s
    )
    assert max(offset.frequency, key=lambda b: b.share).name == 'below f_n'
    delay = diagnoses['sensor_delay']
    assert delay[1].where.phase_delay_s == pytest.approx(delay[0].term.delay_s, rel=0.2)
    mode_case, mode = diagnoses['second_mode']
    assert mode.where.peaks[0].frequency_hz == pytest.approx(mode_case.term.frequency_hz, abs=0.5)
    assert 'non-harmonic peak' in mode.where.summary
    viscous = diagnoses['viscous_damping'][1].where
    # extra viscous damping bends the peak map below the base model's
    assert all(
        m.peak_map_slope < s.peak_map_slope
        for m, s in zip(viscous.measured, viscous.model, strict=True)
    )
    regions = {r.name: r for r in diagnoses['stribeck'][1].where.time}
    assert sum(r.share for r in regions.values()) == pytest.approx(1.0)


def test_json_has_the_issues_keys_and_is_json(diagnoses):
    payload = diagnosis_dict(diagnoses['stribeck'][1])
    for key in (
        'missing_effect',
        'parameters',
        'gap_before',
        'gap_after',
        'where',
        'candidates',
        'mu',
    ):
        assert key in payload
    assert payload['missing_effect'] == 'stribeck'
    assert set(payload['parameters']) == {
        'mu',
        'stribeck.mu_static_excess',
        'stribeck.stribeck_velocity_m_s',
        'stribeck.stribeck_exponent',
    }
    assert set(payload['parameter_at_bound']) == set(payload['parameters'])
    # three hits, one a level: mu_drift is a candidate (told from a speed law by each hit's
    # own friction map), not named here
    assert {c['effect'] for c in payload['candidates']} == set(EFFECTS)
    assert [named['effect'] for named in payload['missing_effects']] == ['stribeck']
    assert payload['missing_effects'][0]['score'] <= payload['required_score']
    assert set(payload['friction_map']) == {'speed', 'position'}
    assert set(payload['friction_map']['speed']) >= {'speed_m_s', 'mu', 'mu_stderr'}
    for candidate in payload['candidates']:
        assert set(candidate) >= {'effect', 'score', 'gap_after', 'parameters'}
    assert payload['where']['summary'] and payload['where']['time']
    json.dumps(payload, allow_nan=False)


def test_candidates_can_be_restricted_and_unknown_ones_are_refused(diagnoses):
    case, _ = diagnoses['velocity_offset']
    result = diagnose(case.records[:1], candidates=('velocity_offset', 'viscous_damping'))
    assert [c.effect for c in result.candidates][0] == 'velocity_offset'
    assert len(result.candidates) == 2
    assert result.missing_effect == 'velocity_offset'
    with pytest.raises(ValueError, match="unknown candidate effect.*'gravity'"):
        diagnose(case.records, candidates=('gravity',))


def test_start_values_come_from_the_signatures(diagnoses):
    # The offset starts at the measured velocity at rest, the delay at the phase slope.
    for effect, attribute in (('velocity_offset', 'offset_m_s'), ('sensor_delay', 'delay_s')):
        case, result = diagnoses[effect]
        impacts = [as_conditioned(r) for r in case.records]
        start = start_term(effect, impacts, result.where, case.rig)
        assert getattr(start, attribute) == pytest.approx(getattr(case.term, attribute), rel=0.25)


def test_a_record_without_a_hit_is_a_clear_failure():
    record = impact_record(1000.0, 1, duration_s=5.0)
    quiet = np.random.default_rng(1).normal(0.0, 0.2, record.force_n.size)
    with pytest.raises(FitError, match='no hit'):
        diagnose(
            [
                type(
                    'R',
                    (),
                    dict(force_n=quiet, velocity_m_s=record.velocity_m_s, sample_rate_hz=1e4),
                )()
            ]
        )
    with pytest.raises(ValueError, match='no impacts'):
        diagnose([])


def test_gaps_are_finite_and_non_negative(diagnoses):
    for _, result in diagnoses.values():
        for value in (
            result.gap_before,
            result.gap_after,
            result.frf_gap_before,
            result.frf_gap_after,
        ):
            assert math.isfinite(value) and value >= 0.0
