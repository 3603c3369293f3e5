"""fmm_ros.sim.hidden_effects: the proof data hides each effect at a lab-realistic size."""

from dataclasses import replace

import numpy as np
import pytest
import scipy.optimize

from fmm_ros.constants import PAPER_LEVELS
from fmm_ros.core.identify.conditioning import as_conditioned
from fmm_ros.core.physics.model import simulate
from fmm_ros.core.physics.terms import MODEL_TERMS
from fmm_ros.sim.hidden_effects import (
    HIDDEN_EFFECTS,
    MU_RANGE,
    RATIO_RANGE,
    base_fit_discrepancy,
    hidden_effect_case,
    hidden_session,
    motion_window,
)


def test_the_vocabulary_is_the_model_terms_and_none():
    assert HIDDEN_EFFECTS == (*MODEL_TERMS, 'none')
    assert set(HIDDEN_EFFECTS) == {
        'viscous_damping',
        'stribeck',
        'asymmetric_friction',
        'cubic_stiffness',
        'velocity_offset',
        'sensor_delay',
        'second_mode',
        'none',
    }


@pytest.mark.parametrize('effect', [e for e in HIDDEN_EFFECTS if e != 'none'])
def test_each_effect_is_sized_to_the_asked_ratio_of_the_noise(effect):
    case = hidden_effect_case(effect, 11, ratio=2.0, duration_s=8.0)
    assert case.effect == effect and case.term.name == effect
    assert case.ratio == pytest.approx(2.0, rel=0.1)


@pytest.mark.parametrize('effect', ['viscous_damping', 'sensor_delay'])
def test_the_sizing_matches_a_brute_force_fit_of_mu(effect):
    # The generator's linearised mu steps against a bounded scalar search on the noise-free
    # records: the discrepancy left by the best mu.
    clean = hidden_effect_case(
        effect, 12, ratio=3.0, duration_s=8.0, force_noise_std_n=0.0, velocity_noise_std_m_s=1e-4
    )
    records = [replace(r, velocity_m_s=r.simulation.velocity_m_s) for r in clean.records]

    def rms(mu):
        residual = [
            r.velocity_m_s[motion_window(r)]
            - simulate(r.force_n, r.sample_rate_hz, mu=mu).velocity_m_s[motion_window(r)]
            for r in records
        ]
        return float(np.sqrt(np.mean(np.concatenate(residual) ** 2)))

    best = scipy.optimize.minimize_scalar(
        rms, bounds=(0.5 * clean.mu, 1.5 * clean.mu), method='bounded', options={'xatol': 1e-7}
    )
    assert clean.ratio * 1e-4 == pytest.approx(best.fun, rel=0.03)
    assert base_fit_discrepancy(clean.records, clean.mu) == pytest.approx(
        clean.ratio * 1e-4, rel=1e-9
    )


@pytest.mark.slow
def test_a_case_is_random_levels_with_the_issues_noise_and_reproducible():
    case = hidden_effect_case('stribeck', 5)
    again = hidden_effect_case('stribeck', 5)
    other = hidden_effect_case('stribeck', 6)
    assert len(case.records) == 3
    assert RATIO_RANGE[0] <= case.ratio <= RATIO_RANGE[1] * 1.1
    assert MU_RANGE[0] <= case.mu <= MU_RANGE[1]
    np.testing.assert_array_equal(case.records[1].velocity_m_s, again.records[1].velocity_m_s)
    assert case.term == again.term and case.term != other.term
    for record in case.records:
        assert record.velocity_m_s.size == 330_000
        conditioned = as_conditioned(record)
        assert conditioned.velocity_noise_std_m_s == pytest.approx(1e-4, rel=0.03)
        assert conditioned.force_noise_std_n == pytest.approx(0.2, rel=0.03)
        nearest = min(PAPER_LEVELS, key=lambda level: abs(level.peak_force_n - record.peak_force_n))
        assert abs(nearest.peak_force_n - record.peak_force_n) < 150.0


def test_none_hides_nothing():
    case = hidden_effect_case('none', 3, duration_s=8.0, force_noise_std_n=0.0)
    assert case.term is None and case.ratio == 0.0
    assert base_fit_discrepancy(case.records, case.mu, case.rig) < 1e-9


def test_bad_arguments_are_refused():
    with pytest.raises(ValueError, match='unknown effect'):
        hidden_effect_case('gravity', 1)
    with pytest.raises(ValueError, match='n_impacts'):
        hidden_effect_case('none', 1, n_impacts=0)
    with pytest.raises(ValueError, match='velocity_noise_std_m_s'):
        hidden_effect_case('none', 1, velocity_noise_std_m_s=0.0)


@pytest.mark.parametrize(
    'effects',
    [('stribeck', 'sensor_delay'), ('mu_drift',), ('speed_regimes',), ('wear_track', 'stribeck')],
)
@pytest.mark.slow
def test_a_session_hides_each_effect_at_its_own_size(effects):
    session = hidden_session(
        effects, 21, n_impacts=4, ratio_range=(2.5, 2.5), duration_s=8.0, force_noise_std_n=0.0
    )
    assert set(session.ratios) == set(effects)
    for effect in effects:
        assert session.ratios[effect] == pytest.approx(2.5, rel=0.1), effect
    if len(effects) > 1:  # several at once are more than one
        assert base_fit_discrepancy(session.records, session.mu_per_hit[0], session.rig) > 3e-4
    assert {term.name for term in session.terms} == set(effects) & set(MODEL_TERMS)
    steps = np.diff(session.mu_per_hit)
    if 'mu_drift' in effects:
        assert np.all(np.abs(steps) > 0.0) and np.allclose(steps, steps[0])
    else:
        assert np.all(steps == 0.0)
    law = session.law
    if 'speed_regimes' in effects:
        assert law.kind == 'speed' and law.factor > 1.0 and 0.02 <= law.threshold <= 0.06
    if 'wear_track' in effects:
        assert law.kind == 'position' and law.factor != 1.0 and 1e-3 <= law.threshold <= 3e-3


def test_a_session_refuses_what_it_cannot_make():
    with pytest.raises(ValueError, match='distinct names'):
        hidden_session(('stribeck', 'stribeck'), 1)
    with pytest.raises(ValueError, match='distinct names'):
        hidden_session(('gravity',), 1)
    with pytest.raises(ValueError, match='at most one friction law'):
        hidden_session(('speed_regimes', 'wear_track'), 1)
    with pytest.raises(ValueError, match='at most one friction law, and only with'):
        hidden_session(('wear_track', 'sensor_delay'), 1)
    with pytest.raises(ValueError, match='n_impacts must be at least 2'):
        hidden_session(('mu_drift',), 1, n_impacts=1)
