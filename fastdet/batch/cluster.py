"""The Dask client of a batch: a ``LocalCluster`` of worker processes (one per core, one
thread and one Numba thread each, set up by a worker plugin) or a connection to a running
scheduler, bounded in time and woken by a stop signal; and :class:`BatchInterrupted`, how a
stopped batch ends."""
from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import logging
import os
import signal
import sys
import threading
from collections.abc import Callable, Iterator, Sequence
from typing import Any, TypeVar

import cv2
from distributed import Client, Future, LocalCluster, WorkerPlugin, as_completed

from .. import signals
from .._numba import WORKERS_ENV, all_kernels, ensure_compiled
from ..errors import FastdetError

CONNECT_TIMEOUT_S = 20
#: how often the waiting thread looks at finished tasks and at stop signals (s)
POLL_S = 0.2
CLOSE_TIMEOUT_S = 20
#: environment of the local cluster's worker processes (a user's own NUMBA_NUM_THREADS wins)
WORKER_ENV = {"NUMBA_NUM_THREADS": "1", "OMP_WAIT_POLICY": "PASSIVE", WORKERS_ENV: "1"}


class BatchInterrupted(Exception):
    """The batch was stopped by signal ``signum`` (after cleaning up): ``done`` videos were
    finished in this run, ``stopped`` were left for the next run."""

    def __init__(self, signum: int, done: int, stopped: int = 0) -> None:
        super().__init__(f"stopped by {signal.Signals(signum).name}")
        self.signum = signum
        self.done = done
        self.stopped = stopped


def default_workers() -> int:
    """One worker per usable core."""
    try:
        return max(len(os.sched_getaffinity(0)), 1)
    except AttributeError:  # pragma: no cover - not Linux
        return max(os.cpu_count() or 1, 1)


def _glibc_malloc_defaults() -> None:
    """Undo the ``MALLOC_TRIM_THRESHOLD_=65536`` that Dask's nanny puts in its workers'
    environment (``distributed.nanny.pre-spawn-environ``): setting it turns off glibc's
    adaptive mmap threshold, so every array of a frame's size is a fresh ``mmap`` whose pages
    fault in again (what that cost: docs/batch.md). These are the values glibc's adaptive
    threshold reaches by itself (the maximum mmap threshold on 64 bits, twice that for
    trimming). No-op without glibc."""
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return
    m_trim_threshold, m_mmap_threshold = -1, -3  # malloc.h
    mallopt(m_mmap_threshold, 32 << 20)
    mallopt(m_trim_threshold, 64 << 20)


class _WorkerSetup(WorkerPlugin):
    """Runs on every worker (also ones that join or restart later): OpenCV on one thread,
    like Numba, since the batch's parallelism is one video per worker thread; glibc's
    malloc as outside Dask (:func:`_glibc_malloc_defaults`)."""

    name = "fastdet-batch-setup"

    def setup(self, worker: Any) -> None:
        cv2.setNumThreads(1)
        _glibc_malloc_defaults()


#: the loggers of Dask's client side in this process, quiet while a batch runs
DASK_LOGGERS = ("distributed", "tornado")


@contextlib.contextmanager
def _quiet_dask() -> Iterator[None]:
    """Dask's own log records of this process (the client's) at ``CRITICAL`` only: a remote
    scheduler killed mid-run printed "distributed.client - ERROR -" with two tracebacks of its
    reconnect attempts (issue 34, item 19). What it means is said by the batch itself: each
    video it cancelled is "failed: the connection to the Dask scheduler was lost", in the
    progress lines, the summary and the manifest."""
    names = {n for n in logging.root.manager.loggerDict if n.split(".")[0] in DASK_LOGGERS} | set(DASK_LOGGERS)
    loggers = [logging.getLogger(name) for name in sorted(names)]  # Dask's config sets levels on the children too
    levels = [lg.level for lg in loggers]
    for lg in loggers:
        lg.setLevel(logging.CRITICAL)
    try:
        yield
    finally:
        for lg, level in zip(loggers, levels):
            lg.setLevel(level)


T = TypeVar("T")


def as_they_end(client: Client, tasks: Sequence[T], submit: Callable[[T], Future],
                idle: Callable[[], None] | None = None) -> Iterator[tuple[T, Future]]:
    """Submit each task (``submit(task)`` returns its future) and yield ``(task, future)`` as
    each ends, in any order, until all have ended or a stop signal came
    (:func:`fastdet.signals.stop_requested`); the caller reads ``future.result()`` and
    releases it. The wait wakes every :data:`POLL_S` seconds and on a signal, calling ``idle``
    (say, to redraw a progress bar). Tasks not yet ended when the generator ends (a stop, an
    error in the caller, closed early) are cancelled: use it as ``with
    contextlib.closing(as_they_end(...)) as ended:`` so that happens at once."""
    futures: dict[Future, T] = {}
    try:
        for t in tasks:
            futures[submit(t)] = t
        ac = as_completed(list(futures), loop=client.loop)
        while not ac.is_empty() and not signals.stop_requested():
            for fut in ac.next_batch(block=False):
                yield futures.pop(fut), fut
            if not ac.has_ready():
                signals.wait(ac.has_ready, POLL_S)
                if idle is not None:
                    idle()
    finally:
        if futures:  # stopped, failed or closed early: the rest is not wanted (the client may
            # already be broken, and its error must not hide why we stopped)
            with contextlib.suppress(Exception):
                client.cancel(list(futures), force=True)


