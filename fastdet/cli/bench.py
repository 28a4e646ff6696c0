"""``python -m fastdet bench [INPUT] [--frames N] [--threads T] [--repeat R] [--model M.npz]
[--oncoming-model W.npz | --no-oncoming]``

Times the stages of :class:`~fastdet.VideoDetector` (what ``python -m fastdet video``
runs on its main thread for every frame) on a video or an image, and prints ms per frame
per stage and the frames per second they allow.

- INPUT: a video, an image sequence (``img%04d.jpg``) or a stream URL (its first N
  frames), or an image (the same frame N times); default
  ``test_images/test1.jpg`` in the data folder (:func:`fastdet.data.data_dir`). Frames are
  decoded into memory before timing, so decoding is not in the figures (it runs in a
  reader thread in ``video``; it is printed on its own line for a video).
- Stages: ``resize/colour`` (crop, resize, colour conversion of every band), ``HOG``
  (block maps), ``scoring`` (spatial map, histogram integral image, dense window scores),
  ``heat`` and ``label`` (heat map, blobs, boxes), ``motion`` (the frame difference that
  narrows and gates the oncoming-traffic model's search), the rest of each stage of
  :mod:`fastdet.video.stages` under its name (``detect (rest)``: band geometry, thresholding,
  window boxes; ``oncoming heat``: the oncoming model's heat map and the merge of its boxes)
  -- :attr:`VideoDetector.timings` -- and ``other``: the rest of ``update`` (Python glue).
  As ``video``, the bundled oncoming-traffic model runs unless
  ``--no-oncoming``; on an image (the same frame N times) nothing moves, so it searches nothing.
- One repeat = N frames through one ``VideoDetector`` whose heat map was reset first;
  the kernels are loaded and two frames processed before the first repeat (warm-up). The
  table gives, per stage, the best and the median over the ``R`` repeats of the mean ms
  per frame; ``fps`` is ``1000 / total`` of the best repeat (the median in brackets).
- ``--threads T`` sets Numba's and OpenCV's thread count (at most ``NUMBA_NUM_THREADS``);
  like ``video``, idle OpenMP workers sleep (``OMP_WAIT_POLICY=PASSIVE``) unless the
  environment says otherwise (the header line shows the setting: with ``ACTIVE`` two
  threads are faster on an idle machine and many times slower on a busy one).

Bad input (missing file, a folder, a file that is neither an image nor a video OpenCV can
read, a model that does not load) raises :class:`~fastdet.errors.FastdetError`: one line,
exit status 2.
"""
from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path
from typing import Any

import cv2
import numba
import numpy as np

from ..console import quiet_native_stderr
from ..data import data_dir
from ..detect import Detector
from ..detect.checks import check_frame
from ..errors import DataError, FastdetError
from ..io.images import check_image
from ..io.reader import FrameReader, check_source
from ..video.detector import make_detector
from ..video.pipeline import VideoDetector
from ._args import pipeline_config, pipeline_groups, positive_int

DEFAULT_IMAGE = Path("test_images") / "test1.jpg"

