"""Fault families in the signal core: every member, not the one instance.

- An acquisition that begins anywhere in a hit, or on any force offset: the capture never
  raises, the hit it began in is `truncated_start`, no record starts before the acquisition,
  and every later hit is reported (whatever the batch size).
- Every unit of the table, on the live path and in replay: converted once to SI; any other
  unit refused by name.
- Impact ids: derived from the trigger and the acquisition's clock, so a capture that joins
  the stream late (a restarted analyzer) gives the hits it sees the ids the first one gave.
"""

import re

import numpy as np
import pytest
from signal_records import hits

from fmm_ros.constants import FORCE, FORCE_TOPIC, VELOCITY, VELOCITY_TOPIC
from fmm_ros.core.signal.analysis import analyze_impact
from fmm_ros.core.signal.capture import CaptureConfig, ImpactCapture
from fmm_ros.core.signal.records import stable_impact_id
from fmm_ros.errors import UnitError
from fmm_ros.io.bags.writer import BagWriter
from fmm_ros.units import FORCE_UNITS, VELOCITY_UNITS, sample_si_factor
from fmm_ros.workflows.replay import replay_bag

RATE_HZ = 2000.0
CONFIG = CaptureConfig(window_s=2.0, min_spacing_s=0.5, rest_time_s=0.5, max_skew_s=1.0)
HIT_AT_S = (0.7, 3.0, 5.5)
PULSE_S = 0.004


def session(offset_n=0.0, seconds=8.0):
    """Three hits, force with a constant offset, small noise."""
    n = int(seconds * RATE_HZ)
    at = [
        (int(t * RATE_HZ), peak) for t, peak in zip(HIT_AT_S, (450.0, 1000.0, 1450.0), strict=True)
    ]
    force, velocity = hits(n, RATE_HZ, at, zeta=0.08, duration_s=PULSE_S)
    rng = np.random.default_rng(7)
    return force + offset_n + rng.normal(0, 0.3, n), velocity + rng.normal(0, 1e-5, n)


def capture(force, velocity, first, batch, origin_s=None):
    """Every record of the channels from sample `first` on, fed in batches as a node is."""
    impacts = ImpactCapture(CONFIG)
    records = []
    for low in range(first, force.size, batch):
        high = min(low + batch, force.size)
        stamp = round((origin_s + low / RATE_HZ) * 1e9) if origin_s else 0
        for quantity, samples in ((FORCE.quantity, force), (VELOCITY.quantity, velocity)):
            records += impacts.feed(quantity, low, samples[low:high], RATE_HZ, stamp_ns=stamp)
    return records + impacts.flush()


# Where the acquisition begins, relative to the first hit's pulse start [s]: in the
# pre-trigger, at contact, on the rise, at the peak, on the fall, just after contact.
STARTS_S = (-0.004, 0.0, 0.0005, PULSE_S / 2, 0.003, PULSE_S + 0.001)


@pytest.mark.parametrize('batch', [97, 1000])
@pytest.mark.parametrize('start_s', STARTS_S)
def test_an_acquisition_begun_in_any_part_of_a_hit_flags_it_and_reports_the_later_ones(
    start_s, batch
):
    force, velocity = session()
    first = int((HIT_AT_S[0] + start_s) * RATE_HZ)
    records = capture(force, velocity, first, batch)
    results = [analyze_impact(record, CONFIG) for record in records]
    later = [r for r in results if r.trigger_sample_index > HIT_AT_S[0] * RATE_HZ + 100]
    assert len(later) == 2 and all('truncated_start' not in r.flags for r in later)
    assert all(r.record_start_sample_index >= first for r in results)
    in_contact = 0.0 <= start_s < PULSE_S
    first_hit = [r for r in results if r not in later]
    if in_contact or start_s < 0:  # the hit's start or its pre-trigger was never acquired
        assert len(first_hit) == 1 and 'truncated_start' in first_hit[0].flags
    else:  # began after the contact: nothing of the hit to report
        assert first_hit == []


@pytest.mark.parametrize('offset_n', [-30.0, 0.0, 10.0, 25.0, 100.0])
def test_a_force_offset_of_any_size_loses_no_later_hit(offset_n):
    """Below the re-arm level, between it and the trigger, above the trigger: all hits found."""
    force, velocity = session(offset_n)
    results = [analyze_impact(r, CONFIG) for r in capture(force, velocity, 0, 500)]
    above_trigger = offset_n >= CONFIG.trigger_level_n
    hits_found = [r for r in results if 'truncated_start' not in r.flags]
    assert [round(r.trigger_sample_index / RATE_HZ, 1) for r in hits_found] == list(HIT_AT_S)
    # On an offset above the trigger the acquisition begins "in contact": that is flagged.
    assert len(results) - len(hits_found) == int(above_trigger)
    assert all(r.record_start_sample_index >= 0 for r in results)


