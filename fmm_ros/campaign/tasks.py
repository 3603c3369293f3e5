"""A campaign's sessions as independent Dask tasks: on this machine's cores or on a cluster.

Each session is one task (`run_cached_session`): hash its inputs, return the cached result when the
key is known, else run the pipeline and cache what it gives. The graph is a list of
`dask.delayed` calls with no edges between them; `run_sessions` computes it on

- a `LocalCluster` of worker processes on this machine (default: one a core, one thread each,
  so the numerics of two sessions never share an interpreter lock), or
- an existing `dask.distributed` scheduler at an address (`dask scheduler` on one machine,
  `dask worker ADDRESS` on each other; the session files and the cache directory must be
  reachable at the same paths from every worker, e.g. on a shared file system), or
- in this process, one session after the other (`SERIAL`: for debugging and as the
  benchmark's baseline).

A session whose task raises (a bug, a worker that died) becomes a failed result naming what
happened; it is not cached, so a rerun tries again. Nothing stops the other sessions.
"""

from __future__ import annotations

import dataclasses
import logging
import os
from collections.abc import Callable, Sequence

from fmm_ros.campaign.cache import ResultCache, session_key
from fmm_ros.campaign.session import (
    FAILED,
    SessionOutcome,
    SessionSpec,
    compute_session,
)
from fmm_ros.core import memory
from fmm_ros.errors import BadInputError, FmmError
from fmm_ros.workflows.session import SessionOptions

_log = logging.getLogger(__name__)

SERIAL = 'serial'
"""The scheduler name that runs every session in this process, without Dask."""
CONNECT_TIMEOUT_S = 10.0
PRE_SPAWN_ENVIRON = 'distributed.nanny.pre-spawn-environ'
"""Dask's configuration of the environment its worker processes start with."""


def run_cached_session(
    spec: SessionSpec, options: SessionOptions, cache_dir: str | None = None
) -> SessionOutcome:
    """One session: from the cache when its data and options are known, else computed.

    Without a cache directory the session is computed and its inputs are not hashed. A
    result the data decided (fitted or failed) is cached; inputs that cannot be read at all
    have no key and fail uncached.
    """
    if not cache_dir:
        return compute_session(spec, options)
    try:
        key = session_key(spec, options)
    except (FmmError, OSError) as error:
        return SessionOutcome(FAILED, f'cannot read: {error}')
    cache = ResultCache(cache_dir)
    if (stored := cache.get(key)) is not None:
        return stored
    result = dataclasses.replace(compute_session(spec, options), key=key)
    cache.put(key, result)
    return result


def run_sessions(
    specs: Sequence[SessionSpec],
    options: SessionOptions,
    *,
    cache_dir: str | os.PathLike | None = None,
    scheduler: str | None = None,
    workers: int | None = None,
    on_result: Callable[[int, SessionOutcome], None] | None = None,
) -> list[SessionOutcome]:
    """Every session's result, in the order of `specs`.

    scheduler: None for a local cluster of `workers` processes (default: one a core), an
    address ('tcp://host:8786') for an existing cluster, or `SERIAL`. on_result(i, result)
    is called as each session finishes (in the order they finish), e.g. for a progress bar.
    Raises OSError when the scheduler cannot be reached.
    """
    cache = os.fspath(cache_dir) if cache_dir is not None else None
    if scheduler == SERIAL:
        results = []
        for index, spec in enumerate(specs):
            results.append(_guarded(run_cached_session, spec, options, cache))
            if on_result:
                on_result(index, results[-1])
        return results
    n_workers = _worker_count(workers)  # checked for any scheduler, as the CLI passes it
    from distributed import Client

    if scheduler is None:
        with local_cluster(n_workers) as cluster, Client(cluster) as client:
            return _compute(client, specs, options, cache, on_result)
    try:
        client = Client(scheduler, timeout=CONNECT_TIMEOUT_S)
    except (OSError, TimeoutError) as error:
        raise OSError(f'cannot reach the Dask scheduler at {scheduler}: {error}') from error
    with client:
        return _compute(client, specs, options, cache, on_result)


