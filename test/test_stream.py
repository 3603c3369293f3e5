"""The one index-aligned stream: gaps, repeats, strays and new acquisitions.

Every consumer (capture, history, bag aligner) runs these rules, so they are tested once on
the stream with a recording sink, and then through each consumer where they matter to it.
"""

import numpy as np
import pytest
from signal_records import hits

from fmm_ros.core.signal.capture import CaptureConfig, ImpactCapture
from fmm_ros.core.signal.history import SampleHistory
from fmm_ros.core.signal.quality import quality_flags
from fmm_ros.core.signal.stream import AlignedStream, Batch, ChannelLedger, StreamRules

RATE = 1000.0
BATCH = 100
ORIGIN_NS = 1_700_000_000 * 10**9


class RecordingSink:
    """Records what the stream hands over: per channel, the samples taken by index, the gaps."""

    def __init__(self):
        self.begins, self.ends = [], []
        self.taken = {'force': {}, 'velocity': {}}
        self.gaps = {'force': [], 'velocity': []}

    def begin(self, rate, first):
        self.begins.append((rate, first))

    def end(self, reason):
        self.ends.append(reason)

    def take(self, quantity, first, samples, full_scale):
        for k, value in enumerate(samples):
            self.taken[quantity][first + k] = value

    def missing(self, quantity, start, stop):
        self.gaps[quantity].append((start, stop))


def batch(first, n=BATCH, *, origin_ns=ORIGIN_NS, rate=RATE, sender='daq', value=None):
    """A batch whose samples are their own indices (or value), stamped by its acquisition."""
    samples = np.arange(first, first + n, dtype=float) if value is None else np.full(n, value)
    stamp = origin_ns + round(first / rate * 1e9) if origin_ns else 0
    return Batch(first, samples, rate, 0.0, sender, stamp)


def feed(stream, *items):
    for quantity, item in items:
        stream.feed(quantity, item)


def both(stream, first, **kwargs):
    feed(stream, ('force', batch(first, **kwargs)), ('velocity', batch(first, **kwargs)))


def test_in_sequence_batches_are_taken_and_counted():
    sink = RecordingSink()
    stream = AlignedStream(sink)
    for first in range(0, 1000, BATCH):
        both(stream, first)
    assert sink.begins == [(RATE, 0)] and sink.ends == []
    assert sorted(sink.taken['velocity']) == list(range(1000))
    ledger = stream.ledger['force']
    assert (ledger.received_samples, ledger.missing_samples, ledger.refused_batches) == (1000, 0, 0)
    assert ledger.acquisitions == [[0, 1000]] and ledger.faults == {}
    assert ledger.summary().startswith('force 0..1000 (1 acquisition), 1000 samples received')


@pytest.mark.parametrize('clock', [True, False])
def test_a_stray_far_future_batch_is_refused_when_the_sequence_goes_on(clock):
    """One corrupt index (10^15) must neither blind the stream nor restart it."""
    origin = ORIGIN_NS if clock else 0
    sink = RecordingSink()
    stream = AlignedStream(sink)
    for first in range(0, 500, BATCH):
        both(stream, first, origin_ns=origin)
    stray = batch(10**15, origin_ns=0)  # corrupt index, stamp of the batch it replaced
    stray = Batch(10**15, stray.samples, RATE, 0.0, 'daq', batch(500, origin_ns=origin).stamp_ns)
    stream.feed('force', stray)
    stream.feed('velocity', batch(500, origin_ns=origin))
    for first in range(500, 1000, BATCH):
        if first > 500:
            stream.feed('velocity', batch(first, origin_ns=origin))
        stream.feed('force', batch(first, origin_ns=origin))
    assert sink.ends == [] and stream.acquisitions == 1
    assert sorted(sink.taken['force']) == list(range(1000))
    ledger = stream.ledger['force']
    assert ledger.faults == {'stray': 1} and ledger.refused_batches == 1
    assert ledger.missing_samples == 0


