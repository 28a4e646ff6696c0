"""Teacher labels of videos on the Dask cluster ``batch`` uses: one task per video.

``python -m fastdet adapt FOOTAGE --teacher M.onnx --workers N`` (a local cluster of N worker
processes) or ``--scheduler tcp://host:8786`` (a running cluster, whose workers see the same
paths and have ``fastdet[cluster,teacher]`` installed) labels each video in a task of its own
(:func:`label_video`): the worker loads the teacher once per task, on one thread (the
parallelism is one video per worker), reads the video and returns the boxes of the planned
frames. Only paths and frame numbers travel to the workers and only the boxes come back; the
caller writes the label files, so the work folder need not be shared.
"""
from __future__ import annotations

import contextlib
import itertools
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any

from ..errors import FastdetError, one_line
from ..io.reader import FrameReader
from ..teacher.label import Labelled
from .cluster import as_they_end, client_for


@dataclass(frozen=True)
class LabelTask:
    """One video to label: ``frames``, 1-based frame numbers in increasing order; ``teacher``,
    the ONNX file (a path the workers can open) with its ``size`` (input width, px, ``None``
    its default) and ``min_score`` (``None``: its default)."""

    video: str
    frames: tuple[int, ...]
    teacher: str
    size: int | None = None
    min_score: float | None = None


def label_video(task: LabelTask) -> list[Labelled]:
    """The teacher's boxes of ``task``'s frames, ``[(frame number, TeacherBoxes), ...]`` in
    frame order (what runs on a worker; frames past the last planned one are not read)."""
    from ..teacher.yolox import TeacherDetector

    detector = TeacherDetector(task.teacher, size=task.size, min_score=task.min_score, threads=1)
    want = set(task.frames)
    last = max(want, default=0)
    out: list[Labelled] = []
    with FrameReader(task.video) as reader:
        for fno, frame, _ in reader:
            if fno > last:
                break
            if fno in want:
                out.append((fno, detector.detect(frame)))
    return out


def label_on_cluster(tasks: Sequence[LabelTask], workers: int | None = None, scheduler: str | None = None
                     ) -> Iterator[tuple[LabelTask, list[Labelled]]]:
    """``(task, labels)`` of each task as it ends on the cluster (in any order): a local
    cluster of ``workers`` processes (default one per core) or the scheduler at ``scheduler``.
    A task that raised is :class:`~fastdet.errors.FastdetError` naming its video (the other
    tasks are cancelled). Call it inside :func:`fastdet.signals.deferred`: a stop signal ends
    the wait, the tasks still running are cancelled and the generator returns (the caller says
    what was done)."""
    if not tasks:
        return
    with client_for(workers, scheduler) as (client, _):
        number = itertools.count()

        def submit(t: LabelTask) -> Any:
            return client.submit(label_video, t, key=f"fastdet-label-{next(number)}-{t.video}", pure=False)

        with contextlib.closing(as_they_end(client, tasks, submit)) as ended:
            for task, fut in ended:
                try:
                    labelled = fut.result()
                except Exception as exc:  # noqa: BLE001 - said with the video's name
                    raise FastdetError(f"{task.video}: labelling on the cluster failed: {one_line(exc)}") from None
                fut.release()
                yield task, labelled