def local_cluster(workers: int | None = None):
    """A `LocalCluster` of `workers` processes (default: one a core), one thread each.

    Use it as a context manager; `run_sessions` starts one per call when given no scheduler,
    and its `scheduler_address` serves as `scheduler=` to reuse one across calls.
    """
    n_workers = _worker_count(workers)
    import dask
    from distributed import LocalCluster

    # Dask starts workers with glibc's trim threshold at 64 KiB, so they hand freed memory
    # back at once; a session allocates and frees many 2.6 MB record arrays, each then
    # faulted in afresh (15x the page faults, 7x the system time measured). The workers
    # keep freed memory as `fmm` itself does (`fmm_ros.core.memory`; glibc's adaptive
    # thresholds still gave a replay ~200,000 faults).
    # Nor do they run Dask's statistical profiler (a stack sample every 10 ms, under the
    # interpreter lock, for a dashboard no one opens here).
    with dask.config.set(
        {
            f'{PRE_SPAWN_ENVIRON}.MALLOC_TRIM_THRESHOLD_': str(memory.TRIM_BYTES),
            f'{PRE_SPAWN_ENVIRON}.MALLOC_MMAP_THRESHOLD_': str(memory.HEAP_BLOCK_BYTES),
            'distributed.worker.profile.enabled': False,
        }
    ):
        return LocalCluster(
            n_workers=n_workers,
            threads_per_worker=1,
            processes=True,
            dashboard_address=None,
            # A task's error comes back with its future; what the workers would log
            # besides is a heartbeat missing a scheduler that is already closing.
            silence_logs=logging.CRITICAL,
        )


def _worker_count(workers: int | None) -> int:
    """Local worker processes: `workers`, or one a core; ValueError below 1."""
    if workers is not None and workers < 1:
        raise BadInputError(f'workers must be at least 1, got {workers}')
    return workers or os.cpu_count() or 1


def _compute(
    client,
    specs: Sequence[SessionSpec],
    options: SessionOptions,
    cache: str | None,
    on_result: Callable[[int, SessionOutcome], None] | None,
) -> list[SessionOutcome]:
    """Send the graph of sessions to the client's scheduler and gather it as it completes."""
    import dask
    from distributed import as_completed

    tasks = [dask.delayed(run_cached_session, pure=False)(spec, options, cache) for spec in specs]
    futures = client.compute(tasks)
    index_of = {future.key: index for index, future in enumerate(futures)}
    results: list[SessionOutcome | None] = [None] * len(specs)
    try:
        for future in as_completed(futures):
            index = index_of[future.key]
            try:
                result = future.result()
            except Exception as error:  # any task error is that session's alone
                result = _task_failure(error)
            results[index] = result
            if on_result:
                on_result(index, result)
    finally:
        client.cancel(futures)
    return [result for result in results if result is not None]


def _guarded(task: Callable[..., SessionOutcome], *args) -> SessionOutcome:
    """task(*args), with an exception turned into that session's failure."""
    try:
        return task(*args)
    except Exception as error:  # as a Dask task's error would be
        return _task_failure(error)


def _task_failure(error: BaseException) -> SessionOutcome:
    """The failed result of a task that raised (not cached: it may not happen again).

    Refused data never gets here (`compute_session` makes it a failed outcome with the
    reason): an exception here is a fault in the code or the cluster. It is reported as an
    internal error, its traceback kept in the log, so a bug is not mistaken for bad data.
    """
    name = type(error).__name__
    if name == 'KilledWorker':
        return SessionOutcome(FAILED, f'its worker died repeatedly (memory? killed?): {error}')
    if isinstance(error, FmmError):
        return SessionOutcome(FAILED, f'the analysis refused the data: {error}')
    _log.error('internal error in a session task', exc_info=error)
    return SessionOutcome(FAILED, f'the analysis raised {name}: {error}', internal_error=True)
