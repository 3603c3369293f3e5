"""The simulated session: schedule draw, and force streams independent of batching."""

import numpy as np
import pytest

from fmm_ros.core.physics.terms import parse_model_term
from fmm_ros.sim.excitation import tip_contact_duration_s
from fmm_ros.sim.hammer import HammerStream, add_indexed_noise, session_schedule

RATE_HZ = 10_000.0
LEVELS = [('low', 450.0), ('medium', 1000.0), ('high', 1450.0)]


def schedule(**kwargs):
    args = dict(sample_rate_hz=RATE_HZ, spacing_s=2.0, first_hit_s=0.5, rng=4) | kwargs
    return session_schedule(LEVELS, 3, **args)


def render(stream, batch, stop):
    applied, measured = [], []
    for first in range(0, stop, batch):
        n = min(batch, stop - first)
        a = stream.applied(first, np.empty(n))
        applied.append(a.copy())
        measured.append(stream.measured(a, first, np.empty(n)))
    return np.concatenate(applied), np.concatenate(measured)


def test_schedule_follows_the_protocol():
    hits = schedule()
    assert [hit.level for hit in hits] == ['low'] * 3 + ['medium'] * 3 + ['high'] * 3
    starts = np.array([hit.start_index for hit in hits]) / RATE_HZ
    np.testing.assert_allclose(np.diff(starts), 2.0, atol=1.1 / RATE_HZ)
    for hit, (_, nominal) in zip(hits, [level for level in LEVELS for _ in range(3)], strict=True):
        assert abs(hit.peak_force_n - nominal) < 100.0
        assert hit.contact_duration_s == tip_contact_duration_s(hit.peak_force_n)
    assert schedule() == hits and schedule(rng=5) != hits


def test_streams_do_not_depend_on_the_batch_size():
    stream = HammerStream(schedule(), RATE_HZ, noise_std_n=0.2, seed=9)
    stop = stream.end_index + 1000
    one = render(stream, stop, stop)
    for batch in (500, 4096, 7777):
        for whole, cut in zip(one, render(stream, batch, stop), strict=True):
            assert whole.tobytes() == cut.tobytes()
    for whole, cut in zip(one, render(stream, 3, 8000), strict=True):  # across the first hit
        assert whole[:8000].tobytes() == cut.tobytes()
    applied, measured = one
    assert np.std(measured - applied) == pytest.approx(0.2, rel=0.02)
    # Each pulse lands whole: its area is the half-sine-like hit's 2 F T / pi.
    for hit in schedule():
        first = int(hit.start_index)
        area = np.trapezoid(applied[first - 2 : first + int(hit.contact_duration_s * RATE_HZ) + 3])
        assert area / RATE_HZ == pytest.approx(
            2 * hit.peak_force_n * hit.contact_duration_s / np.pi, rel=0.01
        )


def test_hits_are_counted_once_their_first_sample_is_out():
    stream = HammerStream(schedule(), RATE_HZ, noise_std_n=0.0, seed=0)
    first = int(schedule()[0].start_index)
    assert stream.hits_started_before(first) == 0
    assert stream.hits_started_before(first + 1) == 1
    assert stream.hits_started_before(stream.end_index) == 9


def test_indexed_noise_depends_on_the_index_only():
    whole = add_indexed_noise(np.zeros(10_000), 123, 1.0, seed=3)
    parts = np.concatenate(
        [
            add_indexed_noise(np.zeros(n), 123 + sum((700, 4000)[:i]), 1.0, 3)
            for i, n in enumerate((700, 4000, 5300))
        ]
    )
    assert whole.tobytes() == parts.tobytes()
    assert not np.array_equal(whole, add_indexed_noise(np.zeros(10_000), 123, 1.0, seed=4))


@pytest.mark.parametrize(
    ('kwargs', 'message'),
    [
        (dict(spacing_s=0.0), 'spacing_s'),
        (dict(spread_std_n=-1.0), 'spread_std_n'),
    ],
)
def test_bad_schedules_are_refused(kwargs, message):
    with pytest.raises(ValueError, match=message):
        schedule(**kwargs)
    with pytest.raises(ValueError, match='at least one force level'):
        session_schedule([], 3, sample_rate_hz=RATE_HZ, spacing_s=1.0, first_hit_s=0.0, rng=0)


def test_model_terms_from_text():
    term = parse_model_term('stribeck: mu_static_excess=0.03, stribeck_velocity_m_s=0.001')
    assert (term.name, term.mu_static_excess, term.stribeck_velocity_m_s) == (
        'stribeck',
        0.03,
        0.001,
    )
    assert parse_model_term('velocity_offset').offset_m_s == 1e-4
    for text, message in [
        ('nope', 'unknown model term'),
        ('stribeck:x=1', 'no parameter x'),
        ('stribeck:mu_static_excess', 'is not param=number'),
        ('stribeck:mu_static_excess=abc', 'is not param=number'),
    ]:
        with pytest.raises(ValueError, match=message):
            parse_model_term(text)
