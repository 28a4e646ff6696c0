"""``python -m fastdet label``: a teacher CNN's boxes for every N-th frame of videos.

``python -m fastdet label VIDEO|DIR --teacher MODEL.onnx -o OUT [--every N] [--size PX]
[--min-score S] [--threads N] [--no-progress]``

- VIDEO is a video file; DIR a folder, whose video files (by extension, not its sub-folders,
  hidden files left out) are labelled in the order of their names.
- The teacher is a YOLOX-style ONNX detector (:mod:`fastdet.teacher.yolox`; the shared
  ``teachers/yolox_nano.onnx``), run with onnxruntime -- an optional dependency: without it
  the command says in one line to install ``fastdet[teacher]``.
- For each clip it writes into the folder OUT (made when missing) ``CLIP.teacher.txt``
  (``frame,-1,left,top,width,height,score,class,-1,-1``, the format of the shared
  ``teacher/`` files) and ``CLIP.frames`` (the frames looked at: 1, 1 + N, 1 + 2N, ...
  among the frames that decode), both renamed into place together when the clip is done
  (:mod:`fastdet.teacher.label`).
- Everything is checked before any output exists (exit 2, one line): every video opens and
  has a frame, the teacher loads and has the layout of a YOLOX head, the numbers are in
  their domain, OUT is (or can be made) a writable folder, and no output is an input or
  another clip's output (two clips of one name in DIR).
- A stop signal (Ctrl-C, SIGTERM, SIGHUP) ends the run after the current frame: the clips
  finished before it keep their files, the clip being labelled gets none (not a part of
  it under the final names); exit status 128 + the signal. A failed write is one line, exit 2,
  and that clip gets no files.
- The summary gives the clips, the frames labelled, the boxes and the seconds.
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import time
from pathlib import Path

from tqdm import tqdm

from .. import signals as _signals
from ..console import prog
from ..errors import DataError
from ..io.paths import check_paths
from ..io.reader import FrameReader
from ..teacher.label import check_every, clip_name, is_labelled, teacher_paths, write_teacher_files
from ..teacher.yolox import TeacherBoxes, TeacherDetector
from ._args import positive_int, teacher_size, video_files

DEFAULT_EVERY = 5


def score_floor(s: str) -> float:
    """argparse type of ``--min-score``: a number in (0, 1]."""
    try:
        v = float(s)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number in (0, 1], got {s!r}") from None
    if not (math.isfinite(v) and 0 < v <= 1):
        raise argparse.ArgumentTypeError(f"expected a number in (0, 1], got {s!r}")
    return v


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("input", metavar="VIDEO|DIR", help="a video file, or a folder whose video files are labelled")
    parser.add_argument("--teacher", required=True, metavar="MODEL.onnx",
                        help="a YOLOX-style ONNX detector (e.g. the data folder's teachers/yolox_nano.onnx)")
    parser.add_argument("-o", "--output", required=True, metavar="OUT",
                        help="folder for CLIP.teacher.txt and CLIP.frames (made when missing)")
    parser.add_argument("--every", type=positive_int, default=DEFAULT_EVERY, metavar="N",
                        help=f"label frames 1, 1+N, 1+2N, ... (default {DEFAULT_EVERY})")
    parser.add_argument("--size", type=teacher_size, default=None, metavar="PX",
                        help="the network input's width, rounded to a multiple of 32; the height follows the "
                             "frame's aspect (default 640, or the model's own fixed size)")
    parser.add_argument("--min-score", type=score_floor, default=0.1, metavar="S",
                        help="drop boxes scoring below S (objectness x class probability; default 0.1)")
    parser.add_argument("--threads", type=positive_int, default=None, metavar="N",
                        help="onnxruntime threads (default NUMBA_NUM_THREADS, else every core)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def _check_videos(videos: list[str]) -> None:
    """Every video opens and decodes its first frame (:class:`FrameReader`), or one line."""
    for v in videos:
        FrameReader(v, notify=lambda _n: None).close()


def _make_folder(out: str) -> list[str]:
    """Make the folder ``out`` (and missing parents); the folders made, deepest last."""
    if os.path.exists(out) and not os.path.isdir(out):
        raise DataError(f"-o {out}: is not a folder (OUT is the folder for CLIP.teacher.txt and CLIP.frames)")
    made: list[str] = []
    p = os.path.abspath(out)
    while not os.path.exists(p):
        made.append(p)
        p = os.path.dirname(p)
    try:
        for d in reversed(made):
            os.mkdir(d)
    except OSError as exc:
        _remove_folders(made)
        raise DataError(f"-o {out}: cannot make the folder ({exc.strerror or exc})") from None
    return list(reversed(made))


def _remove_folders(made: list[str]) -> None:
    for d in sorted(made, key=len, reverse=True):
        try:
            os.rmdir(d)
        except OSError:
            pass


def run(args: argparse.Namespace) -> int:
    """The ``label`` subcommand."""
    t_start = time.perf_counter()
    every = check_every(args.every)
    videos = video_files(args.input)
    _check_videos(videos)
    detector = TeacherDetector(args.teacher, size=args.size, min_score=args.min_score,
                               threads=getattr(args, "threads", None))
    out = args.output
    outputs = [(v, clip_name(v), *teacher_paths(out, clip_name(v))) for v in videos]
    made = _make_folder(out)
    try:
        check_paths([("VIDEO", v) for v in videos] + [("--teacher", args.teacher)],
                    [(f"-o ({os.path.basename(v)})", p, what) for v, _, tp, fp in outputs
                     for p, what in ((tp, "teacher box"), (fp, "frame list"))])
    except BaseException:
        _remove_folders(made)
        raise

    done: list[str] = []
    try:
        with _signals.deferred(raise_on_exit=False):  # a stop: after the current frame
            n_read, n_frames, n_boxes = _label_all(args, detector, every, outputs, done)
    finally:
        if not done:
            _remove_folders(made)  # no clip done: not even an empty OUT left behind

    secs = time.perf_counter() - t_start
    summary = (f"{len(done)} clip{'s' if len(done) != 1 else ''}, {n_frames} frames labelled "
               f"(1 in {every} of {n_read} read), {n_boxes} boxes in {secs:.1f} s; wrote "
               + (f"{len(done) * 2} files into {Path(out)}" if done else "nothing"))
    signum = _signals.received()
    if signum is not None:
        left = len(outputs) - len(done)
        raise _signals.Stopped(signum, summary + f"; {left} clip{'s' if left != 1 else ''} not labelled "
                                                 f"(no files for the clip that was stopped)")
    print(f"{prog()}: {summary}", flush=True)
    return 0


def _label_all(args: argparse.Namespace, detector: TeacherDetector, every: int,
               outputs: list[tuple[str, str, Path, Path]], done: list[str]) -> tuple[int, int, int]:
    """Label the clips in turn, each clip's files written when it is done (its name then
    appended to ``done``); at a stop signal, after the current frame, the clip being
    labelled is dropped. Returns (frames read, frames labelled, boxes)."""
    n_frames = n_boxes = n_read = 0
    for video, clip, _, _ in outputs:
        labelled: list[tuple[int, TeacherBoxes]] = []
        reader = FrameReader(video)
        bar = tqdm(total=reader.expected, unit="frame", desc=clip, file=sys.stderr, dynamic_ncols=True,
                   disable=args.no_progress or not sys.stderr.isatty())
        try:
            for fno, frame, _ in reader:
                if _signals.stop_requested():
                    break
                n_read += 1
                if is_labelled(fno, every):
                    labelled.append((fno, detector.detect(frame)))
                bar.update(1)
        finally:
            bar.close()
            reader.close()
        if _signals.stop_requested():
            break  # this clip's frames are dropped: no files for a part of a clip
        write_teacher_files(args.output, clip, labelled)
        done.append(clip)
        n_frames += len(labelled)
        n_boxes += sum(len(b) for _, b in labelled)
    return n_read, n_frames, n_boxes
