"""``python -m fastdet video``: detect vehicles in a video.

``python -m fastdet video INPUT -o OUT.mp4 [--boxes B.txt] [--json B.jsonl] [--model M.npz]
[--oncoming-model W.npz | --no-oncoming] [--traffic right|left|both] [--no-refine] [--debug] [--profile]
[--no-progress] [--start S] [--frames N]
[--no-track | --offline] [--count] [--line X1,Y1,X2,Y2] [--summary S.json]``

- The bundled oncoming-traffic model runs beside the main one (see :class:`VideoDetector`);
  ``--no-oncoming`` leaves it out, ``--oncoming-model`` replaces it, ``--traffic left``
  looks for oncoming cars on the right of the view (left-hand traffic).
- Each box is refined by the learned regressor (:mod:`fastdet.video.refine`); ``--no-refine``
  reports the heat map's boxes as they are.

- Decoding runs in a reader thread and drawing + encoding in a writer thread, connected to
  the detecting main thread by bounded queues: OpenCV and the numba kernels release the
  GIL, so the three overlap on two cores.
- Every vehicle box carries a track id (:mod:`fastdet.video.track`, ByteTrack); ids start
  at 1 and are the same run after run. ``--no-track`` turns the tracker off (ids ``-1``).
  ``--offline`` (files only) runs the offline pass after the last frame
  (:mod:`fastdet.video.offline`: short gaps of a track filled); the
  outputs are then written after the whole file was read (the video by reading the file a
  second time), without the ``--debug`` panels (the heat maps of every frame are not kept).
  A stop signal during that second reading keeps the box files and the summary (complete)
  but not the video (it would hold fewer frames): the line says "OUT not written".
- ``--boxes`` writes MOTChallenge lines ``frame,id,left,top,width,height,conf,-1,-1,-1``
  and ``--json`` one JSON object per frame (:mod:`fastdet.io.motfiles`); both are flushed after
  every frame. ``conf`` is the peak heat of the vehicle's blob
  (:class:`~fastdet.video.pipeline.VideoDetector`): above the heat threshold for a heat-map
  box, at or below it for a weak blob that kept a track alive, 0 for a box the offline pass
  added. ``frame`` is the 1-based frame number in INPUT, so with ``--start S`` the
  first line is frame ``S + 1``, aligned with the ground truth of the whole clip.
- INPUT is a video file, an image sequence (``frames/img%04d.jpg``), a URL (``rtsp://``,
  ``http://``) or a camera index (``0``); live sources have no frame count (the progress
  bar shows no total) and run until the stream ends or the run is stopped. The end of a
  file is where decoding ends (one note when the header counted otherwise); damaged
  frames in the middle are skipped with a note (:mod:`fastdet.io.reader`).
- Every output is written under a temporary name in its folder (``.OUT.partial.mp4``,
  ``.BOXES.partial.txt``; the extension is kept: it picks the container) and renamed when
  the run ends -- also when Ctrl-C, SIGTERM or SIGHUP stops it (:mod:`fastdet.signals`:
  the current frame is finished, the outputs then hold the same frames, and the exit
  status is 128 + the signal), because the video is then a complete, playable video of the
  frames done. A run that fails (exit 2: a failed write, a frame of another size) keeps
  no output; one killed outright (SIGKILL) leaves only temporary names. A run that ends
  before its first frame leaves no video.
- Bad input (missing file, not a video, no frames, frames too small or grey, an output
  folder that does not exist, a model that does not load) raises
  :class:`~fastdet.errors.FastdetError`; the dispatcher prints one line and exits with
  status 2. Inputs and outputs are all checked before any output file is created.
- The summary gives the frames per second of the frame loop and the whole run's wall time
  (loading the model and, on a first run, compiling the kernels included).
- Counting (:mod:`fastdet.video.count`): ``--count`` prints the number of distinct vehicles
  (track ids seen in at least 3 frames) and, with ``--line X1,Y1,X2,Y2`` (frame pixels; implies ``--count``), how many
  crossed that line in each direction. ``--summary S.json`` writes one JSON object when the
  run ends: ``input``, ``frames``, ``fps``, ``outputs`` and, with the tracker, ``vehicles``
  (and ``line`` with its two counts ``left_to_right`` / ``right_to_left``).
"""
from __future__ import annotations

import argparse
import contextlib
import json
import os
import time
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import numba
import numpy as np

