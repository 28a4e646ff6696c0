"""One video of a batch, run on a Dask worker: :func:`run_video`.

The task gets paths and settings (:class:`VideoTask`) and returns a small summary dict. It
runs the same building blocks, in the same way, as ``python -m fastdet video``:
:class:`~fastdet.io.reader.FrameReader` → :class:`~fastdet.video.pipeline.VideoDetector`
(a fresh one per video: heat map and motion state start empty) →
:class:`~fastdet.io.motfiles.MotWriter` / :class:`~fastdet.io.motfiles.JsonLinesWriter` /
:class:`~fastdet.io.sink.VideoSink`, so the boxes are byte-identical to ``video --boxes``
(``tests/batch/test_job.py`` checks it).

- The detector (models loaded, kernels warmed up) is made once per worker process and
  settings (:func:`detector_for`), and every task runs the kernels on one Numba thread:
  the batch gets its parallelism from the tasks (throughput), not from threads in a frame.
- Every output is written under a temporary name unique to this attempt, in the folder of
  this batch run (``OUT/.partial/RUN/NAME.boxes.<token>.txt``, :func:`run_dir`), and the
  task returns their names (``partials``) without renaming them: the batch's main process
  gives them their final names (:func:`commit_outputs`) when it records the video, so after
  a stop signal no video gets a final name without a manifest line. A retried task (its
  worker was killed) writes its own files, and a failed or killed attempt leaves nothing
  under a final name.
- A video that cannot be used (:class:`~fastdet.errors.FastdetError`: not a video, frames
  too small or grey) is returned as ``status: "failed"`` with the one-line reason and
  ``permanent: True``: retrying would fail again (a rerun skips it while the file is
  unchanged). A failed write (:class:`~fastdet.errors.WriteError`: a full disk, a vanished
  temporary file) or a model that does not load is ``permanent: False``: not a property of
  the video, so the next run tries it again. Any other exception propagates, and Dask
  retries the task. The reader's notes (damaged frames skipped, a frame count other than
  the header's) are returned in ``notes`` instead of being printed on the worker.
- Progress: while it runs, the task sends ``{"name", "token", "frames", "expected"}``
  events on the Dask topic ``task.topic`` (:meth:`distributed.Worker.log_event`) at most
  every :data:`PROGRESS_EVERY` seconds, and once at the end.
"""
from __future__ import annotations

import contextlib
import os
import secrets
import socket
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from distributed import get_worker

from .._numba import serial_thread
from ..errors import FastdetError, ModelError, WriteError, one_line
from ..io.atomic import OutputSet, process_token
from ..io.motfiles import JsonLinesWriter, MotWriter
from ..io.reader import FrameReader
from ..io.sink import VideoSink
from ..video.detector import make_detector
from ..video.pipeline import run_frames
from ..video.run import video_detector_for
from .settings import Settings, output_paths

PROGRESS_EVERY = 0.5  # seconds between progress events of one task
PARTIAL_DIR = ".partial"  # folder in OUT for the outputs being written

_detectors: dict[tuple, Any] = {}
_detectors_lock = threading.Lock()


@dataclass(frozen=True)
class VideoTask:
    """One video: ``input`` (absolute path), its output ``name``, the output folder
    ``out_dir`` (absolute), the :class:`Settings`, the Dask event ``topic`` for progress
    (``None``: no progress events) and the ``run`` id of the batch (its temporary folder,
    :func:`run_dir`; default: this process's :func:`~fastdet.io.atomic.process_token`)."""

    input: str
    name: str
    out_dir: str
    settings: Settings
    topic: str | None = None
    run: str = ""


def run_dir(out_dir: str | os.PathLike, run: str) -> Path:
    """The temporary folder of batch run ``run``: ``OUT/.partial/HOST-PID-RANDOM`` (see
    :func:`fastdet.batch.job.run_id`)."""
    return Path(out_dir) / PARTIAL_DIR / run


def detector_for(settings: Settings) -> Any:
    """The warmed-up detector for ``settings``, made once per process (the key includes the
    model files' hashes, so a long-lived worker notices a changed model file)."""
    p = settings.pipeline
    key = (p.model, settings.model_sha256, p.oncoming, settings.oncoming_sha256, p.traffic, p.search)
    with _detectors_lock:
        det = _detectors.get(key)
        if det is None:
            det = make_detector(p)
            det.warmup()
            _detectors[key] = det
        return det


def partial_path(folder: str | os.PathLike, final: Path, token: str, kind: str = "out") -> Path:
    """Temporary name of the output ``kind`` (``final``) for the attempt ``token`` in ``folder``
    (the run's :func:`run_dir`, which only this run writes): ``FOLDER/TOKEN.KIND.EXT``, short
    whatever the video's name (a 240-character name plus a token did not fit the file
    system); the extension is kept (it picks the container)."""
    ext = final.suffix
    return Path(folder) / f"{token}.{kind}{ext}"


