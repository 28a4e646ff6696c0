"""A batch on Dask: which videos to run, the cluster, the tasks, the manifest, the end.

:func:`run_batch` is what ``python -m fastdet batch`` runs:

1. Each video gets its output name (:func:`~fastdet.batch.inputs.output_names`); unless
   ``overwrite``, the videos the manifest shows complete for the same settings are skipped
   (:meth:`~fastdet.batch.manifest.Manifest.is_complete`), and those that failed because
   of the file itself (not a video, ...) and have not changed are reported as failed
   without running them again (:meth:`~fastdet.batch.manifest.Manifest.known_failure`). With nothing left to do no
   cluster is started.
2. The cluster: by default a ``LocalCluster`` of ``workers`` processes (one per core) with
   one thread and one Numba thread each; with ``scheduler`` (``tcp://host:8786``) the
   client connects to a running cluster instead, whose workers must see the same paths
   (a shared file system) and have fastdet installed.
3. One task per video (:func:`~fastdet.batch.task.run_video`), shipping only paths and
   settings; ``retries`` reruns a task whose attempt raised, and the scheduler reruns a
   task whose worker died (up to ``distributed.scheduler.allowed-failures`` times, then
   the video is recorded as failed).
4. As each video ends, one manifest line; at the end the combined ``table`` (if asked) and
   a summary (:func:`~fastdet.batch.summary.format_summary`).

Temporary files: each batch run writes into its own folder ``OUT/.partial/HOST-PID-RANDOM``
(:func:`run_id`) and removes only that folder at its end; at start-up it also removes the
folders of runs on this host whose process is gone (killed outright), never those of a run
still going. The tasks leave their outputs under temporary names; this process renames them
(:func:`~fastdet.batch.task.commit_outputs`) as it records each video, so a video has final
names exactly when it has a manifest line.

Failures: a video that cannot be used is recorded ``permanent`` and not run again while it
is unchanged; a failed write (a full disk, a temporary file that vanished), a lost worker or
a model that did not load are not properties of the video and are tried again by the next
run.

SIGINT, SIGTERM and SIGHUP (:mod:`fastdet.signals`) stop the batch cleanly: the first one
ends the wait for results; results that arrive after it get no final names; the tasks are
cancelled, the client (and the local cluster, whose worker processes end) closed, this run's
temporary folder removed, and :class:`BatchInterrupted` says how many videos were done and
how many stopped; the outputs and manifest lines of the finished videos stay, so a rerun
does the rest. A second signal while that runs is ignored (the clean-up is bounded by
timeouts). Connecting to a scheduler waits at most :data:`CONNECT_TIMEOUT_S` and wakes on a
stop signal.
"""
from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import logging
import os
import re
import shutil
import signal
import socket
import sys
import threading
import time
import uuid
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field, replace
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import cv2
from distributed import Client, LocalCluster, WorkerPlugin, as_completed
from distributed.scheduler import KilledWorker

from .. import signals
from .._numba import WORKERS_ENV, all_kernels, ensure_compiled
from ..config.batch import BatchOptions
from ..errors import DataError, FastdetError, WriteError, one_line
from ..io.atomic import process_token
from .inputs import output_names
from .manifest import Manifest, input_stat
from .progress import BatchProgress
from .settings import MANIFEST_NAME, Settings, output_paths
from .summary import format_summary as _format_summary
from .table import write_table
from .task import PARTIAL_DIR, VideoTask, commit_outputs, discard_outputs, run_video

POLL_S = 0.2  # how often the main thread looks at finished tasks and redraws the bar
CONNECT_TIMEOUT_S = 20
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


@dataclass
class BatchReport:
    """What a batch did: manifest entries of the videos ``done`` in this run, ``skipped``
    (done before) and ``failed``; ``wall`` seconds; ``workers`` (None: not started)."""

    done: list[dict[str, Any]] = field(default_factory=list)
    skipped: list[dict[str, Any]] = field(default_factory=list)
    failed: list[dict[str, Any]] = field(default_factory=list)
    wall: float = 0.0
    workers: int | None = None
    table_rows: int | None = None


def format_summary(report: BatchReport) -> str:
    """The end-of-batch table of ``report`` (:func:`fastdet.batch.summary.format_summary`)."""
    return _format_summary(report.done, report.skipped, report.failed, report.wall, report.workers)


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


