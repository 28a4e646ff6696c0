"""A teacher's boxes for a video: every N-th frame labelled (:func:`label_video`), written as
the shared ``teacher/`` folder's files (:func:`write_teacher_files`).

Files, for a clip ``CLIP`` (the video's name without its extension):

- ``CLIP.teacher.txt``: MOTChallenge detection lines, one a box,
  ``frame,-1,left,top,width,height,score,class,-1,-1`` -- ``frame`` 1-based, the box in
  frame px with one decimal, ``score`` with three, ``class`` the COCO id (2 car,
  3 motorcycle, 5 bus, 7 truck); the frames in order, each frame's boxes by score, highest first;
- ``CLIP.frames``: the 1-based numbers of the frames looked at, one a line (a listed frame
  without lines in ``CLIP.teacher.txt``: the teacher saw nothing there).

Both are written under temporary names and renamed together when complete
(:class:`~fastdet.io.atomic.OutputSet`): never one without the other, never a partial one.
"""
from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

import numpy as np

from ..errors import FastdetError, WriteError
from ..io.atomic import OutputSet, partial_name
from ..io.reader import FrameReader
from .yolox import TeacherBoxes, TeacherDetector

TEACHER_SUFFIX = ".teacher.txt"
FRAMES_SUFFIX = ".frames"

Labelled = tuple[int, TeacherBoxes]


def clip_name(video: str | os.PathLike[str]) -> str:
    """``CLIP`` of a video file: its name without the last extension (``a/b.c.mp4`` -> ``b.c``)."""
    return Path(video).stem


def teacher_paths(out_dir: str | os.PathLike[str], clip: str) -> tuple[Path, Path]:
    """``(OUT/CLIP.teacher.txt, OUT/CLIP.frames)``."""
    return Path(out_dir) / f"{clip}{TEACHER_SUFFIX}", Path(out_dir) / f"{clip}{FRAMES_SUFFIX}"


def is_labelled(frame: int, every: int) -> bool:
    """Frame ``frame`` (1-based) is one of every ``every``-th frame from frame 1."""
    return (frame - 1) % every == 0


def check_every(every: int) -> int:
    """``every`` as a whole number >= 1, or one line (:class:`~fastdet.errors.FastdetError`)."""
    if isinstance(every, bool) or int(every) != every or every < 1:
        raise FastdetError(f"every must be a whole number >= 1, got {every!r}")
    return int(every)


def format_line(frame: int, box: Iterable[float], score: float, cls: int) -> str:
    """One line of a ``.teacher.txt`` file (no newline), for a box ``x1, y1, x2, y2`` in frame px."""
    x1, y1, x2, y2 = (float(v) for v in box)
    return f"{frame},-1,{x1:.1f},{y1:.1f},{x2 - x1:.1f},{y2 - y1:.1f},{float(score):.3f},{int(cls)},-1,-1"


def label_frames(frames: Iterable[tuple[int, np.ndarray]], detector: TeacherDetector,
                 every: int = 5) -> Iterator[Labelled]:
    """``(frame number, boxes)`` for every ``every``-th frame of ``frames`` (``(1-based
    number, (h, w, 3) uint8 BGR frame)`` pairs) from frame 1; the other frames are passed over."""
    every = check_every(every)
    for fno, frame in frames:
        if is_labelled(fno, every):
            yield fno, detector.detect(frame)


def label_video(source: str | os.PathLike[str], detector: TeacherDetector, every: int = 5,
                on_frame: Callable[[int], None] | None = None) -> list[Labelled]:
    """Every ``every``-th frame of the video ``source`` from frame 1, labelled by ``detector``:
    ``[(frame number, TeacherBoxes), ...]`` in frame order. Frames are read with
    :class:`~fastdet.io.reader.FrameReader` (damaged frames skipped, numbers kept);
    ``on_frame(number)`` is called after each frame read (progress)."""
    every = check_every(every)
    out: list[Labelled] = []
    with FrameReader(source) as reader:
        for fno, frame, _ in reader:
            if is_labelled(fno, every):
                out.append((fno, detector.detect(frame)))
            if on_frame is not None:
                on_frame(fno)
    return out


def _write(tmp: Path, final: Path, text: str) -> None:
    try:
        with open(tmp, "w", encoding="utf-8", newline="\n") as fh:
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())
    except BaseException as exc:
        try:
            tmp.unlink(missing_ok=True)
        except OSError:
            pass
        if isinstance(exc, OSError):
            raise WriteError(f"{final}: cannot write ({exc.strerror or exc})") from None
        raise


def teacher_text(labelled: Iterable[Labelled]) -> tuple[str, str]:
    """The text of ``CLIP.teacher.txt`` and of ``CLIP.frames`` for ``labelled`` frames (in
    the order given)."""
    lines: list[str] = []
    numbers: list[str] = []
    for fno, boxes in labelled:
        numbers.append(f"{int(fno)}\n")
        lines.extend(format_line(fno, b, s, c) + "\n" for b, s, c in zip(boxes.boxes, boxes.scores, boxes.classes))
    return "".join(lines), "".join(numbers)


def write_teacher_files(out_dir: str | os.PathLike[str], clip: str, labelled: Iterable[Labelled],
                        pending: OutputSet | None = None) -> tuple[Path, Path]:
    """Write ``OUT/CLIP.teacher.txt`` and ``OUT/CLIP.frames`` for ``labelled`` frames, both
    under temporary names first. Without ``pending`` they are renamed together at once;
    with it they are added to it and the caller commits (or discards) them. A failed write is
    one line (:class:`~fastdet.errors.WriteError`) and leaves neither file."""
    boxes_path, frames_path = teacher_paths(out_dir, clip)
    boxes_text, frames_text = teacher_text(labelled)
    own = pending is None
    outputs = OutputSet() if pending is None else pending
    t_boxes, t_frames = partial_name(boxes_path), partial_name(frames_path)
    _write(t_boxes, boxes_path, boxes_text)
    try:
        _write(t_frames, frames_path, frames_text)
    except BaseException:
        t_boxes.unlink(missing_ok=True)
        raise
    outputs.add(t_boxes, boxes_path)
    outputs.add(t_frames, frames_path)
    if own:
        try:
            outputs.commit()
        except BaseException:
            outputs.discard()
            raise
    return boxes_path, frames_path
