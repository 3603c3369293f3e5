"""Impact capture: the trigger rule, streaming == batch to the last bit, gaps, skew, buffers."""

import numpy as np
import pytest
from signal_records import hits

from fmm_ros.core.signal.analysis import analyze_impact
from fmm_ros.core.signal.capture import (
    CaptureConfig,
    ImpactCapture,
    TriggerDetector,
    capture_impacts,
    find_triggers,
)
from fmm_ros.core.signal.quality import quality_flags

RATE_HZ = 1000.0
# A short window and a low rate keep the sample-by-sample runs quick; the logic is rate-free.
SHORT = CaptureConfig(window_s=3.0, min_spacing_s=0.5, rest_time_s=0.5, max_skew_s=1.0)


def stream(n_seconds=14.0, rate_hz=RATE_HZ):
    """Force and velocity with four hits (one double, two overlapping) and noise after rest."""
    n = int(n_seconds * rate_hz)
    at = [
        (int(1.0 * rate_hz), 450.0),
        (int(1.03 * rate_hz), 80.0),
        (int(5.0 * rate_hz), 1000.0),
        (int(6.5 * rate_hz), 1450.0),
        (int(11.0 * rate_hz), 600.0),
    ]
    force, velocity = hits(n, rate_hz, at, zeta=0.08, duration_s=0.005)
    rng = np.random.default_rng(4)
    return force + rng.normal(0, 0.5, n), velocity + rng.normal(0, 2e-5, n)


def assert_same_records(got, want):
    assert [r.trigger_sample_index for r in got] == [r.trigger_sample_index for r in want]
    for a, b in zip(got, want, strict=True):
        assert a.record_start_sample_index == b.record_start_sample_index
        assert a.window_samples == b.window_samples
        assert a.force_n.tobytes() == b.force_n.tobytes()
        assert a.velocity_m_s.tobytes() == b.velocity_m_s.tobytes()
        assert a.force_gaps == b.force_gaps and a.velocity_gaps == b.velocity_gaps


def feed_in_pieces(force, velocity, config, sizes, lag_batches=0, drop=()):
    """Feed each channel in pieces of the given sizes, velocity `lag_batches` pieces behind."""
    capture = ImpactCapture(config)
    bounds = np.cumsum([0, *sizes])
    pieces = [(int(a), int(b)) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]
    records = []
    for i in range(len(pieces) + lag_batches):
        if i < len(pieces) and ('force', i) not in drop:
            a, b = pieces[i]
            records += capture.feed('force', a, force[a:b], RATE_HZ)
        j = i - lag_batches
        if 0 <= j < len(pieces) and ('velocity', j) not in drop:
            a, b = pieces[j]
            records += capture.feed('velocity', a, velocity[a:b], RATE_HZ)
    return records + capture.flush()


def random_sizes(n, rng, low=1, high=700):
    sizes = []
    while sum(sizes) < n:
        sizes.append(int(rng.integers(low, high)))
    sizes[-1] -= sum(sizes) - n
    return sizes


def test_trigger_rule_hysteresis_and_spacing():
    config = CaptureConfig(trigger_level_n=20.0, rearm_level_n=5.0, min_spacing_s=0.1)
    force = np.zeros(1000)
    force[100:110] = [0, 10, 25, 30, 19, 21, 30, 12, 6, 0]  # wobbles above/below 20 N: one hit
    force[150:153] = [30, 40, 0]  # inside min spacing: no trigger
    force[300:303] = [21, 22, 0]  # after spacing, re-armed: trigger
    force[303:306] = [0, 0, 0]
    assert find_triggers(force, 1000.0, config).tolist() == [102, 300]
    never_rearmed = force.copy()
    never_rearmed[105:300] = 10.0  # stays above the re-arm level
    assert find_triggers(never_rearmed, 1000.0, config).tolist() == [102]


def test_trigger_detector_is_independent_of_block_sizes():
    force, _ = stream()
    whole = find_triggers(force, RATE_HZ, SHORT)
    assert len(whole) == 4  # 450 N + bounce counts once
    rng = np.random.default_rng(1)
    for _ in range(5):
        detector = TriggerDetector(SHORT, RATE_HZ)
        found, first = [], 0
        for size in random_sizes(force.size, rng, 1, 50):
            found += detector.scan(force[first : first + size], first)
            first += size
        assert found == whole.tolist()


