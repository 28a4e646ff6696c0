"""Spread a serial kernel's rows over threads: :func:`split_range` (how the package's
kernels use several cores without being ``parallel=True`` kernels); and threads that run the
kernels on one core each (:func:`serial_kernels`, :func:`serial_thread`)."""
from __future__ import annotations

import contextlib
import threading
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor

import numba

_pool: ThreadPoolExecutor | None = None
_pool_lock = threading.Lock()


def serial_thread() -> None:
    """Make this thread run the kernels on one core (``numba.set_num_threads`` is per
    thread): for a thread that runs beside others which use the cores already (the video's
    band threads and tail thread, a batch task), or as a pool's initializer."""
    numba.set_num_threads(1)


@contextlib.contextmanager
def serial_kernels() -> Iterator[None]:
    """``with serial_kernels():`` -- :func:`serial_thread` for the block, the thread's own
    setting back after it."""
    before = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        yield
    finally:
        numba.set_num_threads(before)


def split_range(fn: Callable[[int, int], None], n: int, parts: int) -> None:
    """``fn(lo, hi)`` over ``0 <= i < n`` cut into ``parts`` contiguous ranges of about equal
    length, run at once: the first on the calling thread, the others on a shared pool of
    ``NUMBA_NUM_THREADS - 1`` threads (``fn`` runs serial Numba kernels, which release the
    GIL). Returns when all are done; re-raises the first exception. ``parts <= 1``: one call
    ``fn(0, n)`` here. How the package's kernels use several cores without being
    ``parallel=True`` kernels."""
    global _pool
    parts = max(1, min(int(parts), n, numba.config.NUMBA_NUM_THREADS))
    if parts == 1:
        if n > 0:
            fn(0, n)
        return
    cuts = [n * i // parts for i in range(parts + 1)]
    with _pool_lock:
        if _pool is None:
            _pool = ThreadPoolExecutor(max_workers=max(1, numba.config.NUMBA_NUM_THREADS - 1),
                                       thread_name_prefix="fastdet-rows")
        pool = _pool
    futures = [pool.submit(fn, cuts[i], cuts[i + 1]) for i in range(1, parts)]
    errors: list[BaseException] = []
    try:
        fn(cuts[0], cuts[1])
    finally:
        for f in futures:
            try:
                f.result()
            except BaseException as exc:  # noqa: BLE001 - re-raised below
                errors.append(exc)
    if errors:
        raise errors[0]


def longest_first(costs: Sequence[float], workers: int, start: float = 0.0) -> list[list[int]]:
    """The indices of ``costs`` shared among ``workers``: the costliest first, each to the least
    loaded worker (every worker but the first starting ``start`` late; ties in cost keep their
    order, ties in load go to the lowest worker). One list per worker, some possibly empty."""
    loads = [0.0] + [float(start)] * (workers - 1)
    plan: list[list[int]] = [[] for _ in range(workers)]
    for i in sorted(range(len(costs)), key=lambda i: -costs[i]):
        w = loads.index(min(loads))
        plan[w].append(i)
        loads[w] += costs[i]
    return plan