def commit_outputs(summary: dict[str, Any], out_dir: str | os.PathLike) -> None:
    """Give a done video's temporary files (``summary["partials"]``) their final names in
    ``out_dir``, all or none (:class:`~fastdet.io.atomic.OutputSet`);
    :class:`~fastdet.errors.WriteError` when one is missing or cannot be renamed."""
    pairs = [(Path(tmp), Path(out_dir) / summary["outputs"][kind]) for kind, tmp in summary["partials"].items()]
    outs = OutputSet()
    for tmp, final in pairs:
        outs.add(tmp, final)
    missing = [final for tmp, final in pairs if not tmp.exists()]
    if missing:
        outs.discard()
        raise WriteError(f"{missing[0]}: its temporary file vanished before the rename")
    outs.commit()


def discard_outputs(summary: dict[str, Any]) -> None:
    """Remove a video's temporary files (a stop came before they were committed)."""
    for tmp in (summary.get("partials") or {}).values():
        with contextlib.suppress(OSError):
            Path(tmp).unlink(missing_ok=True)


def _reporter(task: VideoTask, token: str) -> Callable[[int, int | None, bool], None]:
    """A function ``report(frames, expected, final)`` sending progress events (no-op
    outside a Dask worker or without a topic)."""
    worker = None
    if task.topic is not None:
        try:
            worker = get_worker()
        except ValueError:  # not running on a worker (called directly)
            worker = None
    last = [0.0]

    def report(frames: int, expected: int | None, final: bool = False) -> None:
        now = time.monotonic()
        if worker is None or (not final and now - last[0] < PROGRESS_EVERY):
            return
        last[0] = now
        worker.log_event(task.topic, {"name": task.name, "token": token, "frames": frames,
                                      "expected": expected})

    return report


def _quietly(fn: Callable[[], None]) -> None:
    """Run a clean-up step after a failure; its own error must not hide the first one."""
    with contextlib.suppress(Exception):
        fn()


def _unlink(paths: list[Path]) -> None:
    for p in paths:
        try:
            p.unlink(missing_ok=True)
        except OSError:
            pass


def run_video(task: VideoTask) -> dict[str, Any]:
    """Detect vehicles in one video and write its outputs (see the module docstring).

    Returns ``{"input", "name", "status": "done", "frames", "boxes", "seconds", "outputs":
    {kind: file name}, "sizes": {file name: bytes}, "host", "token"}`` or, for a video that
    cannot be read, ``{"input", "name", "status": "failed", "error", "seconds", "frames", ...}``.
    """
    t0 = time.perf_counter()
    serial_thread()  # this task's kernels run on one core (one task per worker thread)
    token = secrets.token_hex(8)
    s = task.settings
    finals = output_paths(task.out_dir, task.name, s)
    folder = run_dir(task.out_dir, task.run or process_token())
    tmps = {k: partial_path(folder, p, token, k) for k, p in finals.items()}
    summary: dict[str, Any] = {"input": task.input, "name": task.name, "host": socket.gethostname(),
                               "token": token, "frames": 0}
    report = _reporter(task, token)
    notes: list[str] = []
    n = n_boxes = 0
    reader = sink = None
    writers: list[Any] = []

    def close_outputs(discard: bool) -> None:
        """Close the writers: their files get this attempt's temporary names (in the run's
        folder; the batch renames them), or are removed with ``discard``."""
        for wr in (*writers, sink):
            if wr is not None:
                wr.close(discard=discard)

    try:
        folder.mkdir(parents=True, exist_ok=True)
        reader = FrameReader(task.input, notify=notes.append)
        detector = detector_for(s)
        vd = video_detector_for(reader, detector, s.pipeline)
        h, w = reader.shape[:2]
        if "video" in tmps:
            sink = VideoSink(str(tmps["video"]), reader.fps, (w, h), threshold=s.pipeline.heat.threshold)
        mot = MotWriter(tmps["boxes"])
        writers.append(mot)
        jsl = JsonLinesWriter(tmps["json"]) if "json" in tmps else None
        if jsl is not None:
            writers.append(jsl)
        report(0, reader.expected, True)
        for fno, frame, _, dets in run_frames(vd, reader):
            mot.write_detections(fno, dets)
            if jsl is not None:
                jsl.write_detections(fno, dets)
            if sink is not None:
                sink.put((frame, dets, None))
            n += 1
            n_boxes += len(dets)
            report(n, reader.expected)
        close_outputs(discard=False)  # all complete: the batch renames them (commit_outputs)
        report(n, n, True)
    except FastdetError as exc:
        _quietly(lambda: close_outputs(discard=True))
        _unlink(list(tmps.values()))
        # a failed write or a model that does not load says nothing about the video
        permanent = not isinstance(exc, (WriteError, ModelError))
        summary.update(status="failed", error=one_line(exc), permanent=permanent, frames=n,
                       seconds=time.perf_counter() - t0,
                       notes=notes)
        return summary
    except BaseException:
        _quietly(lambda: close_outputs(discard=True))
        _unlink(list(tmps.values()))
        raise
    finally:
        if reader is not None:
            reader.close()
    summary.update(status="done", frames=n, boxes=n_boxes, seconds=time.perf_counter() - t0,
                   skipped_frames=reader.n_skipped, notes=notes,
                   outputs={k: p.name for k, p in finals.items()},
                   partials={k: str(p) for k, p in tmps.items()},
                   sizes={finals[k].name: p.stat().st_size for k, p in tmps.items()})
    return summary
