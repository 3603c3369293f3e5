"""Open-world diagnosis: several effects at once, 'unexplained', mu drift, friction map.

Proof data from `fmm_ros.sim.hidden_effects.hidden_session`: 0.2 N / 1e-4 m/s noise, random
levels and mu; pairs of terms each 2-4x the velocity noise alone, mu drifting over eight hits,
two friction laws no term expresses (velocity strengthening above a transition speed, a worn
groove), clean sessions. The diagnosis sees only force and velocity. A few fixed cases check
the answers in detail; `test_a_small_sweep_holds_the_claims` runs a few random cases of each
kind (the full sweep with its confusion table is benchmarks/bench_diagnose.py).
"""

import json

import numpy as np
import pytest

from fmm_ros.constants import MU_DRIFT
from fmm_ros.core.diagnose import UNEXPLAINED, diagnose
from fmm_ros.core.physics.terms import EFFECT_SIZE, MODEL_TERMS
from fmm_ros.sim.hidden_effects import OUT_OF_VOCABULARY, hidden_session
from fmm_ros.workflows.results import diagnosis_dict

pytestmark = pytest.mark.slow

SEED = 13


@pytest.fixture(scope='module')
def cases():
    """One diagnosis of each fixed case, shared by the tests below."""
    specs = {
        'stribeck+delay': (('stribeck', 'sensor_delay'), 3),
        'viscous+mode': (('viscous_damping', 'second_mode'), 3),
        'drift': ((MU_DRIFT,), 8),
        'speed_regimes': (('speed_regimes',), 3),
        'wear_track': (('wear_track',), 3),
        'clean8': ((), 8),
    }
    results = {}
    for index, (name, (effects, hits)) in enumerate(specs.items()):
        session = hidden_session(
            effects,
            np.random.default_rng([SEED, index]),
            n_impacts=hits,
            ratio_range=(2.0, 4.0),
        )
        lines = []
        results[name] = (session, diagnose(session.records, progress=lines.append), lines)
    return results


@pytest.mark.parametrize('name', ['stribeck+delay', 'viscous+mode'])
def test_both_effects_of_a_pair_are_named_with_their_parameters(cases, name):
    session, result, _ = cases[name]
    assert set(result.named_effects) == set(session.effects), result.verdict
    assert result.missing_effect == result.named_effects[0]
    assert result.gap_after <= 0.25 * result.gap_before
    for named in result.missing_effects:
        assert named.score <= result.required_score and named.drop_score > -result.required_score
        assert not named.partial
        term = next(t for t in session.terms if t.name == named.effect)
        size, _ = EFFECT_SIZE[named.effect]
        estimate = {p.name: p for p in named.parameters}[f'{named.effect}.{size}']
        assert estimate.value == pytest.approx(getattr(term, size), rel=0.15)


@pytest.mark.parametrize('name', OUT_OF_VOCABULARY)
def test_a_law_outside_the_vocabulary_is_unexplained_and_located(cases, name):
    _, result, _ = cases[name]
    assert result.missing_effect == UNEXPLAINED, result.verdict
    unexplained = result.missing_effects[0]
    assert unexplained.where is not None and unexplained.where.excess_to_noise > 0.5
    assert len(unexplained.where.speed) == len(unexplained.where.position) == 8
    assert all(named.partial for named in result.missing_effects[1:])
    assert result.verdict.startswith('unexplained:') and 'speed' in result.verdict


def test_a_drifting_mu_is_named_with_each_hits_mu_and_the_slope(cases):
    session, result, _ = cases['drift']
    assert result.named_effects == (MU_DRIFT,), result.verdict
    trend = result.missing_effects[0].trend
    assert trend.refitted and trend.p_value < 1e-6
    truth = np.diff(session.mu_per_hit)[0]
    assert trend.slope_per_hit == pytest.approx(truth, abs=4 * trend.slope_stderr)
    errors = np.array(trend.mu_stderr)
    assert np.all(np.abs(np.array(trend.mu) - session.mu_per_hit) < 5 * errors + 2e-4)
    assert result.gap_after <= 0.5 * result.gap_before
    assert result.mu_trend == trend
    payload = diagnosis_dict(result)
    drift = payload['missing_effects'][0]
    assert drift['effect'] == MU_DRIFT and len(drift['mu_per_hit']) == 8
    assert drift['slope_per_hit'] == pytest.approx(trend.slope_per_hit)
    json.dumps(payload, allow_nan=False)


def test_a_clean_session_of_eight_hits_names_nothing_and_shows_no_trend(cases):
    session, result, _ = cases['clean8']
    assert result.named_effects == () and result.missing_effect == 'none', result.verdict
    assert not result.mu_trend.refitted and result.mu_trend.p_value > 1e-3
    assert result.residual_where.excess_to_noise < 0.5
    speed = result.friction_map.speed
    pulls = (np.array(speed.mu) - session.mu_per_hit[0]) / np.array(speed.mu_stderr)
    assert np.all(np.abs(pulls) < 5.0)