@contextlib.contextmanager
def _client(opts: BatchOptions) -> Iterator[tuple[Client, int]]:
    """A client on the local cluster or on ``opts.scheduler``, closed (with the local
    cluster) on exit; yields ``(client, number of workers)``."""
    cluster = None
    try:
        if opts.scheduler:
            client = _connect(opts.scheduler)
        else:
            n = opts.workers or default_workers()
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
        workers = len(client.scheduler_info().get("workers", {}))
        if not workers:
            print(f"fastdet batch: the scheduler at {opts.scheduler} has no workers yet; the videos "
                  f"wait for some to join", file=sys.stderr, flush=True)
        yield client, workers
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
            box["client"] = Client(address, timeout=limit, set_as_default=False)
        except BaseException as exc:  # noqa: BLE001 - reported by the waiting thread
            box["error"] = exc

    t = threading.Thread(target=connect, name="fastdet-connect", daemon=True)
    t.start()
    finished = signals.wait(lambda: not t.is_alive(), limit + 1)
    if not finished:
        if signals.stop_requested():
            raise BatchInterrupted(signals.received() or signal.SIGINT, 0)
        raise FastdetError(f"cannot connect to the Dask scheduler at {address}: no answer in {limit:g} s "
                           f"(is it a Dask scheduler?)")
    if "error" in box:
        exc = box["error"]
        raise FastdetError(f"cannot connect to the Dask scheduler at {address}: "
                           f"{str(exc).splitlines()[0] if str(exc) else type(exc).__name__}") from None
    return box["client"]


def run_id() -> str:
    """``HOST-PID-RANDOM``: this batch run's temporary folder name (unique to the process)."""
    host = re.sub(r"[^A-Za-z0-9.]+", "_", socket.gethostname()) or "host"
    return f"{host}-{process_token()}"


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    return True


def remove_run(out_dir: Path, run: str) -> None:
    """Remove run ``run``'s temporary folder, and ``.partial`` when it is then empty."""
    d = out_dir / PARTIAL_DIR
    shutil.rmtree(d / run, ignore_errors=True)
    with contextlib.suppress(OSError):
        d.rmdir()  # only when empty


def remove_stale_runs(out_dir: Path) -> list[str]:
    """Remove the temporary folders of batch runs on this host whose process is gone (a run
    killed outright); the folders of live runs and of other hosts stay. Returns the names."""
    d = out_dir / PARTIAL_DIR
    host = run_id().rsplit("-", 2)[0]
    gone: list[str] = []
    try:
        entries = list(d.iterdir())
    except OSError:
        return gone
    for p in entries:
        m = re.fullmatch(r"(?P<host>.+)-(?P<pid>\d+)-[0-9a-f]{8}", p.name)
        if p.is_dir() and m and m["host"] == host and not _pid_alive(int(m["pid"])):
            shutil.rmtree(p, ignore_errors=True)
            gone.append(p.name)
    return gone


def _one_line(exc: BaseException) -> str:
    if isinstance(exc, KilledWorker):
        return "its worker died every time it ran it (Dask KilledWorker)"
    return one_line(exc)


def _now() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


def _entry(summary: dict[str, Any], task: VideoTask, stat: dict[str, int], settings: Settings) -> dict[str, Any]:
    """The manifest line of a finished task."""
    e: dict[str, Any] = {"input": task.input, "name": task.name, **summary, **stat}
    e["input"], e["name"] = task.input, task.name
    if e.get("status") == "done":
        secs = float(e.get("seconds") or 0.0)
        e["fps"] = round(e["frames"] / secs, 2) if secs > 0 else None
        e["settings"] = settings.record()
    e["seconds"] = round(float(e.get("seconds") or 0.0), 3)
    e["settings_hash"] = settings.digest()
    e["finished"] = _now()
    return e


def _record(summary: dict[str, Any], task: VideoTask, opts: BatchOptions, stats: dict[str, dict[str, int]],
            manifest: Manifest, report: BatchReport, progress: BatchProgress) -> None:
    """A finished task: its outputs renamed (all or none), then its manifest line."""
    if summary.get("status") == "done":
        try:
            commit_outputs(summary, opts.out_dir)
        except WriteError as exc:
            discard_outputs(summary)
            summary = {**summary, "status": "failed", "error": one_line(exc), "permanent": False}
    summary = {k: v for k, v in summary.items() if k != "partials"}
    entry = _entry(summary, task, stats[task.input], opts.settings)
    manifest.append(entry)
    (report.done if entry["status"] == "done" else report.failed).append(entry)
    progress.finished(entry)


