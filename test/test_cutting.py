"""Impacts cut from a node's own history (ros/cutting.py), in whatever order they come.

And from the recorder's bags when the history never held them (a fitter respawned: its
stream begins after the hit, and the bag is still being written).
"""

import numpy as np

from fmm_interfaces.msg import ImpactResult
from fmm_ros.constants import FORCE, VELOCITY
from fmm_ros.core.signal.history import SampleHistory
from fmm_ros.io.bags import BagWriter, backfill
from fmm_ros.io.bags.backfill import bag_family
from fmm_ros.ros import cutting, msgs
from fmm_ros.ros.cutting import ImpactCutter

RATE_HZ = 1000.0
T0_NS = 1_700_000_000 * 10**9  # sample 0 of the first acquisition


class Log:
    """Collects the warnings a node's logger would print."""

    def __init__(self) -> None:
        self.lines: list[str] = []

    def warning(self, line: str) -> None:
        self.lines.append(line)

    def info(self, line: str) -> None:
        self.lines.append(line)


def impact(impact_id: int, origin_ns: int) -> ImpactResult:
    msg = ImpactResult()
    msg.impact_id = impact_id
    msg.header.stamp = msgs.time_msg(origin_ns + round(100 / RATE_HZ * 1e9))
    msg.trigger_sample_index = 100
    msg.record_start_sample_index = 0
    msg.record_duration_s = 1.0
    msg.sample_rate_hz = RATE_HZ
    return msg


def one_second(history: SampleHistory, cutter: ImpactCutter, origin_ns: int) -> list:
    """Both channels, samples 0..999 stamped from origin_ns; the cuts they complete."""
    cuts = []
    for channel in (FORCE, VELOCITY):
        history.feed(channel.quantity, 0, np.ones(1000), RATE_HZ, stamp_ns=origin_ns)
        cuts += cutter.batch_fed()
    return cuts


def test_an_impact_heard_before_any_sample_is_cut_when_its_samples_come():
    """A station started late hears held results first: the first acquisition keeps them."""
    history, log = SampleHistory(10.0), Log()
    cutter = ImpactCutter(history, log)
    assert cutter.impact(impact(8, T0_NS)) == []
    cuts = one_second(history, cutter, T0_NS)
    assert [msg.impact_id for msg, _ in cuts] == [8] and log.lines == []
    assert cuts[0][1].force_n.size == 1000


def test_an_impact_of_another_clock_is_dropped_and_said_when_the_acquisition_begins():
    history, log = SampleHistory(10.0), Log()
    cutter = ImpactCutter(history, log)
    cutter.impact(impact(3, T0_NS - 60 * 10**9))  # a minute older: another acquisition
    cutter.impact(impact(4, T0_NS))
    cuts = one_second(history, cutter, T0_NS)
    assert [msg.impact_id for msg, _ in cuts] == [4]
    assert log.lines == [
        'a new acquisition began: impacts [3] of the previous one cannot be cut any more'
    ]


def test_an_impact_of_another_clock_is_not_held_once_samples_are():
    history, log = SampleHistory(10.0), Log()
    cutter = ImpactCutter(history, log)
    one_second(history, cutter, T0_NS)
    assert cutter.impact(impact(5, T0_NS + 3600 * 10**9)) == []
    assert log.lines == [
        'impact 5 belongs to another acquisition than the samples held (its clock differs): '
        'not held'
    ]
    assert [m.impact_id for m, _ in cutter.impact(impact(6, T0_NS))] == [6]


def recording(bag, force, velocity, origin_ns):
    """A bag being written, as a live recorder leaves it: flushed, not closed."""
    writer = BagWriter(bag, time_origin_ns=origin_ns, flush_interval_s=None)
    writer.__enter__()
    writer.write_signals(force, velocity, RATE_HZ, batch_size=100)
    writer.flush()
    return writer


def respawned(history: SampleHistory, cutter: ImpactCutter, origin_ns: int) -> list:
    """Samples 1500..2499 of both channels only: a node started after the hit's record."""
    cuts = []
    for channel in (FORCE, VELOCITY):
        stamp = origin_ns + round(1500 / RATE_HZ * 1e9)
        history.feed(channel.quantity, 1500, np.zeros(1000), RATE_HZ, stamp_ns=stamp)
        cuts += cutter.batch_fed()
    return cuts


