"""Impacts cut from a node's own history (ros/cutting.py), in whatever order they come."""

import numpy as np

from fmm_interfaces.msg import ImpactResult
from fmm_ros.constants import FORCE, VELOCITY
from fmm_ros.core.signal.history import SampleHistory
from fmm_ros.ros import msgs
from fmm_ros.ros.cutting import ImpactCutter

RATE_HZ = 1000.0
T0_NS = 1_700_000_000 * 10**9  # sample 0 of the first acquisition


class Log:
    """Collects the warnings a node's logger would print."""

    def __init__(self) -> None:
        self.lines: list[str] = []

    def warning(self, line: str) -> None:
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