def test_the_friction_map_shows_the_speed_and_position_laws(cases):
    speed = cases['speed_regimes'][1].friction_map.speed
    law = cases['speed_regimes'][0].law
    below = [
        (mu, e)
        for v, mu, e in zip(speed.centres, speed.mu, speed.mu_stderr, strict=True)
        if v < 0.5 * law.threshold
    ]
    above = [
        (mu, e)
        for v, mu, e in zip(speed.centres, speed.mu, speed.mu_stderr, strict=True)
        if v > 2.0 * law.threshold
    ]
    assert below and above
    step = np.mean([mu for mu, _ in above]) - np.mean([mu for mu, _ in below])
    truth = (law.factor - 1.0) * cases['speed_regimes'][0].mu_per_hit[0]
    assert step == pytest.approx(truth, rel=0.3)
    session, result, _ = cases['wear_track']
    position = result.friction_map.position
    groove = session.law
    inside = [
        mu
        for x, mu in zip(position.centres, position.mu, strict=True)
        if abs(x - groove.centre_m) < 0.5 * groove.threshold
    ]
    outside = [
        mu
        for x, mu in zip(position.centres, position.mu, strict=True)
        if abs(x - groove.centre_m) > 1.5 * groove.threshold
    ]
    assert inside and outside
    contrast = np.mean(inside) - np.mean(outside)
    assert contrast == pytest.approx((groove.factor - 1.0) * session.mu_per_hit[0], rel=0.35)


def test_progress_reports_every_screen_refit_and_step(cases):
    _, result, lines = cases['stribeck+delay']
    assert lines[0].startswith('base model fitted to 3 impact(s)')
    assert any(line.startswith('step 1: screened stribeck') for line in lines)
    assert any(line.startswith('step 1: refitted') for line in lines)
    assert any(line.startswith('backward check') for line in lines)
    assert lines[-1] == result.verdict


def test_a_small_sweep_holds_the_claims():
    """Three random cases of each kind: pairs named, outside laws unexplained, drift named,
    clean sessions clean (the benchmark runs ten of each)."""
    wrong = []
    kinds = ['pair', MU_DRIFT, *OUT_OF_VOCABULARY, 'clean']
    for row, kind in enumerate(kinds):
        for case in range(3):
            rng = np.random.default_rng([SEED, 100 + row, case])
            if kind == 'pair':
                effects = tuple(str(e) for e in rng.choice(list(MODEL_TERMS), 2, replace=False))
            else:
                effects = () if kind == 'clean' else (kind,)
            hits = 8 if kind == MU_DRIFT else 3
            session = hidden_session(effects, rng, n_impacts=hits, ratio_range=(2.0, 4.0))
            named = diagnose(session.records).named_effects
            if kind in OUT_OF_VOCABULARY:
                right = bool(named) and named[0] == UNEXPLAINED
            else:
                right = sorted(named) == sorted(effects)
            if not right:
                wrong.append((kind, effects, named))
    assert wrong == []


@pytest.mark.parametrize('name', ['drift', 'wear_track'])
def test_the_service_carries_the_list_the_trend_and_the_map(cases, name):
    """What the fitter node fills is what `fmm ros call diagnose` reads back and prints."""
    from fmm_interfaces.srv import DiagnoseModel
    from fmm_ros.cli.formats import diagnosis_text
    from fmm_ros.ros import msgs

    _, result, _ = cases[name]
    sent = diagnosis_dict(result)
    received = msgs.diagnose_response_dict(
        msgs.fill_diagnose_response(DiagnoseModel.Response(), result)
    )
    json.dumps(received, allow_nan=False)  # what `fmm ros call diagnose --json` prints
    for key in ('missing_effect', 'selection', 'verdict', 'parameter_at_bound'):
        assert received[key] == sent[key]
    for got, want in zip(received['missing_effects'], sent['missing_effects'], strict=True):
        for key in (
            'effect',
            'score',
            'drop_score',
            'partial',
            'parameters',
            'parameter_units',
            'parameter_at_bound',
        ):
            assert got[key] == want[key]
        if 'where' in want:
            assert got['where']['summary'] == want['where']['summary']
        if 'slope_per_hit' in want:
            assert got['mu_per_hit'] == want['mu_per_hit']
            assert got['trend_p_value'] == want['trend_p_value']
    for axis, key in (('speed', 'speed_m_s'), ('position', 'position_m')):
        for field in (key, 'mu', 'mu_stderr'):
            assert received['friction_map'][axis][field] == sent['friction_map'][axis][field]
    for got, want in zip(received['candidates'], sent['candidates'], strict=True):
        assert got['detection_limit'] == want['detection_limit']
        assert got['parameters'] == want['parameters']
        assert got.get('unobservable') == want.get('unobservable')
    assert any(candidate['detection_limit'] for candidate in sent['candidates'])
    assert diagnosis_text(received, 8).splitlines()[1] == diagnosis_text(sent, 8).splitlines()[1]
