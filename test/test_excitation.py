"""fmm_ros.sim.excitation: pulse shapes and impulses, the paper's levels, impact records."""

import math

import numpy as np
import pytest

from fmm_ros.constants import LEVEL_TOLERANCE_N, PAPER_LEVELS
from fmm_ros.core.physics.model import simulate
from fmm_ros.core.physics.terms import model_term
from fmm_ros.sim.excitation import (
    half_sine_duration_s,
    half_sine_pulse,
    hammer_pulse,
    impact_record,
    level_contact_duration_s,
    level_peak_force_n,
    paper_level,
    rectangular_pulse,
    tip_contact_duration_s,
)

RATE_HZ = 10_000.0


def trapezoid_impulse(force, rate_hz=RATE_HZ):
    return np.trapezoid(force) / rate_hz


def test_paper_levels_and_their_half_sine_contact_durations():
    durations_ms = {level.name: level_contact_duration_s(level) * 1e3 for level in PAPER_LEVELS}
    assert durations_ms == pytest.approx({'low': 3.4, 'medium': 2.2, 'high': 1.8}, abs=0.05)
    assert LEVEL_TOLERANCE_N == 50.0
    for level in PAPER_LEVELS:
        # the tip law fitted through the three levels reproduces each within 2 %
        assert tip_contact_duration_s(level.peak_force_n) == pytest.approx(
            level_contact_duration_s(level), rel=0.02
        )
    # a harder hit is a shorter one (the rubber tip stiffens)
    assert tip_contact_duration_s(2000.0) < tip_contact_duration_s(1000.0)


def test_half_sine_pulse_has_the_requested_peak_duration_and_impulse():
    peak, contact = 1000.0, 2.2e-3
    force = half_sine_pulse(peak, contact, RATE_HZ, 0.1, start_s=0.01)
    assert force.size == 1000
    nonzero = np.flatnonzero(force)
    assert (nonzero[0], nonzero[-1]) == (101, 121)  # 0.0100 s is sin(0) = 0, 0.0122 s too
    assert force.max() == pytest.approx(peak, rel=1e-3)
    # 22 samples under the arc: the trapezoid rule reads pi^2 / (12 * 22^2) = 0.17 % low
    assert trapezoid_impulse(force) == pytest.approx(2 * peak * contact / math.pi, rel=3e-3)
    assert half_sine_duration_s(peak, trapezoid_impulse(force)) == pytest.approx(contact, rel=3e-3)


def test_hammer_pulse_is_skewed_but_keeps_the_half_sine_impulse():
    peak, contact = 1450.0, 1.8e-3
    rate = 1e6  # fine enough to see the shape
    skewed = hammer_pulse(peak, contact, rate, 0.01, start_s=1e-3, rise_fraction=0.3)
    assert np.argmax(skewed) / rate == pytest.approx(1e-3 + 0.3 * contact, abs=2 / rate)
    assert trapezoid_impulse(skewed, rate) == pytest.approx(2 * peak * contact / math.pi, rel=1e-6)
    np.testing.assert_array_equal(
        hammer_pulse(peak, contact, rate, 0.01, start_s=1e-3, rise_fraction=0.5),
        half_sine_pulse(peak, contact, rate, 0.01, start_s=1e-3),
    )


@pytest.mark.parametrize(('force_n', 'width_s'), [(100.0, 2.5e-3), (25.0, 10e-3)])
def test_rectangular_pulse_impulse_is_force_times_duration(force_n, width_s):
    force = rectangular_pulse(force_n, width_s, RATE_HZ, 1.0, start_s=0.01)
    assert np.count_nonzero(force) == round(width_s * RATE_HZ)
    assert np.flatnonzero(force)[0] == 100
    assert trapezoid_impulse(force) == pytest.approx(force_n * width_s, rel=1e-12)


