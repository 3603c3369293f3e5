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