from .. import signals as _signals
from ..config import HeatConfig
from ..console import process_seconds, prog
from ..detections import Detections
from ..errors import DataError, FastdetError, WriteError
from ..io.atomic import OutputSet, partial_name
from ..io.motfiles import JsonLinesWriter, MotWriter
from ..io.paths import bundled_models, check_paths
from ..io.reader import FrameReader, check_source
from ..io.sink import VideoSink, check_video_path
from ..video.count import CountLine, VehicleCounter
from ..video.detector import make_detector
from ..video.pipeline import run_frames
from ..video.run import defer_plausible, offline_boxes, progress_bar, video_detector_for
from ._args import add_horizon_argument, nonneg_int, pipeline_config, pipeline_groups, positive_int


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.usage = ("%(prog)s INPUT [-o OUT.mp4] [--boxes B.txt]\n"
                    "       [--json B.jsonl] [--summary S.json] [--count] [options]")
    io = parser.add_argument_group("inputs and outputs")
    io.add_argument("input", metavar="INPUT", help="video, image sequence (img%%04d.jpg), URL, camera")
    io.add_argument("-o", "--output", metavar="OUT.mp4", help="annotated video")
    io.add_argument("--boxes", metavar="BOXES.txt",
                    help="MOTChallenge boxes with track ids (conf: the peak heat of the box's blob)")
    io.add_argument("--json", metavar="BOXES.jsonl", help="boxes per frame as JSON lines")
    io.add_argument("--summary", metavar="S.json", help="a JSON summary (frames, fps, outputs, counts)")
    io.add_argument("--start", type=nonneg_int, default=0, metavar="S",
                    help="skip the first S frames (frame numbers kept)")
    io.add_argument("--frames", type=positive_int, default=None, metavar="N", help="at most N frames")
    io.add_argument("--no-progress", action="store_true", help="no progress bar")
    search, tracking, advanced = pipeline_groups(parser)
    add_horizon_argument(search)
    track = tracking.add_mutually_exclusive_group()
    track.add_argument("--no-track", action="store_true", help="no tracker: boxes without ids (-1)")
    track.add_argument("--offline", action="store_true",
                       help="files only: fill track gaps at the end")
    tracking.add_argument("--count", action="store_true", help="print the number of distinct vehicles")
    tracking.add_argument("--line", metavar="X1,Y1,X2,Y2", type=_line_arg,
                          help="count crossings of this line, per direction")
    d = HeatConfig()
    advanced.add_argument("--heat-frames", type=positive_int, default=d.n_frames, metavar="N",
                          help=f"frames the heat map remembers (default {d.n_frames})")
    advanced.add_argument("--heat-decay", type=float, default=d.decay, metavar="D",
                          help=f"a frame k frames old weighs D**k (default {d.decay})")
    advanced.add_argument("--heat-threshold", type=float, default=d.threshold, metavar="T",
                          help=f"heat a vehicle needs (default {d.threshold})")
    advanced.add_argument("--debug", action="store_true", help="panels: windows, heat map, blobs, tracks")
    advanced.add_argument("--profile", action="store_true", help="print ms per frame per stage")


def _line_arg(s: str) -> CountLine:
    try:
        return CountLine.parse(s)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


_STAGES = (
    ("decode", "decode", "reader"),
    ("resize/colour", "resize_colour", "main"),
    ("HOG", "hog", "main"),
    ("scoring", "score", "main"),
    ("detect (rest)", "detect", "main"),
    ("heat", "heat", "main"),
    ("label", "label", "main"),
    ("heat map (rest)", "heatmap", "main"),
    ("oncoming heat", "fusion", "main"),
    ("horizon", "horizon", "main"),
    ("plan", "plan", "main"),
    ("motion", "motion", "main"),
    ("weak blobs", "weak", "main"),
    ("track", "track", "main"),
    ("clip", "clip", "main"),
    ("refine", "refine", "main"),
    ("plausible", "plausible", "main"),
    ("observe", "observe", "main"),
    ("boxes out", "boxes_out", "main"),
    ("draw", "draw", "writer"),
    ("encode", "encode", "writer"),
)


def _profile_table(totals: dict[str, float], n: int, wall: float, main_busy: float) -> str:
    # with 2+ Numba threads the Detector runs its bands in that many threads: its stage
    # times add up their work, which can exceed the main thread's busy time
    band = numba.get_num_threads() > 1
    lines = [f"{'stage':<16}{'ms/frame':>10}  thread"]
    for label, key, thread in _STAGES:
        if key in totals:
            if band and key in ("resize_colour", "hog", "score"):
                thread = f"{numba.get_num_threads()} band threads (work summed)"
            lines.append(f"{label:<16}{1e3 * totals[key] / n:>10.2f}  {thread}")
    lines.append(f"{'main thread busy':<16}{1e3 * main_busy / n:>10.2f}  main (detect + heat + boxes out)")
    lines.append(f"{'wall':<16}{1e3 * wall / n:>10.2f}  ({n / wall:.1f} fps)")
    return "\n".join(lines)