@pytest.mark.parametrize('clock', [True, False])
def test_a_restarted_acquisition_is_followed_within_one_batch(clock):
    """A DAQ restarted by its process manager: index back to 0, later clock."""
    sink = RecordingSink()
    stream = AlignedStream(sink)
    old = ORIGIN_NS if clock else 0
    new = ORIGIN_NS + 700 * 10**9 if clock else 0
    for first in range(0, 30_000, BATCH):
        both(stream, first, origin_ns=old, value=1.0)
    # Velocity of the old acquisition is still in flight when force restarts.
    stream.feed('force', batch(0, origin_ns=new, value=2.0))
    stream.feed('velocity', batch(30_000, origin_ns=old, value=1.0))
    stream.feed('force', batch(BATCH, origin_ns=new, value=2.0))  # confirms: one batch late
    assert sink.ends == ['reset'] and sink.begins[-1] == (RATE, 0)
    stream.feed('velocity', batch(30_100, origin_ns=old, value=1.0))  # stale
    for first in range(0, 500, BATCH):
        if first >= 2 * BATCH:
            stream.feed('force', batch(first, origin_ns=new, value=2.0))
        stream.feed('velocity', batch(first, origin_ns=new, value=2.0))
    assert stream.acquisitions == 2
    force, velocity = stream.ledger['force'], stream.ledger['velocity']
    assert force.acquisitions == [[0, 30_000], [0, 500]] and force.resyncs == 1
    assert velocity.acquisitions[-1] == [0, 500] and velocity.resyncs == 1
    assert force.faults == {'reset': 1}
    # 30_000 came before the restart was confirmed (it is the old acquisition's, taken);
    # 30_100 came after: stale.
    assert velocity.faults == {'stale': 1} and velocity.refused_batches == 1


@pytest.mark.parametrize('clock', ['acquisition', 'none', 'wall'])
@pytest.mark.parametrize('jump', [BATCH, 10 * BATCH, int(10 * RATE), int(10 * RATE) + BATCH, 10**6])
def test_an_index_jump_is_missing_samples_of_the_same_acquisition(jump, clock):
    """A jump ahead (1 batch, 10 batches, 10 s, past max_gap_s) is never a new acquisition.

    Only the source declares one (index back, a new sender or rate). 'wall': stamps of the
    wall clock of a source running faster than real time, so its clock cannot vouch for it.
    """
    sink = RecordingSink()
    stream = AlignedStream(sink)
    sent = 0

    def send(first):
        nonlocal sent
        origin = {'acquisition': ORIGIN_NS, 'none': 0, 'wall': ORIGIN_NS - first * 10**6}[clock]
        both(stream, first, origin_ns=origin)
        sent += BATCH

    for first in range(0, 3000, BATCH):
        send(first)
    for first in range(3000 + jump, 6000 + jump, BATCH):
        send(first)
    end = 6000 + jump
    assert sink.ends == [] and stream.acquisitions == 1
    for quantity in ('force', 'velocity'):
        ledger = stream.ledger[quantity]
        assert ledger.acquisitions == [[0, end]], ledger.summary()
        assert ledger.received_samples == sent and ledger.resyncs == 0
        assert ledger.missing_samples == jump == end - sent, ledger.summary()
        gaps = sink.gaps[quantity]  # velocity: part skew while force has jumped first
        assert gaps[0][0] == 3000 and gaps[-1][1] == 3000 + jump
        assert all(a[1] == b[0] for a, b in zip(gaps, gaps[1:], strict=False)), gaps
        assert not set(ledger.faults) & {'reset', 'jump', 'clock', 'stray'} or (
            jump > 10 * RATE and ledger.faults.get('jump') == 1
        ), ledger.faults


