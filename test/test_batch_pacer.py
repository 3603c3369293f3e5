"""A source's wall-clock pace (ros/flow.BatchPacer): short stalls are made up.

Re-anchoring the clock as soon as a source was two batches behind lost every stall longer
than 20 ms for good at x50 (x44.9 of x50 on a graph that sustained x77.5 asked x100). The
pacer now makes up a stall of up to CATCH_UP_S, two batches a step (twice the pace on ticks,
within the flow window), and re-anchors only beyond it, saying it fell behind.
"""

import pytest

from fmm_ros.ros import flow

RATE = 100.0  # batches a second


class Clock:
    """A monotonic clock the test moves by hand."""

    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


@pytest.fixture
def clock(monkeypatch):
    clock = Clock()
    monkeypatch.setattr(flow.time, 'monotonic', clock)
    return clock


def release(pacer: flow.BatchPacer, count: int) -> None:
    for _ in range(count):
        pacer.release()


def test_a_stall_within_the_catch_up_is_made_up_at_twice_the_pace(clock):
    pacer = flow.BatchPacer(RATE, catch_up_s=1.0)
    assert pacer.due() == 0  # the first call anchors the clock
    clock.now += 0.5  # half a second without a tick: 50 batches due
    assert pacer.due() == flow.CATCH_UP_BATCHES == 2  # not all at once: nothing floods
    assert not pacer.fell_behind
    release(pacer, 2)
    for _ in range(60):  # ticks at the batch rate: one batch due, two go, until caught up
        clock.now += 1.0 / RATE
        release(pacer, pacer.due())
    owed = int((clock.now - 1000.0) * RATE + 1e-9) - pacer.released
    assert 0 <= owed <= 1  # the stall cost no pace


def test_a_lag_beyond_the_catch_up_reanchors_and_says_so(clock):
    pacer = flow.BatchPacer(RATE, catch_up_s=1.0)
    pacer.due()
    clock.now += 1.5  # 150 batches behind: the graph is slower than asked
    assert pacer.due() == 1
    assert pacer.fell_behind
    pacer.release()
    clock.now += 0.015
    assert pacer.due() == 1  # paced from the re-anchored clock, the 150 not made up
    assert not pacer.fell_behind


def test_the_pace_over_time_is_the_asked_rate_despite_stalls(clock):
    """Ticks at the batch rate with a 0.3 s stall every second: the released count keeps up."""
    pacer = flow.BatchPacer(RATE, catch_up_s=1.0)
    pacer.due()
    for tick in range(1, 501):
        clock.now += 1.0 / RATE + (0.3 if tick % 100 == 50 else 0.0)
        release(pacer, pacer.due())
    elapsed = clock.now - 1000.0
    assert int(elapsed * RATE) - 1 <= pacer.released <= int(elapsed * RATE)


def test_where_a_flow_window_bounds_it_the_stall_goes_at_once(clock):
    """PacedSource asks for all that is owed when consumers report (their window bounds it)."""
    pacer = flow.BatchPacer(RATE, catch_up_s=1.0)
    pacer.due()
    clock.now += 0.5
    assert pacer.due(most=1_000_000) == 50
