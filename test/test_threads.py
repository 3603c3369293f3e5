"""Per-impact work in threads: order kept, serial in a worker, the GIL released by the model."""

import os
import signal
import threading
import time

import numpy as np
import pytest

from fmm_ros.core import _threads
from fmm_ros.core.physics.model import simulate


def test_results_come_back_in_order_whatever_finishes_first():
    def late_for_small(k: int) -> int:
        time.sleep(0.002 * (5 - k))
        return k * k

    assert _threads.thread_map(late_for_small, range(6), threads=3) == [0, 1, 4, 9, 16, 25]


def test_a_worker_maps_serially_instead_of_waiting_on_its_own_pool():
    def inner(k: int) -> str:
        return threading.current_thread().name

    def outer(k: int) -> list[str]:
        return _threads.thread_map(inner, range(3), threads=2)

    names = _threads.thread_map(outer, range(2), threads=2)
    assert all(len(set(row)) == 1 and row[0].startswith('fmm-impacts') for row in names)


def test_model_runs_in_threads_give_the_serial_numbers():
    force = np.zeros(20_000)
    force[100:130] = np.hanning(30) * 900.0

    def run(x0_m: float) -> np.ndarray:
        return simulate(force, 10_000.0, x0_m=x0_m).velocity_m_s

    starts = [0.0, 1e-4, -2e-4, 3e-4]
    for shared, serial in zip(
        _threads.thread_map(run, starts, threads=2), [run(x) for x in starts], strict=True
    ):
        np.testing.assert_array_equal(shared, serial)


def test_available_threads_is_within_the_cores_and_the_cap():
    assert 1 <= _threads.available_threads() <= _threads.MAX_THREADS


def test_a_forked_child_gets_pools_of_its_own():
    # The parent's pool has both its threads, idle: a child handed that pool would take
    # them for ready and start none.
    _threads.thread_map(time.sleep, [0.05, 0.05], threads=2)
    time.sleep(0.1)
    read, write = os.pipe()
    child = os.fork()
    if child == 0:  # pragma: no cover (the child reports through the pipe)
        signal.alarm(20)  # a child waiting on threads it does not have is killed: '' below
        try:
            os.write(write, repr(_threads.thread_map(abs, [-1, -2], threads=2)).encode())
        finally:
            os._exit(0)
    os.close(write)
    with os.fdopen(read) as pipe:
        assert pipe.read() == '[1, 2]'
    os.waitpid(child, 0)


def test_an_error_is_raised_once_every_call_has_finished():
    finished = []

    def call(k: int) -> None:
        if k == 0:
            raise ValueError('the first call fails at once')
        time.sleep(0.1)
        finished.append(k)

    with pytest.raises(ValueError, match='fails at once'):
        _threads.thread_map(call, range(3), threads=2)
    assert sorted(finished) == [1, 2]


def test_imap_overlaps_making_the_items_with_the_calls_and_keeps_their_order():
    made = []
    fifth_made = threading.Event()

    def items():
        for k in range(12):
            made.append(k)
            if k == 4:
                fifth_made.set()
            yield k

    def call(k: int) -> int:
        if k == 0:  # the first call lasts until the items run 2 x 2 ahead of it
            fifth_made.wait(timeout=10)
        time.sleep(0.002 * (k % 3))
        return k * k

    results = _threads.thread_imap(call, items(), threads=2)
    assert next(results) == 0
    assert len(made) == 5  # four calls in flight and one more drawn, no further
    assert [0, *results] == [k * k for k in range(12)]


def test_imap_is_serial_with_one_thread_and_in_a_worker():
    def name(_: int) -> str:
        return threading.current_thread().name

    assert set(_threads.thread_imap(name, range(3), threads=1)) == {threading.main_thread().name}
    nested = _threads.thread_map(
        lambda _: list(_threads.thread_imap(name, range(3), threads=2)), range(2), threads=2
    )
    assert all(len(set(row)) == 1 for row in nested)


@pytest.mark.parametrize('failing', ['a call', 'the items', 'the caller leaving'])
def test_imap_raises_or_stops_only_once_every_call_in_flight_has_finished(failing):
    started, finished = [], []
    second_started = threading.Event()

    def items():
        yield from range(3)
        if failing == 'the items':
            raise ValueError('the items fail')

    def call(k: int) -> int:
        started.append(k)
        if k == 1:
            second_started.set()
        if k == 0 and failing == 'a call':
            # Fails as soon as a second call is in flight: on a loaded machine the first call
            # could otherwise fail before the second was even submitted.
            second_started.wait(timeout=10.0)
            raise ValueError('the first call fails')
        time.sleep(0.1)
        finished.append(k)
        return k

    results = _threads.thread_imap(call, items(), threads=2)
    if failing == 'the caller leaving':
        assert next(results) == 0
        results.close()  # a loop left early: the generator is closed
        assert sorted(finished) == [0, 1, 2]
        return
    with pytest.raises(ValueError, match='fail'):
        list(results)
    if failing == 'a call':
        # Call 2 is submitted only if the loop saw call 0 still running after call 1 began.
        assert 1 in finished and sorted(finished) == sorted(k for k in started if k != 0)
    else:
        assert sorted(finished) == [0, 1, 2]