@pytest.mark.parametrize('lead', [1, 10, 40])
@pytest.mark.parametrize('jump', [BATCH, 10 * BATCH, int(10 * RATE)])
@pytest.mark.parametrize('first_channel', ['force', 'velocity'])
def test_a_jump_of_the_leading_channel_costs_the_other_none_of_its_batches(
    jump, lead, first_channel
):
    """Channels out of step by `lead` batches (under max_skew_s), the index jumping in both.

    The leader's jump is no signal: the batches the other channel still has in flight from
    before it are taken, not declared missing as lagging (fresh processes at x10 had one
    such batch refused after a 10 s jump). Each channel misses exactly the jump.
    """
    sink = RecordingSink()
    stream = AlignedStream(sink)
    other = 'velocity' if first_channel == 'force' else 'force'
    firsts = list(range(0, 6000, BATCH))

    def index(first):
        return first + (jump if first >= 3000 else 0)

    order = [(first_channel, first) for first in firsts[:lead]]
    for k, first in enumerate(firsts):
        if k + lead < len(firsts):
            order.append((first_channel, firsts[k + lead]))
        order.append((other, first))
    for quantity, first in order:
        stream.feed(quantity, batch(index(first), origin_ns=0))
    for quantity in ('force', 'velocity'):
        ledger = stream.ledger[quantity]
        assert ledger.missing_samples == jump, ledger.summary()
        assert ledger.refused_batches == 0 and ledger.resyncs == 0, ledger.summary()
        assert ledger.received_samples == 6000


def test_index_back_to_zero_is_a_new_acquisition_whatever_the_clock():
    """The source declares a new acquisition by starting its index again."""
    sink = RecordingSink()
    stream = AlignedStream(sink)
    for first in range(0, 30_000, BATCH):
        both(stream, first, origin_ns=0)
    for first in range(0, 500, BATCH):
        both(stream, first, origin_ns=0)
    assert sink.ends == ['reset'] and stream.acquisitions == 2
    assert stream.ledger['force'].missing_samples == 0


def test_a_new_sender_or_rate_starts_a_new_acquisition():
    sink = RecordingSink()
    stream = AlignedStream(sink)
    for first in range(0, 500, BATCH):
        both(stream, first)
    for first in (500, 600):
        both(stream, first, sender='player')
    assert sink.ends == ['sender'] and stream.acquisitions == 2
    for first in (0, 50):  # a new acquisition at another rate, clockless
        both(stream, first, n=50, rate=500.0, origin_ns=0, sender='player')
    assert sink.ends == ['sender', 'rate'] and sink.begins[-1] == (500.0, 0)
    assert stream.sample_rate_hz == 500.0


def test_repeats_and_late_batches_are_refused_and_a_new_tail_taken():
    sink = RecordingSink()
    stream = AlignedStream(sink)
    for first in range(0, 500, BATCH):
        both(stream, first)
    stream.feed('force', batch(300))  # a duplicate
    stream.feed('force', batch(450))  # half old, half new
    stream.feed('force', batch(550))
    ledger = stream.ledger['force']
    assert ledger.faults == {'past': 2} and ledger.refused_batches == 1
    assert ledger.refused_samples == BATCH + 50
    assert sorted(sink.taken['force']) == list(range(650))
    assert all(sink.taken['force'][k] == k for k in range(650))


def test_gaps_are_declared_once_and_a_huge_one_costs_nothing():
    sink = RecordingSink()
    stream = AlignedStream(sink, StreamRules(max_skew_s=10**9))
    both(stream, 0)
    both(stream, 300)  # batches 100..300 lost
    assert sink.gaps['force'] == [(100, 300)]
    assert stream.ledger['force'].faults == {'gap': 1}
    # A clock that vouches for a long gap (the stream was cut for a year) keeps it one
    # acquisition: held one batch, then declared missing, not allocated.
    year = int(3e7 * RATE)
    for first in (year, year + BATCH):
        both(stream, first)
    assert stream.acquisitions == 1 and sink.ends == []
    assert sink.gaps['force'][-1] == (400, year)
    assert stream.ledger['force'].missing_samples == 200 + year - 400


def test_a_lagging_channel_is_declared_missing_beyond_the_skew():
    sink = RecordingSink()
    stream = AlignedStream(sink, StreamRules(max_skew_s=0.5))
    for first in range(0, 1000, BATCH):
        stream.feed('force', batch(first))
    assert sink.gaps['velocity'] == [(0, 100), (100, 200), (200, 300), (300, 400), (400, 500)]
    assert stream.ledger['velocity'].faults == {'skew': 5}