def _run_tasks(client: Client, tasks: list[VideoTask], stats: dict[str, dict[str, int]], opts: BatchOptions,
               manifest: Manifest, report: BatchReport) -> None:
    """Submit the tasks and record each as it ends, until all ended or a stop signal came
    (then the results still to come, and any that arrive, get no final names)."""
    progress = BatchProgress([t.name for t in tasks], opts.progress)
    job = tasks[0].topic or "fastdet-batch"
    futures: dict[Any, VideoTask] = {}
    try:
        client.subscribe_topic(job, progress.on_event)
        for t in tasks:
            futures[client.submit(run_video, t, key=f"{job}-{t.name}", retries=opts.retries, pure=False)] = t
        ac = as_completed(list(futures), loop=client.loop)
        while not ac.is_empty() and not signals.stop_requested():
            for fut in ac.next_batch(block=False):
                task = futures.pop(fut)
                try:
                    summary = fut.result()
                except Exception as exc:  # noqa: BLE001 - the task raised on every attempt, or its workers died
                    summary = {"status": "failed", "error": _one_line(exc), "frames": 0}
                fut.release()
                if signals.stop_requested():  # came while this result arrived: no final names now
                    discard_outputs(summary)
                    continue
                _record(summary, task, opts, stats, manifest, report, progress)
            if not ac.has_ready():
                signals.wait(ac.has_ready, POLL_S)
                progress.refresh()
    finally:
        # clean-up after a stop: the client may already be broken, and its error must not
        # hide the reason we stopped
        if futures:
            with contextlib.suppress(Exception):
                client.cancel(list(futures), force=True)
        with contextlib.suppress(Exception):
            client.unsubscribe_topic(job)
        progress.close()


def prepare_out_dir(out_dir: Path) -> None:
    """Make the output folder if missing; :class:`DataError` when it cannot be used."""
    if out_dir.exists() and not out_dir.is_dir():
        raise DataError(f"{out_dir}: exists and is not a folder")
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise DataError(f"{out_dir}: cannot create the output folder ({exc.strerror or exc})") from None
    if not os.access(out_dir, os.W_OK):
        raise DataError(f"{out_dir}: output folder is not writable")


def run_batch(videos: Sequence[Path], opts: BatchOptions) -> BatchReport:
    """Run the batch of ``videos`` (absolute paths, see :func:`~fastdet.batch.inputs.expand_inputs`)
    and return what happened; raises :class:`BatchInterrupted` after a signal (cleaned up)."""
    with signals.handled():  # a no-op under the CLI's dispatcher, which has them already
        return _run_batch(videos, opts)


def _run_batch(videos: Sequence[Path], opts: BatchOptions) -> BatchReport:
    t0 = time.perf_counter()
    out_dir = Path(os.path.abspath(opts.out_dir))
    prepare_out_dir(out_dir)
    manifest = Manifest(out_dir / MANIFEST_NAME)
    settings = opts.settings
    digest = settings.digest()
    topic = f"fastdet-batch-{uuid.uuid4().hex[:12]}"
    run = run_id()
    report = BatchReport()
    names = output_names(videos)
    tasks: list[VideoTask] = []
    stats: dict[str, dict[str, int]] = {}
    for video, name in zip(videos, names):
        path = str(video)
        if not opts.overwrite:
            if manifest.is_complete(path, name, digest, output_paths(out_dir, name, settings)):
                report.skipped.append(manifest.entries[path])
                continue
            before = manifest.known_failure(path, name, digest)
            if before is not None:  # the same file failed the same way: not run again
                report.failed.append({**before, "earlier": True})
                continue
        try:
            stats[path] = input_stat(path)
        except OSError as exc:
            entry = {"input": path, "name": name, "status": "failed", "frames": 0, "seconds": 0.0,
                     "error": f"{path}: cannot read ({exc.strerror or exc})", "settings_hash": digest,
                     "finished": _now()}
            manifest.append(entry)
            report.failed.append(entry)
            continue
        tasks.append(VideoTask(path, name, str(out_dir), settings, topic, run))

    opts = replace(opts, out_dir=out_dir)
    with signals.deferred(repeats=False, raise_on_exit=False):
        if tasks:
            remove_stale_runs(out_dir)
            try:
                if not signals.stop_requested():
                    with _client(opts) as (client, workers):
                        report.workers = workers
                        if not signals.stop_requested():
                            _run_tasks(client, tasks, stats, opts, manifest, report)
            finally:
                # the client and the local cluster are closed: no attempt of ours still writes
                # (on a remote cluster a running task may: remove_stale_runs of a later run
                # takes what it leaves)
                remove_run(out_dir, run)
        stop = signals.received()
        if stop is not None:
            ran = {t.input for t in tasks}
            recorded = sum(1 for e in report.done + report.failed if e.get("input") in ran and not e.get("earlier"))
            raise BatchInterrupted(stop, len(report.done), len(tasks) - recorded)
        if opts.table is not None:
            order = {str(v): i for i, v in enumerate(videos)}
            ok = sorted(report.done + report.skipped, key=lambda e: order.get(e["input"], 0))
            report.table_rows = write_table(opts.table, [(e["name"], out_dir / e["outputs"]["boxes"]) for e in ok])
    report.wall = time.perf_counter() - t0
    return report