@pytest.mark.slow
def test_the_flagged_record_converts_to_a_message():
    """The record that began before the acquisition no longer overflows the uint64 fields."""
    from fmm_ros.ros import msgs  # the message layer (rclpy types), as the analyzer uses it

    force, velocity = session(offset_n=25.0)
    record = capture(force, velocity, 0, 500)[0]
    message = msgs.impact_result_msg(analyze_impact(record, CONFIG), stamp=msgs.time_msg(0))
    assert 'truncated_start' in message.flags and message.record_start_sample_index == 0


@pytest.mark.parametrize('join_s', [0.0, 1.3, 2.99, 4.0])
def test_a_capture_joining_late_gives_each_hit_the_id_the_first_gave(join_s):
    force, velocity = session()
    origin_s = 1_764_000_000.123456
    whole = {
        r.trigger_sample_index: stable_impact_id(r)
        for r in capture(force, velocity, 0, 500, origin_s)
    }
    joined = {
        r.trigger_sample_index: stable_impact_id(r)
        for r in capture(force, velocity, int(join_s * RATE_HZ), 500, origin_s)
    }
    assert len(set(whole.values())) == len(whole) == 3
    assert joined and all(whole[trigger] == joined[trigger] for trigger in joined)
    # Another acquisition (another clock) gives its hits other ids.
    other = capture(force, velocity, 0, 500, origin_s + 600.0)
    assert not {stable_impact_id(r) for r in other} & set(whole.values())


@pytest.mark.slow
@pytest.mark.parametrize(
    ('quantity', 'unit', 'factor'),
    [('force', unit, factor) for unit, factor in FORCE_UNITS.items()]
    + [('velocity', unit, factor) for unit, factor in VELOCITY_UNITS.items()],
)
def test_every_unit_of_the_table_replays_as_si(tmp_path, quantity, unit, factor):
    """A bag in any force or velocity unit of the table gives the hits and |X/F| of SI."""
    force, velocity = session(seconds=4.0)
    want = replay_bag(_bag(tmp_path / 'si', force, velocity, 'N', 'm/s'), CONFIG)
    units = {'force': 'N', 'velocity': 'm/s', quantity: unit}
    got = replay_bag(
        _bag(
            tmp_path / 'unit',
            force / (factor if quantity == 'force' else 1.0),
            velocity / (factor if quantity == 'velocity' else 1.0),
            units['force'],
            units['velocity'],
        ),
        CONFIG,
    )
    assert len(got.results) == len(want.results) == 2
    for a, b in zip(got.results, want.results, strict=True):
        assert a.flags == b.flags
        assert a.peak_receptance_m_per_n == pytest.approx(
            b.peak_receptance_m_per_n, rel=1e-9, nan_ok=True
        )
        assert a.impulse_n_s == pytest.approx(b.impulse_n_s, rel=1e-9, nan_ok=True)


@pytest.mark.slow
@pytest.mark.parametrize(
    ('quantity', 'unit'), [('force', 'kp'), ('velocity', 'm/s^2'), ('force', 'm/s')]
)
def test_a_unit_the_table_does_not_know_is_refused_by_name(tmp_path, quantity, unit):
    force, velocity = session(seconds=2.0)
    units = {'force': 'N', 'velocity': 'm/s', quantity: unit}
    bag = _bag(tmp_path / 'bag', force, velocity, units['force'], units['velocity'])
    with pytest.raises(UnitError, match=re.escape(repr(unit))):
        replay_bag(bag, CONFIG)
    with pytest.raises(UnitError):
        sample_si_factor(quantity, unit)
    assert sample_si_factor(quantity, '') == 1.0  # the message's SI default


def _bag(path, force, velocity, force_unit, velocity_unit):
    with BagWriter(path, time_origin_ns=1_764_000_000_000_000_000) as writer:
        for low in range(0, force.size, 500):
            for topic, quantity, unit, samples in (
                (FORCE_TOPIC, FORCE.quantity, force_unit, force),
                (VELOCITY_TOPIC, VELOCITY.quantity, velocity_unit, velocity),
            ):
                writer.write_sample_batch(
                    topic,
                    samples[low : low + 500],
                    quantity=(quantity, unit),
                    sample_rate_hz=RATE_HZ,
                    first_sample_index=low,
                )
    return path
