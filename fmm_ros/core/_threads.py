"""Per-impact work shared out between threads.

The model runs of a fit or a diagnosis are one impact each, in numba kernels that release the
GIL (`nogil`), so the impacts of a session run side by side on as many cores; so do the
analyses of a replay's or a session's records (DFTs, numpy reductions and kernels that
release it too), a replay's while its capture goes on (`thread_imap`). Every result is
computed alone and returned in order: the numbers are the same whatever the thread count.
"""

import collections
import os
import threading
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor, wait
from typing import TypeVar

MAX_THREADS = 4
"""Most threads a fit asks for: past four cores a 30-impact Jacobian gains little."""

_PREFIX = 'fmm-impacts'
_T = TypeVar('_T')
_R = TypeVar('_R')


def available_threads() -> int:
    """Cores this process may run on, at most MAX_THREADS."""
    return max(1, min(MAX_THREADS, len(os.sched_getaffinity(0))))


_pools: dict[tuple[int, int], ThreadPoolExecutor] = {}
_pools_lock = threading.Lock()


def pool(threads: int) -> ThreadPoolExecutor:
    """One pool of worker threads a size, kept for the process (fits are many and short).

    Keyed by process id too: a forked child (a campaign's worker process) inherits the pool
    object but not its threads, and work submitted to it would never run.
    """
    key = (os.getpid(), threads)
    with _pools_lock:
        if key not in _pools:
            _pools[key] = ThreadPoolExecutor(max_workers=threads, thread_name_prefix=_PREFIX)
        return _pools[key]


def in_worker() -> bool:
    """Whether this thread is one of the pools' workers (which must not wait on a pool)."""
    return threading.current_thread().name.startswith(_PREFIX)


def _usable(threads: int | None) -> int:
    """The threads a call may share its work between.

    `threads` (default `available_threads()`), or 1 in a pool's worker: a worker waiting on
    its own pool could wait for ever.
    """
    if in_worker():
        return 1
    return available_threads() if threads is None else threads


def thread_map(
    function: Callable[[_T], _R], items: Iterable[_T], threads: int | None = None
) -> list[_R]:
    """[function(item) for item in items], the calls shared out between threads.

    threads: default `available_threads()`. Serial with one thread, one item, or when called
    from a pool's worker (a worker waiting on its own pool could wait for ever). Every call
    has finished before a call's error is raised (the first in order): none still writes into
    what the caller reuses after catching it.
    """
    items = list(items)
    threads = _usable(threads)
    if threads <= 1 or len(items) < 2:
        return [function(item) for item in items]
    futures = [pool(threads).submit(function, item) for item in items]
    wait(futures)
    return [future.result() for future in futures]


def thread_imap(
    function: Callable[[_T], _R], items: Iterable[_T], threads: int | None = None
) -> Iterator[_R]:
    """function(item) for each item, lazily and in order, the calls shared out between threads.

    `thread_map` for items made one by one (records a capture completes as it reads): the
    items are drawn on the caller's thread while earlier calls run, at most 2 * threads
    calls in flight, so making the items and working on them overlap and only the items in
    flight are held. Each result is yielded once its call and all calls before it are done.
    Serial as `thread_map` is (one thread, or called from a pool's worker). On an error (a
    call's, the items', or the caller leaving the loop early), every call in flight has
    finished before it goes on: none still works on an item the caller reuses.
    """
    threads = _usable(threads)
    if threads <= 1:
        yield from map(function, items)
        return
    workers = pool(threads)
    flight: collections.deque[Future] = collections.deque()
    try:
        for item in items:
            flight.append(workers.submit(function, item))
            while len(flight) > 2 * threads or (flight and flight[0].done()):
                yield flight.popleft().result()
        while flight:
            yield flight.popleft().result()
    finally:
        wait(flight)


def in_background(function: Callable[..., _R], *args: object) -> Future:
    """function(*args) on a pool's thread while the caller goes on, as a Future.

    Done here, before it returns, where `thread_map` would run serially (one core, or called
    from a pool's worker).
    """
    threads = _usable(None)
    if threads > 1:
        return pool(threads).submit(function, *args)
    done: Future = Future()
    done.set_result(function(*args))
    return done