def test_impact_record_defaults_and_contents():
    record = impact_record(paper_level('medium').peak_force_n, rng=3)
    assert record.force_n.size == record.velocity_m_s.size == 330_000
    assert record.sample_rate_hz == RATE_HZ
    assert record.time_s[-1] == pytest.approx(33.0 - 1e-4)
    assert record.trigger_index == 1001  # 0.1 s pre-trigger plus a fraction of a sample
    assert record.impulse_n_s == pytest.approx(paper_level('medium').impulse_n_s, rel=0.03)
    pre = slice(0, record.trigger_index)
    assert np.std(record.force_n[pre]) == pytest.approx(0.05, rel=0.15)
    assert np.std(record.velocity_m_s[pre]) == pytest.approx(1e-5, rel=0.15)
    assert np.max(record.force_n) == pytest.approx(1000.0, abs=15.0)
    noise = record.velocity_m_s - record.simulation.velocity_m_s
    assert np.std(noise) == pytest.approx(1e-5, rel=0.02)
    assert record.simulation.at_rest


def test_impact_record_is_reproducible_from_a_seed_or_generator():
    effects = (model_term('velocity_offset'),)
    a = impact_record(450.0, rng=11, duration_s=3.0, effects=effects)
    b = impact_record(450.0, rng=np.random.default_rng(11), duration_s=3.0, effects=effects)
    c = impact_record(450.0, rng=12, duration_s=3.0, effects=effects)
    np.testing.assert_array_equal(a.force_n, b.force_n)
    np.testing.assert_array_equal(a.velocity_m_s, b.velocity_m_s)
    assert not np.array_equal(a.force_n, c.force_n)


def test_impact_record_velocity_is_the_model_response_to_the_clean_pulse():
    record = impact_record(
        1450.0, rng=5, duration_s=4.0, force_noise_std_n=0.0, velocity_noise_std_m_s=0.0
    )
    again = simulate(record.force_n, RATE_HZ)
    np.testing.assert_array_equal(record.velocity_m_s, again.velocity_m_s)
    assert record.peak_force_n == 1450.0
    assert record.impulse_n_s == pytest.approx(trapezoid_impulse(record.force_n), rel=1e-12)


def test_level_peak_force_scatters_about_the_nominal_level():
    peaks = [level_peak_force_n('high', rng=seed) for seed in range(400)]
    assert np.mean(peaks) == pytest.approx(1450.0, abs=5.0)
    assert np.std(peaks) == pytest.approx(30.0, rel=0.15)
    assert level_peak_force_n('low', rng=1) == level_peak_force_n('low', rng=1)


@pytest.mark.parametrize(
    ('call', 'message'),
    [
        (lambda: half_sine_pulse(-5.0, 1e-3, RATE_HZ, 1.0), 'peak_force_n must be positive'),
        (lambda: half_sine_pulse(100.0, 0.0, RATE_HZ, 1.0), 'contact_duration_s must be positive'),
        (lambda: half_sine_pulse(100.0, 1e-3, RATE_HZ, 1.0, start_s=1.0), 'does not fit'),
        (lambda: hammer_pulse(100.0, 1e-3, RATE_HZ, 1.0, rise_fraction=1.0), 'rise_fraction'),
        (lambda: rectangular_pulse(100.0, 1e-5, RATE_HZ, 1.0), 'shorter than one sample'),
        (lambda: rectangular_pulse(math.nan, 1e-3, RATE_HZ, 1.0), 'force_n must be finite'),
        (
            lambda: impact_record(1000.0, rng=1, force_noise_std_n=-1.0),
            'force_noise_std_n must not be negative',
        ),
        (
            lambda: impact_record(1000.0, rng=1, sample_rate_hz=0.0),
            'sample_rate_hz must be positive',
        ),
        (lambda: level_peak_force_n('extreme', rng=1), "unknown hammer level 'extreme'"),
    ],
)
def test_bad_input_raises_a_value_error_naming_the_problem(call, message):
    with pytest.raises(ValueError, match=message):
        call()