@pytest.mark.parametrize('end_at_rest', [False, True])
def test_streaming_equals_batch_to_the_last_bit(end_at_rest):
    # Velocity will run up to 25 batches (< 7.5 s) behind force: within max_skew_s.
    config = CaptureConfig(
        window_s=3.0, min_spacing_s=0.5, rest_time_s=0.5, max_skew_s=8.0, end_at_rest=end_at_rest
    )
    force, velocity = stream()
    batch = capture_impacts(force, velocity, RATE_HZ, config)
    assert [r.trigger_sample_index for r in batch] == find_triggers(force, RATE_HZ, config).tolist()
    one_at_a_time = feed_in_pieces(force, velocity, config, [1] * force.size)
    assert_same_records(one_at_a_time, batch)
    rng = np.random.default_rng(7)
    for lag in (0, 3, 25):
        sizes = random_sizes(force.size, rng, 1, 300)
        assert_same_records(feed_in_pieces(force, velocity, config, sizes, lag), batch)
    # The analysis of identical records is identical too.
    for a, b in zip(one_at_a_time, batch, strict=True):
        ra, rb = analyze_impact(a, config), analyze_impact(b, config)
        assert ra.flags == rb.flags and ra.impulse_n_s == rb.impulse_n_s
        assert ra.mobility.tobytes() == rb.mobility.tobytes()


def test_records_are_the_stream_samples_aligned_by_index():
    force, velocity = stream()
    for record in capture_impacts(force, velocity, RATE_HZ, SHORT):
        start = record.record_start_sample_index
        assert record.trigger_sample_index - start == round(SHORT.pretrigger_s * RATE_HZ)
        np.testing.assert_array_equal(record.force_n, force[start : start + 3000])
        np.testing.assert_array_equal(record.velocity_m_s, velocity[start : start + 3000])


def test_end_at_rest_shortens_the_record_but_keeps_the_frequency_grid():
    config = CaptureConfig(window_s=3.0, min_spacing_s=0.5, rest_time_s=0.5, end_at_rest=True)
    n = 6000
    force, velocity = hits(n, RATE_HZ, [(1000, 450.0)], zeta=0.5)
    (record,) = capture_impacts(force, velocity, RATE_HZ, config)
    assert record.force_n.size < 3000 and record.window_samples == 3000
    tail = record.velocity_m_s[-500:]
    assert np.all(np.abs(tail) <= config.rest_velocity_m_s)
    assert np.abs(record.velocity_m_s[-501]) > config.rest_velocity_m_s
    (full,) = capture_impacts(force, velocity, RATE_HZ, SHORT)
    short_result, full_result = analyze_impact(record, config), analyze_impact(full, SHORT)
    np.testing.assert_array_equal(short_result.frequency_hz, full_result.frequency_hz)
    np.testing.assert_allclose(
        short_result.peak_receptance_m_per_n, full_result.peak_receptance_m_per_n, rtol=1e-3
    )