def close_outputs(sink: VideoSink | None, writers: Sequence[Any], discard: bool,
                  outputs: OutputSet | None = None) -> OutputSet:
    """Close the box files and the video into ``outputs`` (their temporary files, renamed
    together by :meth:`OutputSet.commit`, video first), or remove them all with ``discard``
    -- and when one of them fails to close (a failed write:
    :class:`~fastdet.errors.DataError`, raised after the others were removed)."""
    done = outputs if outputs is not None else OutputSet()
    found: dict[int, tuple[Path, Path]] = {}
    error: DataError | None = None
    outs = (sink, *writers)
    for i in (*range(1, len(outs)), 0):  # the box files first: the video's check takes longest
        if outs[i] is None:
            continue
        try:
            p = outs[i].close(discard=discard or error is not None, rename=False)
        except DataError as exc:
            error = error or exc
            continue
        if p is not None:
            final = outs[i].path if outs[i] is sink else Path(outs[i].name)
            found[i] = (Path(p), Path(final))
    if error is not None:
        for tmp, _ in found.values():
            tmp.unlink(missing_ok=True)
        done.discard()
        raise error
    for i in sorted(found):
        done.add(*found[i])
    return done


def _emit(fno: int, dets: Detections, mot: MotWriter | None, jsl: JsonLinesWriter | None,
          counter: VehicleCounter | None) -> None:
    """One frame's boxes (with their ids) to the box files and the counter."""
    if mot is not None:
        mot.write_detections(fno, dets)
    if jsl is not None:
        jsl.write_detections(fno, dets)
    if counter is not None:
        counter.update(dets)


def _redraw(args: argparse.Namespace, sink: VideoSink, frames: list[tuple[int, Detections]]) -> bool:
    """``--offline``: read INPUT again and give the sink each frame with its final boxes (no
    debug panels: the heat maps of every frame are not kept). ``False`` when a stop signal
    came during the redraw (the video then holds fewer frames than the box files: the caller
    keeps no video)."""
    by_frame = dict(frames)
    last = frames[-1][0]
    stopped = _signals.stop_requested()  # a stop during detection: still draw the frames done
    reader = FrameReader(args.input, args.start, last - args.start)
    try:
        for fno, frame, _ in reader:
            if fno > last:
                break
            if _signals.stop_requested() and not stopped:
                return False
            dets = by_frame.get(fno)
            if dets is not None:
                sink.put((frame, dets, None))
    finally:
        reader.close()
    return not (_signals.stop_requested() and not stopped)