def test_an_impact_the_stream_missed_is_cut_from_the_recorders_open_bag(tmp_path):
    force, velocity = np.arange(3000.0), -np.arange(3000.0) / 1e3
    writer = recording(tmp_path / 'bag', force, velocity, T0_NS)
    try:
        missed = impact(9, T0_NS)  # record [0, 1000): before this node's first sample
        without, log = ImpactCutter(history := SampleHistory(10.0), Log()), Log()
        respawned(history, without, T0_NS)
        assert without.impact(missed) == [] and without.not_held == [9]

        history, log = SampleHistory(10.0), Log()
        cutter = ImpactCutter(history, log, from_bags=tmp_path / 'bag')
        respawned(history, cutter, T0_NS)
        ((msg, record),) = cutter.impact(missed)
    finally:
        writer.__exit__(None, None, None)
    assert msg.impact_id == 9 and cutter.not_held == [] and cutter.for_bags == []
    np.testing.assert_array_equal(record.force_n, force[:1000])
    np.testing.assert_array_equal(record.velocity_m_s, velocity[:1000])
    assert record.trigger_sample_index == 100 and record.source == 'impact 9'
    assert log.lines == [
        "impact 9 cut from the recorder's bag (samples from 0 never reached this history: "
        'it begins at sample 1500 (the node started or restarted after them))'
    ]


def test_impacts_missed_together_are_cut_in_one_read_of_the_bag(tmp_path, monkeypatch):
    force = np.arange(3000.0)
    recording(tmp_path / 'bag', force, -force, T0_NS).__exit__(None, None, None)
    history, log = SampleHistory(10.0), Log()
    cutter = ImpactCutter(history, log, from_bags=tmp_path / 'bag')
    reads = []
    real = backfill.BagReader
    monkeypatch.setattr(backfill, 'BagReader', lambda *a, **k: reads.append(a) or real(*a, **k))
    later = impact(11, T0_NS)
    later.record_start_sample_index, later.trigger_sample_index = 500, 600
    later.header.stamp = msgs.time_msg(T0_NS + round(600 / RATE_HZ * 1e9))
    cutter.impact(impact(10, T0_NS)), cutter.impact(later)
    cuts = respawned(history, cutter, T0_NS)
    assert sorted(msg.impact_id for msg, _ in cuts) == [10, 11] and len(reads) == 1
    np.testing.assert_array_equal(
        dict((m.impact_id, r) for m, r in cuts)[11].force_n, force[500:1500]
    )


def test_an_impact_the_bags_do_not_hold_waits_for_them_then_is_named(tmp_path, monkeypatch):
    """Another acquisition's clock in the bag, or the bag not flushed yet: waited for."""
    force = np.ones(3000)
    recording(tmp_path / 'bag', force, force, T0_NS - 3600 * 10**9).__exit__(None, None, None)
    history, log = SampleHistory(10.0), Log()
    cutter = ImpactCutter(history, log, from_bags=tmp_path / 'bag')
    respawned(history, cutter, T0_NS)
    assert cutter.impact(impact(9, T0_NS)) == [] and len(cutter.for_bags) == 1
    # A respawned recorder's bag beside it holds the hit: found on the next try.
    recording(tmp_path / 'bag_1', 2 * force, force, T0_NS).__exit__(None, None, None)
    assert bag_family(tmp_path / 'bag') == [tmp_path / 'bag', tmp_path / 'bag_1']
    ((_, record),) = cutter.cut_from_bags()
    np.testing.assert_array_equal(record.force_n, 2 * force[:1000])
    # Past the wait, an impact no bag holds is named as not held.
    monkeypatch.setattr(cutting, 'BAG_WAIT_S', 0.0)
    cutter = ImpactCutter(history, log, from_bags=tmp_path / 'elsewhere')
    assert cutter.impact(impact(10, T0_NS)) == [] and cutter.not_held == [10]
    assert cutter.for_bags == []
    assert log.lines[-1].startswith('impact 10 cannot be held: samples from 0 never reached')
    assert log.lines[-1].endswith(f'nor is it in {tmp_path / "elsewhere"}')
