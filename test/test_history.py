"""The fitter's sample history: records cut by index equal the streamed samples."""

import numpy as np
import pytest

from fmm_ros.core.signal.history import SampleHistory

RATE_HZ = 10_000.0


def fed(history, force, velocity, batch, skip=()):
    for first in range(0, force.size, batch):
        history.feed('force', first, force[first : first + batch], RATE_HZ, 2000.0)
        if first not in skip:
            history.feed('velocity', first, velocity[first : first + batch], RATE_HZ)
    return history


def test_records_cut_from_the_rings_equal_the_streams_across_wrap_around():
    rng = np.random.default_rng(0)
    force, velocity = rng.normal(size=(2, 25_000))
    history = fed(SampleHistory(0.7), force, velocity, 500)
    record = history.record(19_000, 6_000, trigger_sample_index=19_100, source='x')
    assert record.force_n.tobytes() == force[19_000:25_000].tobytes()
    assert record.velocity_m_s.tobytes() == velocity[19_000:25_000].tobytes()
    assert (record.record_start_sample_index, record.trigger_sample_index) == (19_000, 19_100)
    assert (record.window_samples, record.force_full_scale_n) == (6_000, 2000.0)
    assert record.force_gaps == record.velocity_gaps == ()


def test_missing_batches_are_nan_gaps_and_unavailable_spans_are_refused():
    force, velocity = np.ones((2, 10_000))
    history = fed(SampleHistory(2.0), force, velocity, 500, skip={3_000})
    record = history.record(2_000, 4_000)
    assert record.velocity_gaps == ((1_000, 1_500),) and record.force_gaps == ()
    assert np.isnan(record.velocity_m_s[1_000:1_500]).all()
    with pytest.raises(ValueError, match='not all arrived'):
        history.record(8_000, 4_000)
    small = fed(SampleHistory(0.3), force, velocity, 500)
    with pytest.raises(ValueError, match='no longer held'):
        small.record(1_000, 2_000)
    assert small.holds(7_000) and not small.holds(6_999)


def test_bad_batches_are_refused_and_change_nothing():
    history = fed(SampleHistory(0.5), np.zeros(1_000), np.zeros(1_000), 500)
    assert history.capacity == 5_000  # sized from the batches' rate
    # A repeat is refused and counted; a batch at another rate is held as a possible new
    # acquisition and refused as a stray when the next batch continues the old sequence.
    history.feed('force', 500, np.ones(10), RATE_HZ)
    history.feed('velocity', 1_000, np.ones(10), 5_000.0)
    with pytest.raises(ValueError, match="'force' or 'velocity'"):
        history.feed('torque', 1_000, np.ones(10), RATE_HZ)
    assert history.next_index('force') == 1_000
    history.feed('velocity', 1_000, np.zeros(500), RATE_HZ)
    assert history.ledger['force'].faults == {'past': 1}
    assert history.ledger['velocity'].faults == {'stray': 1}
    assert not np.isnan(history.record(0, 1_000).force_n).any()


def test_a_new_acquisition_at_another_rate_resizes_the_history():
    history = fed(SampleHistory(0.5), np.zeros(1_000), np.zeros(1_000), 500)
    for first in range(0, 1_000, 100):  # restarted at 2 kHz: index 0 again
        history.feed('force', first, np.ones(100), 2_000.0)
        history.feed('velocity', first, np.ones(100), 2_000.0)
    assert (history.capacity, history.sample_rate_hz, history.acquisitions) == (1_000, 2_000.0, 2)
    assert history.record(0, 1_000).force_n.tolist() == [1.0] * 1_000
    assert history.ledger['force'].resyncs == 1 and history.ledger['force'].faults == {'rate': 1}


def test_held_spans_are_what_arrived_of_what_the_ring_still_holds():
    """For a recorder's recall: clipped to the ring, across its wrap, split where nothing came."""
    rng = np.random.default_rng(1)
    force, velocity = rng.normal(size=(2, 25_000))
    history = fed(SampleHistory(0.7), force, velocity, 500, skip={22_000})
    runs = history.held('velocity', 10_000, 30_000)  # the ring holds 18,000..25,000
    assert [(first, len(values)) for first, values in runs] == [(18_000, 4_000), (22_500, 2_500)]
    for first, values in runs:
        assert values.tobytes() == velocity[first : first + len(values)].tobytes()
    assert [(f, len(v)) for f, v in history.held('force', 20_000, 21_000)] == [(20_000, 1_000)]
    assert history.held('force', 25_000, 26_000) == [] == history.held('force', 1_000, 2_000)