def run(args: argparse.Namespace, detector: Any = None) -> int:
    """The ``video`` subcommand. ``detector`` replaces the model's Detector (tests)."""
    out, boxes_path, json_path = args.output, args.boxes, args.json
    summary_path = getattr(args, "summary", None)
    line = getattr(args, "line", None)
    counting = bool(getattr(args, "count", False) or line is not None)
    track = not getattr(args, "no_track", False)
    offline = bool(getattr(args, "offline", False))
    if not (out or boxes_path or json_path or summary_path or counting):
        raise FastdetError("nothing to write: give -o OUTPUT.mp4, --boxes BOXES.txt, --json BOXES.jsonl, "
                           "--summary S.json and/or --count")
    if counting and not track:
        raise FastdetError("--count and --line need the tracker: leave out --no-track")
    config = pipeline_config(args)
    heat = config.heat
    check_source(args.input)
    check_paths([("INPUT", args.input), ("--model", args.model),
                 ("--oncoming-model", getattr(args, "oncoming_model", None)), *bundled_models()],
                [("-o", out, "video"), ("--boxes", boxes_path, "box"), ("--json", json_path, "JSON"),
                 ("--summary", summary_path, "summary")])
    if out:
        check_video_path(out)  # .webm and the like: refused before any work

    reader = FrameReader(args.input, args.start, args.frames)
    sink = mot = jsl = None
    pending: OutputSet | None = None
    try:
        if offline and reader.live:
            raise FastdetError(f"{args.input}: --offline needs a video file, not a live source")
        if detector is None:
            detector = make_detector(config)
        elif args.model is not None:
            raise FastdetError("--model cannot be used with an injected detector")
        vd = video_detector_for(reader, detector, config)
        if offline:
            defer_plausible(vd)
        vd.warmup()
        counter = VehicleCounter(line) if track else None
        done: list[tuple[int, Detections]] = []  # --offline: every frame's tracks

        h, w = reader.shape[:2]
        if out:
            sink = VideoSink(out, reader.fps, (w, h), debug=args.debug, threshold=heat.threshold)
        if boxes_path:
            mot = MotWriter(boxes_path)
        if json_path:
            jsl = JsonLinesWriter(json_path)

        totals: dict[str, float] = {}
        n = 0
        main_busy = 0.0
        t_start = time.perf_counter()
        bar = progress_bar(reader.expected, not args.no_progress, os.path.basename(args.input))
        failed, stop = True, None
        redraw_stopped: VideoSink | None = None
        try:
            reading = [0.0]  # seconds spent waiting for the reader's frames

            def frames() -> Iterator[tuple[int, np.ndarray, float]]:
                it = iter(reader)
                while not _signals.stop_requested():  # a stop signal ends the loop after the current frame
                    t = time.perf_counter()
                    item = next(it, None)
                    reading[0] += time.perf_counter() - t
                    if item is None:
                        return
                    yield item

            with _signals.deferred(), contextlib.closing(run_frames(vd, frames())) as boxes:
                while True:
                    t0, r0 = time.perf_counter(), reading[0]
                    got = next(boxes, None)
                    if got is None:
                        break
                    fno, frame, t_dec, dets = got
                    t1 = time.perf_counter()
                    t0 += reading[0] - r0  # the reader's wait is not the main thread's work
                    # the frame goes to every output or to none: a second (impatient) stop signal
                    # waits until it is in all of them (the video's put may wait for the encoder)
                    with _signals.deferred(repeats=False, raise_on_exit=False):
                        if offline:
                            done.append((fno, dets))
                        else:
                            _emit(fno, dets, mot, jsl, counter)
                        t2 = time.perf_counter()
                        if sink is not None and not offline:
                            dbg = None
                            if args.debug:
                                d = vd.debug
                                dbg = (d.windows, d.heat, d.labels, d.mask, d.tracks)
                            sink.put((frame, dets, dbg))
                    for k, v in vd.timings.items():
                        totals[k] = totals.get(k, 0.0) + v
                    totals["decode"] = totals.get("decode", 0.0) + t_dec
                    totals["boxes_out"] = totals.get("boxes_out", 0.0) + (t2 - t1)
                    main_busy += t2 - t0
                    n += 1
                    bar.update(1)
                if offline and done:
                    final = offline_boxes(vd, done, reader.shape)
                    for fno, dets in final:
                        _emit(fno, dets, mot, jsl, counter)
                    if sink is not None and not _redraw(args, sink, final):
                        # stopped while the video was redrawn: it holds fewer frames than the
                        # box files, so it is not kept (never a truncated video under its name)
                        redraw_stopped = sink
                        sink = None
                        redraw_stopped.close(discard=True)
            failed = False
        except KeyboardInterrupt as exc:  # a stop (Ctrl-C, SIGTERM, SIGHUP): keep the frames done
            failed = False
            stop = exc if isinstance(exc, _signals.Stopped) else None
            raise
        finally:
            bar.close()
            pending = close_outputs(sink, (mot, jsl), discard=failed)
            wall = time.perf_counter() - t_start
            if sink is not None:
                totals["draw"], totals["encode"] = sink.draw_s, sink.encode_s
            if n and not failed:
                outs = [str(p) for p in pending.finals()]
                if summary_path:
                    info: dict[str, Any] = {"input": str(args.input), "frames": n, "fps": round(n / wall, 2),
                                            "outputs": list(outs)}
                    if counter is not None:
                        info.update(counter.summary())
                    _write_summary(pending, summary_path, info)
                    outs.append(str(summary_path))
                pending.commit()  # every output under its final name, or none (a failed rename)
                summary = (f"{n} frames in {wall:.2f} s, {n / wall:.1f} fps "
                           f"({process_seconds():.1f} s in all, start-up included)"
                           + (f"; {reader.n_skipped} damaged frames skipped" if reader.n_skipped else "")
                           + (f"; wrote {', '.join(outs)}" if outs else "")
                           + (f"; {out} not written (stopped while the video was redrawn)"
                              if redraw_stopped is not None else ""))
                if counting and counter is not None:
                    summary += f"; {counter.text()}"
                if stop is not None:
                    stop.detail = summary  # the dispatcher's one line
                else:
                    print(f"{prog()}: {summary}", flush=True)
                if args.profile:
                    print(_profile_table(totals, n, wall, main_busy), flush=True)
    finally:
        reader.close()
        close_outputs(sink, (mot, jsl), discard=True)  # no-op for outputs closed above
        if pending is not None:
            pending.discard()  # no-op once committed
    return 0


def _write_summary(pending: OutputSet, path: str, info: dict[str, Any]) -> None:
    """``--summary``: the JSON object to its temporary file, renamed with the other outputs."""
    tmp = partial_name(path)
    try:
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(json.dumps(info) + "\n")
            fh.flush()
            os.fsync(fh.fileno())
    except OSError as exc:
        with contextlib.suppress(OSError):
            tmp.unlink(missing_ok=True)
        pending.discard()
        raise WriteError(f"{path}: cannot write ({exc.strerror or exc})") from None
    pending.add(tmp, path)