@contextlib.contextmanager
def client_for(workers: int | None = None, scheduler: str | None = None) -> Iterator[tuple[Client, int]]:
    """A client on a local cluster of ``workers`` processes (default: one per core) or on the
    scheduler at ``scheduler``, closed (with the local cluster) on exit; yields ``(client,
    number of workers)``. Dask's log records are quiet meanwhile (:func:`_quiet_dask`)."""
    with _quiet_dask():
        with _client_of(workers, scheduler) as made:
            yield made


@contextlib.contextmanager
def _client_of(workers: int | None, scheduler: str | None) -> Iterator[tuple[Client, int]]:
    cluster = None
    try:
        if scheduler:
            client = _connect(scheduler)
        else:
            n = workers or default_workers()
            # the kernels compiled once here on every core (if the cache lacks them), not once
            # per worker process; the workers load them
            ensure_compiled(all_kernels(), what="the kernels")
            env = {k: os.environ.get(k, v) for k, v in WORKER_ENV.items()}
            # workers' own log lines (a heartbeat that fails while the cluster closes, a task's
            # traceback) are not for the user: every outcome is in the summary and the manifest
            cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None,
                                   silence_logs=logging.CRITICAL, env=env)
            client = Client(cluster, set_as_default=False)
    except BaseException:
        if cluster is not None:
            cluster.close(timeout=CLOSE_TIMEOUT_S)
        raise
    try:
        try:
            client.register_plugin(_WorkerSetup())
        except ImportError as exc:  # raised on a worker, which cannot unpickle fastdet's plugin
            raise FastdetError(f"the Dask workers cannot import {exc.name or 'fastdet'}: install "
                               f"fastdet[cluster] on every worker machine") from None
        n_workers = len(client.scheduler_info().get("workers", {}))
        if not n_workers:
            print(f"fastdet: the scheduler at {scheduler} has no workers yet; the videos "
                  f"wait for some to join", file=sys.stderr, flush=True)
        yield client, n_workers
    finally:
        try:
            client.close(timeout=CLOSE_TIMEOUT_S)
        finally:
            if cluster is not None:
                cluster.close(timeout=CLOSE_TIMEOUT_S)


def check_address(address: str) -> None:
    """``FastdetError`` for a scheduler address that is not ``scheme://host:port`` (checked
    before a client exists: a client half made from a bad address hangs when collected)."""
    from distributed.comm.addressing import parse_address, parse_host_port

    try:
        scheme, loc = parse_address(address, strict=True)
        if scheme in ("tcp", "tls", "ws", "wss", "ucx"):
            parse_host_port(loc)
    except (ValueError, TypeError) as exc:
        raise FastdetError(f"--scheduler {address!r} is not a scheduler address such as tcp://host:8786 "
                           f"({str(exc).splitlines()[0] if str(exc) else type(exc).__name__})") from None


def _connect(address: str, timeout: float | None = None) -> Client:
    """A client of the scheduler at ``address``, made in a helper thread: the wait is
    bounded by ``timeout`` (default :data:`CONNECT_TIMEOUT_S`) and ends at a stop signal.
    Something at that address that is not a Dask scheduler (an HTTP server) keeps a
    client's handshake waiting for ever: the helper thread is then left behind (a daemon)."""
    check_address(address)
    limit = CONNECT_TIMEOUT_S if timeout is None else timeout
    box: dict[str, Any] = {}

    def connect() -> None:
        try:
            box["client"] = _BoundedClient(address, timeout=limit, set_as_default=False)
        except BaseException as exc:  # noqa: BLE001 - reported by the waiting thread
            # only the message: the traceback holds the half-made client, collected here (in
            # this thread, within _BoundedClient's bound), not in the main thread at exit
            box["error"] = (type(exc), str(exc))
            del exc

    t = threading.Thread(target=connect, name="fastdet-connect", daemon=True)
    t.start()
    finished = signals.wait(lambda: bool(box) or not t.is_alive(), limit + 1)
    if not finished:
        if signals.stop_requested():
            raise BatchInterrupted(signals.received() or signal.SIGINT, 0)
        raise FastdetError(f"cannot connect to the Dask scheduler at {address}: no answer in {limit:g} s "
                           f"(is it a Dask scheduler?)")
    if "error" in box:
        kind, text = box["error"]
        if not issubclass(kind, (OSError, TimeoutError)):
            # Dask read what answered as its own framing: "Unable to allocate 2.82 EiB" for
            # a banner, "Maximum allowed dimension exceeded" for a bogus frame length
            raise FastdetError(f"cannot connect to the Dask scheduler at {address}: what answered there does not "
                               f"speak Dask's protocol (is it a Dask scheduler?)")
        raise FastdetError(f"cannot connect to the Dask scheduler at {address}: "
                           f"{text.splitlines()[0] if text else kind.__name__}") from None
    return box["client"]


#: seconds a client that is collected (never closed: one whose handshake failed) may take to close
DEL_CLOSE_TIMEOUT_S = 2.0


class _BoundedClient(Client):
    """A Dask client whose collection is bounded: ``Client.__del__`` closes with twice the
    connect timeout (40 s) and, for a client whose handshake failed (a server that is not Dask),
    waited all of it and then printed a ``TimeoutError`` traceback (issue 34, item 9). Closed
    clients are not affected (the batch closes its client itself)."""

    def __del__(self) -> None:
        with contextlib.suppress(Exception):
            if getattr(self, "status", "closed") not in ("closed", "newly-created"):
                self.close(timeout=DEL_CLOSE_TIMEOUT_S)