def test_missing_batch_is_a_gap_in_that_record_only():
    force, velocity = stream()
    sizes = [500] * (force.size // 500)
    clean = feed_in_pieces(force, velocity, SHORT, sizes)
    # Batch 11 (samples 5500..6000) of velocity never arrives: inside the 5 s hit's record.
    gapped = feed_in_pieces(force, velocity, SHORT, sizes, lag_batches=1, drop={('velocity', 11)})
    assert [r.trigger_sample_index for r in gapped] == [r.trigger_sample_index for r in clean]
    for record, reference in zip(gapped, clean, strict=True):
        start = record.record_start_sample_index
        if start <= 5500 < start + 3000:
            assert record.velocity_gaps == ((5500 - start, 6000 - start),)
            assert np.isnan(record.velocity_m_s[5500 - start : 6000 - start]).all()
            assert 'gap' in quality_flags(record, SHORT)
            assert 'nan' not in quality_flags(record, SHORT)
        else:
            assert record.velocity_gaps == () and record.force_gaps == ()
            assert record.velocity_m_s.tobytes() == reference.velocity_m_s.tobytes()


def test_missing_force_batch_cannot_trigger_and_is_a_gap():
    force, velocity = stream()
    sizes = [500] * (force.size // 500)
    # Force batch 13 (6500..7000) holds the 1450 N hit: that impact is never seen ...
    records = feed_in_pieces(force, velocity, SHORT, sizes, drop={('force', 13)})
    assert [r.trigger_sample_index for r in records] == [1001, 5001, 11001]
    # ... and the 1000 N hit's record (4991..7991) shows the force gap.
    assert records[1].force_gaps == ((6500 - 4991, 7000 - 4991),)
    assert records[1].velocity_gaps == ()


def test_end_of_stream_flushes_open_records_as_gaps():
    force, velocity = stream(n_seconds=6.0)
    capture = ImpactCapture(SHORT)
    done = capture.feed_both(0, force, velocity, RATE_HZ)
    assert capture.open_impacts == 1  # the 5 s hit needs samples up to 7990
    (last,) = capture.flush()
    assert last.force_gaps == ((6000 - 4991, 3000),) == last.velocity_gaps
    assert 'gap' in quality_flags(last, SHORT)
    assert [r.trigger_sample_index for r in done] == [1001]


def test_a_lagging_channel_beyond_max_skew_is_declared_missing():
    force, velocity = stream()
    capture = ImpactCapture(SHORT)
    capture.feed('force', 0, force[:3000], RATE_HZ)  # 3 s ahead, max skew 1 s
    # Velocity up to 1999 is declared missing; a batch of it arriving now is refused and
    # counted (it used to raise, which stopped a node's stream or a bag's replay).
    assert capture.feed('velocity', 0, velocity[:500], RATE_HZ) == []
    ledger = capture.ledger['velocity']
    assert (ledger.missing_samples, ledger.refused_batches, ledger.refused_samples) == (
        2000,
        1,
        500,
    )
    assert ledger.faults == {'skew': 1, 'past': 1}
    records = capture.feed('velocity', 2000, velocity[2000:3000], RATE_HZ)
    records += capture.feed_both(3000, force[3000:], velocity[3000:], RATE_HZ) + capture.flush()
    first = records[0]
    assert first.trigger_sample_index == 1001
    assert first.velocity_gaps == ((0, 2000 - 991),) and first.force_gaps == ()


def test_bad_batches_are_refused_without_losing_state():
    force, velocity = stream()
    reference = capture_impacts(force, velocity, RATE_HZ, SHORT)
    capture = ImpactCapture(SHORT)
    records = capture.feed_both(0, force[:4000], velocity[:4000], RATE_HZ)
    # A batch at another rate may start a new acquisition: held, and refused as a stray
    # when the next batch continues the old sequence. A batch from the past is refused.
    # Neither raises (one such batch used to blind a live analyzer for good).
    assert capture.feed('velocity', 4000, velocity[4000:4500], 2 * RATE_HZ) == []
    assert capture.feed('force', 3500, force[3500:4500], RATE_HZ) == []
    with pytest.raises(ValueError, match="'force' or 'velocity'"):
        capture.feed('displacement', 4000, velocity[4000:4500], RATE_HZ)
    with pytest.raises(ValueError, match='aligned'):
        capture.feed_both(4000, force[4000:4500], velocity[4000:4400], RATE_HZ)
    with pytest.raises(ValueError, match='one-dimensional'):
        capture.feed('force', 4500, np.zeros((2, 2)), RATE_HZ)
    with pytest.raises(ValueError, match='positive'):
        capture.feed('force', 4500, force[4500:5000], 0.0)
    records += capture.feed_both(4000, force[4000:], velocity[4000:], RATE_HZ) + capture.flush()
    assert_same_records(records, reference)
    assert capture.ledger['velocity'].faults == {'stray': 1}
    # 3500..4000 refused, its tail 4000..4500 taken; feed_both's 4000..4500 then repeats it.
    force_ledger = capture.ledger['force']
    assert force_ledger.faults == {'past': 2} and force_ledger.refused_samples == 1000
    assert force_ledger.received_samples == force.size


def test_recycled_buffers_are_reused_and_checked():
    force, velocity = stream()
    capture = ImpactCapture(SHORT)
    first = capture.feed_both(0, force[:4500], velocity[:4500], RATE_HZ)[0]
    base = first.force_n.base
    capture.recycle(first)
    with pytest.raises(ValueError, match='once'):
        capture.recycle(first)
    later = capture.feed_both(4500, force[4500:], velocity[4500:], RATE_HZ)
    assert any(record.force_n.base is base for record in later)
    foreign = capture_impacts(force, velocity, RATE_HZ, SHORT)[0]
    with pytest.raises(ValueError):
        ImpactCapture(SHORT).recycle(foreign)


def test_capture_config_is_validated():
    with pytest.raises(ValueError, match='hysteresis'):
        CaptureConfig(trigger_level_n=10.0, rearm_level_n=10.0)
    with pytest.raises(ValueError, match='pretrigger_s'):
        CaptureConfig(pretrigger_s=40.0)
    with pytest.raises(ValueError, match='min_spacing_s'):
        CaptureConfig(min_spacing_s=0.0)