#: (label, key in VideoDetector.timings)
STAGES = (
    ("horizon", "horizon"),
    ("plan", "plan"),
    ("motion", "motion"),
    ("resize/colour", "resize_colour"),
    ("HOG", "hog"),
    ("scoring", "score"),
    ("detect (rest)", "detect"),
    ("heat", "heat"),
    ("label", "label"),
    ("heat map (rest)", "heatmap"),
    ("oncoming heat", "fusion"),
    ("weak blobs", "weak"),
    ("track", "track"),
    ("clip", "clip"),
    ("refine", "refine"),
    ("plausible", "plausible"),
    ("observe", "observe"),
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.usage = "%(prog)s [INPUT] [--frames N] [--repeat R] [options]"
    what = parser.add_argument_group("what to time")
    what.add_argument("input", metavar="INPUT", nargs="?", default=None,
                      help=f"video, image sequence, URL or image (default: {DEFAULT_IMAGE})")
    what.add_argument("--frames", type=positive_int, default=30, metavar="N",
                      help="frames per repeat (default 30)")
    what.add_argument("--repeat", type=positive_int, default=3, metavar="R",
                      help="timed repeats: best and median (default 3)")
    what.add_argument("--threads", type=positive_int, default=None, metavar="T",
                      help="Numba and OpenCV threads (default: all)")
    pipeline_groups(parser)


def load_frames(path: str | os.PathLike, n: int) -> tuple[list, str, float | None]:
    """``(frames, kind, decode ms per frame)``: an image repeated ``n`` times (``kind``
    ``'image'``, no decode time) or the first ``n`` frames of a video (``'video'``; fewer
    when it is shorter). Raises :class:`DataError` for anything unreadable."""
    name = os.fspath(path)
    kind = check_source(name)
    if os.path.isdir(name):
        raise DataError(f"{name}: is a folder, not an image or a video")
    if kind == "file" and cv2.haveImageReader(name):
        with quiet_native_stderr():  # libjpeg's warnings: check_image says it in one line
            frame = cv2.imread(name, cv2.IMREAD_COLOR)
        if frame is None:
            raise DataError(f"{name}: not an image OpenCV can read (damaged?)")
        check_image(name)
        return [frame] * n, "image", None

    try:
        reader = FrameReader(name, 0, n)
    except DataError as exc:
        msg = str(exc)
        if "not a video OpenCV can read" in msg or msg.endswith("the video has no frames"):
            msg = f"{name}: neither an image nor a video OpenCV can read (damaged, empty or another format)"
        raise DataError(msg) from None
    frames, decode = [], 0.0
    try:
        for _, frame, dt in reader:
            frames.append(frame)
            decode += dt
    finally:
        reader.close()
    frames = [np.ascontiguousarray(f) for f in frames]
    return frames, "video", 1e3 * decode / len(frames)


def _detector(args: argparse.Namespace) -> Detector:
    try:
        return make_detector(pipeline_config(args))
    except FastdetError:
        raise
    except (OSError, ValueError) as exc:
        raise FastdetError(f"model: {exc}") from None


def time_stages(vd: Any, frames: list, repeat: int) -> list[dict[str, float]]:
    """Run ``frames`` through ``vd`` (a warmed-up VideoDetector) ``repeat`` times, resetting
    its heat map before each; returns per repeat the mean seconds per frame of each stage,
    ``other`` (rest of ``update``) and ``total``."""
    runs = []
    for _ in range(repeat):
        vd.reset()
        sums = {key: 0.0 for _, key in STAGES}
        wall = 0.0
        for frame in frames:
            t0 = time.perf_counter()
            vd.update(frame)
            wall += time.perf_counter() - t0
            for _, key in STAGES:
                sums[key] += vd.timings.get(key, 0.0)
        n = len(frames)
        run = {k: v / n for k, v in sums.items()}
        run["other"] = max(wall / n - sum(run.values()), 0.0)
        run["total"] = wall / n
        runs.append(run)
    return runs


def format_table(runs: list[dict[str, float]]) -> str:
    best = min(runs, key=lambda r: r["total"])
    rows = [(label, key) for label, key in STAGES] + [("other", "other")]
    lines = [f"{'stage':<15}{'best ms':>9}{'median ms':>11}{'share':>8}"]
    # with band threads the detector's stage times add up the work of every thread, so the
    # shares are of the summed work, and `total` (wall time) can be less than the sum
    work = sum(best[key] for _, key in rows)
    for label, key in rows:
        b = min(r[key] for r in runs)
        med = statistics.median(r[key] for r in runs)
        share = best[key] / work if work else 0.0
        lines.append(f"{label:<15}{1e3 * b:>9.2f}{1e3 * med:>11.2f}{100 * share:>7.0f}%")
    med_total = statistics.median(r["total"] for r in runs)
    lines.append(f"{'total (wall)':<15}{1e3 * best['total']:>9.2f}{1e3 * med_total:>11.2f}")
    lines.append(f"{'fps':<15}{1 / best['total']:>9.1f}{1 / med_total:>11.1f}")
    lines.append("(stage times add up the work of all band threads; shares are of that sum)")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    """The ``bench`` subcommand."""
    if args.input is None:
        args.input = str(data_dir() / DEFAULT_IMAGE)
    frames, kind, decode_ms = load_frames(args.input, args.frames)

    max_threads = numba.config.NUMBA_NUM_THREADS
    threads = args.threads if args.threads is not None else max_threads
    if threads > max_threads:
        raise FastdetError(f"--threads {threads}: at most NUMBA_NUM_THREADS={max_threads} "
                           f"(set the environment variable to allow more)")
    before = numba.get_num_threads(), cv2.getNumThreads()
    numba.set_num_threads(threads)
    cv2.setNumThreads(threads)
    try:
        det = _detector(args)
        check_frame(det, frames[0], args.input, more=lambda: frames[1:])
        vd = VideoDetector(det, pipeline_config(args))
        t0 = time.perf_counter()
        vd.warmup()
        for frame in frames[:2]:
            vd.update(frame)
        warm_s = time.perf_counter() - t0

        runs = time_stages(vd, frames, args.repeat)

        h, w = frames[0].shape[:2]
        n_bands = sum(len(sc.search.bands) for sc in det.scorers)
        models = "main model" if det.oncoming_model is None else "main + oncoming model"
        try:
            layer = numba.threading_layer()
        except ValueError:
            layer = "none"
        omp = "".join(f", {k}={os.environ[k]}" for k in ("OMP_WAIT_POLICY", "GOMP_SPINCOUNT") if k in os.environ)
        print(f"fastdet bench: {os.path.basename(args.input)} ({kind}, {w}x{h}), {len(frames)} frames "
              f"x {args.repeat} repeats, {threads} thread(s) (numba {layer}{omp}), {models}, {n_bands} bands")
        print(f"warm-up (load kernels, 2 frames): {warm_s:.2f} s")
        if decode_ms is not None:
            print(f"decode (not in the total; a reader thread in `video`): {decode_ms:.2f} ms/frame")
        print(format_table(runs), flush=True)
    finally:
        numba.set_num_threads(before[0])
        cv2.setNumThreads(before[1])
    return 0