def test_malformed_input_raises_and_changes_nothing():
    stream = AlignedStream(RecordingSink())
    with pytest.raises(ValueError, match="'force' or 'velocity'"):
        stream.feed('torque', batch(0))
    with pytest.raises(ValueError, match='positive'):
        stream.feed('force', Batch(0, np.zeros(3), float('nan')))
    with pytest.raises(ValueError, match='one-dimensional'):
        stream.feed('force', Batch(0, np.zeros((2, 2)), RATE))
    assert not stream.started


def test_the_ledger_round_trips_through_plain_data():
    stream = AlignedStream(RecordingSink())
    both(stream, 0)
    both(stream, 500)
    stream.feed('force', batch(10**12))
    stream.finish()
    ledger = stream.ledger['force']
    assert ChannelLedger.from_dict(ledger.to_dict()) == ledger
    assert ledger.faults == {'gap': 1, 'unconfirmed': 1}


def test_a_restart_mid_recording_gives_the_records_of_both_acquisitions():
    """The capture ends the open record flagged, starts again at once, reports later hits."""
    config = CaptureConfig(window_s=3.0, min_spacing_s=0.5, max_skew_s=1.0)
    n = 10_000
    # 8 ms pulses: 8 samples at 1 kHz, not the coarse ones the flag is for.
    force, velocity = hits(n, RATE, [(1000, 450.0), (6000, 1000.0)], zeta=0.05, duration_s=0.008)
    capture = ImpactCapture(config)
    records = []
    first_origin, second_origin = ORIGIN_NS, ORIGIN_NS + 60 * 10**9
    for first in range(0, 2500, 500):  # the first acquisition stops 1.5 s after its hit
        stamp = first_origin + first * 10**6
        records += capture.feed('force', first, force[first : first + 500], RATE, stamp_ns=stamp)
        records += capture.feed(
            'velocity', first, velocity[first : first + 500], RATE, stamp_ns=stamp
        )
    for first in range(0, n, 500):  # the DAQ restarted: index 0 again, its clock later
        stamp = second_origin + first * 10**6
        records += capture.feed('force', first, force[first : first + 500], RATE, stamp_ns=stamp)
        records += capture.feed(
            'velocity', first, velocity[first : first + 500], RATE, stamp_ns=stamp
        )
    records += capture.flush()
    assert [r.trigger_sample_index for r in records] == [1001, 1001, 6001]
    cut = records[0]
    assert cut.interrupted and quality_flags(cut, config) == ('gap', 'interrupted')
    assert cut.force_gaps == ((2500 - 991, 3000),)
    for record in records[1:]:
        assert not {'gap', 'interrupted'} & set(quality_flags(record, config))
    assert capture.ledger['force'].acquisitions == [[0, 2500], [0, n]]


def test_the_history_holds_only_the_acquisition_it_follows():
    history = SampleHistory(2.0)
    for first in range(0, 3000, 500):
        for quantity in ('force', 'velocity'):
            history.feed(quantity, first, np.ones(500), RATE, stamp_ns=ORIGIN_NS + first * 10**6)
    later = ORIGIN_NS + 100 * 10**9
    for first in range(0, 1000, 500):
        for quantity in ('force', 'velocity'):
            history.feed(quantity, first, np.full(500, 2.0), RATE, stamp_ns=later + first * 10**6)
    assert history.acquisitions == 2 and history.origin_s == pytest.approx(later / 1e9)
    assert history.record(0, 1000).force_n.tolist() == [2.0] * 1000
    with pytest.raises(ValueError, match='not all arrived'):
        history.record(1000, 1000)


def test_every_quality_flag_has_its_meaning_on_the_report_page():
    """A record flagged `interrupted` (or any flag) must not break the report's legend."""
    from fmm_ros.core.signal.capture import FLAGS
    from fmm_ros.report import FLAG_MEANINGS

    assert list(FLAG_MEANINGS) == list(FLAGS)
