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

SIGINT, SIGTERM and SIGHUP stop the batch cleanly: the first one cancels the tasks, closes
the client (and the local cluster, whose worker processes end), removes the temporary files
of the unfinished videos, and raises :class:`BatchInterrupted`; the outputs and manifest
lines of the finished videos stay, so a rerun does the rest. A second signal while that
runs is ignored (the clean-up is bounded by timeouts).
"""
from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import logging
import os
import re
import signal
import sys
import threading
import time
import uuid
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import cv2
from distributed import Client, LocalCluster, WorkerPlugin, as_completed
from distributed.scheduler import KilledWorker

from ..errors import DataError, FastdetError
from .inputs import output_names
from .manifest import Manifest, input_stat
from .progress import BatchProgress
from .settings import MANIFEST_NAME, SUFFIXES, Settings, output_paths
from .summary import format_summary as _format_summary
from .table import write_table
from .task import PARTIAL_DIR, VideoTask, run_video

POLL_S = 0.2  # how often the main thread looks at finished tasks and redraws the bar
CONNECT_TIMEOUT_S = 20
CLOSE_TIMEOUT_S = 20
#: environment of the local cluster's worker processes (a user's own NUMBA_NUM_THREADS wins)
WORKER_ENV = {"NUMBA_NUM_THREADS": "1", "OMP_WAIT_POLICY": "PASSIVE"}


class BatchInterrupted(Exception):
    """The batch was stopped by signal ``signum`` (after cleaning up)."""

    def __init__(self, signum: int, done: int) -> None:
        super().__init__(f"stopped by {signal.Signals(signum).name}")
        self.signum = signum
        self.done = done


@dataclass(frozen=True)
class BatchOptions:
    """How to run a batch. ``workers``: local worker processes (default: the usable cores);
    ``scheduler``: address of a running Dask scheduler (then ``workers`` is unused);
    ``overwrite``: redo finished videos (default: skip them); ``retries``: extra attempts of a
    task that raised; ``table``: path of the combined table or ``None``; ``progress``: a bar."""

    out_dir: Path
    settings: Settings
    workers: int | None = None
    scheduler: str | None = None
    overwrite: bool = False
    retries: int = 2
    table: Path | None = None
    progress: bool = True


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


class _Signals:
    """While active, SIGINT / SIGTERM / SIGHUP are recorded in ``signum`` instead of ending
    the process; :meth:`check` raises at a safe point. No-op outside the main thread."""

    SIGNALS = tuple(s for s in (signal.SIGINT, signal.SIGTERM, getattr(signal, "SIGHUP", None)) if s is not None)

    def __init__(self) -> None:
        self.signum: int | None = None
        self._old: dict[int, Any] = {}

    def _handler(self, signum: int, frame: Any) -> None:
        if self.signum is None:
            self.signum = signum

    def __enter__(self) -> _Signals:
        if threading.current_thread() is threading.main_thread():
            for s in self.SIGNALS:
                self._old[s] = signal.signal(s, self._handler)
        return self

    def __exit__(self, *exc: object) -> None:
        for s, old in self._old.items():
            signal.signal(s, old)
        self._old.clear()

    def check(self, done: int) -> None:
        if self.signum is not None:
            raise BatchInterrupted(self.signum, done)


@contextlib.contextmanager
def _client(opts: BatchOptions) -> Iterator[tuple[Client, int]]:
    """A client on the local cluster or on ``opts.scheduler``, closed (with the local
    cluster) on exit; yields ``(client, number of workers)``."""
    cluster = None
    try:
        if opts.scheduler:
            try:
                client = Client(opts.scheduler, timeout=CONNECT_TIMEOUT_S, set_as_default=False)
            except (OSError, TimeoutError, ValueError) as exc:
                raise FastdetError(f"cannot connect to the Dask scheduler at {opts.scheduler}: "
                                   f"{str(exc).splitlines()[0] if str(exc) else type(exc).__name__}") from None
        else:
            n = opts.workers or default_workers()
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


def _partial_pattern(names: Sequence[str]) -> re.Pattern[str]:
    exts = "|".join(re.escape(s.rsplit(".", 1)[1]) for s in SUFFIXES.values())
    kinds = "|".join(re.escape(s.rsplit(".", 1)[0].lstrip(".")) for s in SUFFIXES.values())
    alts = "|".join(re.escape(n) for n in sorted(set(names), key=len, reverse=True))
    return re.compile(rf"^\.?(?:{alts})\.(?:{kinds})\.[0-9a-f]{{16}}(?:\.partial)?\.(?:{exts})$")


def remove_partials(out_dir: Path, names: Sequence[str]) -> None:
    """Remove the temporary files of ``names`` left by stopped or killed attempts, and the
    ``.partial`` folder when it is empty."""
    d = out_dir / PARTIAL_DIR
    if not names or not d.is_dir():
        return
    pat = _partial_pattern(names)
    try:
        for p in d.iterdir():
            if pat.match(p.name):
                p.unlink(missing_ok=True)
        if not any(d.iterdir()):
            d.rmdir()
    except OSError:
        pass


def _one_line(exc: BaseException) -> str:
    if isinstance(exc, KilledWorker):
        return "its worker died every time it ran it (Dask KilledWorker)"
    text = str(exc).strip()
    return f"{type(exc).__name__}: {text.splitlines()[0]}" if text else type(exc).__name__


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


def _run_tasks(client: Client, tasks: list[VideoTask], stats: dict[str, dict[str, int]], opts: BatchOptions,
               manifest: Manifest, report: BatchReport, signals: _Signals) -> None:
    progress = BatchProgress([t.name for t in tasks], opts.progress)
    job = tasks[0].topic or "fastdet-batch"
    futures: dict[Any, VideoTask] = {}
    try:
        client.subscribe_topic(job, progress.on_event)
        for t in tasks:
            futures[client.submit(run_video, t, key=f"{job}-{t.name}", retries=opts.retries, pure=False)] = t
        ac = as_completed(list(futures), loop=client.loop)
        while not ac.is_empty():
            signals.check(len(report.done))
            for fut in ac.next_batch(block=False):
                task = futures.pop(fut)
                try:
                    summary = fut.result()
                except Exception as exc:  # noqa: BLE001 - the task raised on every attempt, or its workers died
                    summary = {"status": "failed", "error": _one_line(exc), "frames": 0}
                fut.release()
                entry = _entry(summary, task, stats[task.input], opts.settings)
                manifest.append(entry)
                (report.done if entry["status"] == "done" else report.failed).append(entry)
                progress.finished(entry)
            if not ac.has_ready():
                time.sleep(POLL_S)
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
    t0 = time.perf_counter()
    out_dir = Path(os.path.abspath(opts.out_dir))
    prepare_out_dir(out_dir)
    manifest = Manifest(out_dir / MANIFEST_NAME)
    settings = opts.settings
    digest = settings.digest()
    topic = f"fastdet-batch-{uuid.uuid4().hex[:12]}"
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
        tasks.append(VideoTask(path, name, str(out_dir), settings, topic))

    todo = [t.name for t in tasks]
    with _Signals() as signals:
        if tasks:
            remove_partials(out_dir, todo)
            try:
                signals.check(0)
                with _client(opts) as (client, workers):
                    report.workers = workers
                    signals.check(0)
                    _run_tasks(client, tasks, stats, opts, manifest, report, signals)
            except BatchInterrupted:
                # the client and the local cluster are closed: no attempt of ours still writes
                # (on a remote cluster a running task may: its files are left to the next run)
                if not opts.scheduler:
                    remove_partials(out_dir, todo)
                raise
            except KeyboardInterrupt:  # a signal before the handlers were in place
                raise BatchInterrupted(signal.SIGINT, len(report.done)) from None
            remove_partials(out_dir, todo)
        signals.check(len(report.done))
        if opts.table is not None:
            order = {str(v): i for i, v in enumerate(videos)}
            ok = sorted(report.done + report.skipped, key=lambda e: order.get(e["input"], 0))
            report.table_rows = write_table(opts.table, [(e["name"], out_dir / e["outputs"]["boxes"]) for e in ok])
    report.wall = time.perf_counter() - t0
    return report
