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

The client and cluster are made in :mod:`fastdet.batch.cluster`, the run folders handled in
:mod:`fastdet.batch.runs`; their public names are re-exported here.
"""
from __future__ import annotations

import contextlib
import os
import time
import uuid
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from distributed import Client
from distributed.scheduler import KilledWorker

from .. import signals
from ..config.batch import BatchOptions
from ..errors import DataError, WriteError, one_line
from ..io.atomic import new_folders
from .cluster import (  # noqa: F401  (re-exported)
    CLOSE_TIMEOUT_S,
    CONNECT_TIMEOUT_S,
    WORKER_ENV,
    BatchInterrupted,
    _connect,
    _glibc_malloc_defaults,
    _WorkerSetup,
    as_they_end,
    check_address,
    client_for,
    default_workers,
)
from .inputs import output_names
from .manifest import Manifest, input_stat
from .progress import BatchProgress
from .runs import _pid_alive, remove_run, remove_stale_runs, run_id  # noqa: F401  (re-exported)
from .settings import MANIFEST_NAME, Settings, max_name_length, output_paths
from .summary import format_summary as _format_summary
from .table import write_table
from .task import VideoTask, commit_outputs, discard_outputs, run_video


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


def _one_line(exc: BaseException) -> str:
    if isinstance(exc, KilledWorker):
        return "its worker died every time it ran it (Dask KilledWorker)"
    if getattr(exc, "reason", None) == "scheduler-connection-lost":  # Dask's FutureCancelledError
        return "the connection to the Dask scheduler was lost (the video is run again on the next run)"
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

    def submit(t: VideoTask) -> Any:
        return client.submit(run_video, t, key=f"{job}-{t.name}", retries=opts.retries, pure=False)

    try:
        client.subscribe_topic(job, progress.on_event)
        with contextlib.closing(as_they_end(client, tasks, submit, idle=progress.refresh)) as ended:
            for task, fut in ended:
                try:
                    summary = fut.result()
                except Exception as exc:  # noqa: BLE001 - the task raised on every attempt, or its workers died
                    summary = {"status": "failed", "error": _one_line(exc), "frames": 0}
                fut.release()
                if signals.stop_requested():  # came while this result arrived: no final names now
                    discard_outputs(summary)
                    continue
                _record(summary, task, opts, stats, manifest, report, progress)
    finally:
        # clean-up after a stop: the client may already be broken, and its error must not
        # hide the reason we stopped (the tasks still running were cancelled above)
        with contextlib.suppress(Exception):
            client.unsubscribe_topic(job)
        progress.close()


@contextmanager
def out_dir_for_run(out_dir: Path) -> Iterator[None]:
    """``with out_dir_for_run(out):`` makes the output folder (and its missing parents)
    if missing -- :class:`DataError` when it cannot be used -- and, when the block raises (a
    scheduler that does not answer or is not Dask, a refused ``--table``, a stop signal before
    any video was done), removes the folders it made that are still empty: a failed start leaves
    no empty ``--out`` behind (issue 34). A folder that existed stays; one that holds anything
    (a manifest line, an output) stays."""
    if out_dir.exists() and not out_dir.is_dir():
        raise DataError(f"{out_dir}: exists and is not a folder")
    with contextlib.ExitStack() as stack:
        try:
            stack.enter_context(new_folders(out_dir))
        except OSError as exc:
            raise DataError(f"{out_dir}: cannot create the output folder ({exc.strerror or exc})") from None
        if not os.access(out_dir, os.W_OK):
            raise DataError(f"{out_dir}: output folder is not writable")
        yield


def run_batch(videos: Sequence[Path], opts: BatchOptions) -> BatchReport:
    """Run the batch of ``videos`` (absolute paths, see :func:`~fastdet.batch.inputs.expand_inputs`)
    and return what happened; raises :class:`BatchInterrupted` after a signal (cleaned up). A
    run that fails to start leaves no output folder it made (:func:`out_dir_for_run`)."""
    with signals.handled():  # a no-op under the CLI's dispatcher, which has them already
        with out_dir_for_run(Path(os.path.abspath(opts.out_dir))):
            return _run_batch(videos, opts)


def _run_batch(videos: Sequence[Path], opts: BatchOptions) -> BatchReport:
    t0 = time.perf_counter()
    out_dir = Path(os.path.abspath(opts.out_dir))
    manifest = Manifest(out_dir / MANIFEST_NAME)
    settings = opts.settings
    digest = settings.digest()
    topic = f"fastdet-batch-{uuid.uuid4().hex[:12]}"
    run = run_id()
    report = BatchReport()
    names = output_names(videos, max_name_length(out_dir))
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
                    with client_for(opts.workers, opts.scheduler) as (client, workers):
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
