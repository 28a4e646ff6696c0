"""``python -m fastdet video``: detect vehicles in a video.

``python -m fastdet video INPUT -o OUT.mp4 [--boxes B.txt] [--json B.jsonl] [--model M.npz]
[--oncoming-model W.npz | --no-oncoming] [--debug] [--profile] [--no-progress] [--start S] [--frames N]``

- The bundled oncoming-traffic model runs beside the main one (see :class:`VideoDetector`);
  ``--no-oncoming`` leaves it out, ``--oncoming-model`` replaces it.

- Decoding runs in a reader thread and drawing + encoding in a writer thread, connected to
  the detecting main thread by bounded queues: OpenCV and the numba kernels release the
  GIL, so the three overlap on two cores.
- ``--boxes`` writes MOTChallenge lines ``frame,-1,left,top,width,height,conf,-1,-1,-1``
  and ``--json`` one JSON object per frame (:mod:`fastdet.io.motfiles`); both are flushed after
  every frame. ``frame`` is the 1-based frame number in INPUT, so with ``--start S`` the
  first line is frame ``S + 1``, aligned with the ground truth of the whole clip.
- The video is written as ``.OUT.partial.mp4`` in the output folder (the extension is kept:
  it picks the container) and renamed to ``OUT.mp4`` when the run ends -- also when it ends
  early on Ctrl-C or on a frame that fails to decode, because the file is then a complete,
  playable video of the frames done, matching the boxes file line for line. A run that
  ends before its first frame leaves no video.
- Bad input (missing file, not a video, no frames, an output folder that does not exist,
  a model that does not load) raises :class:`~fastdet.errors.FastdetError`; the dispatcher
  prints one line and exits with status 2. Inputs and outputs are all checked before any
  output file is created.
"""
from __future__ import annotations

import argparse
import os
import time
from typing import Any

import numba

from ..config import HeatConfig
from ..errors import DataError, FastdetError
from ..io.motfiles import JsonLinesWriter, MotWriter
from ..io.reader import FrameReader
from ..io.atomic import check_output_path
from ..io.sink import VideoSink
from ..video.pipeline import VideoDetector, _passive_omp, _progress, make_detector
from ._args import add_oncoming_arguments, nonneg_int, oncoming_arg, positive_int


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("input", metavar="INPUT", help="video file (anything OpenCV reads)")
    parser.add_argument("-o", "--output", metavar="OUTPUT.mp4",
                        help="annotated video (mp4v); written as .OUTPUT.partial.mp4, renamed when done")
    parser.add_argument("--boxes", metavar="BOXES.txt",
                        help="boxes per frame, MOTChallenge: frame,-1,left,top,width,height,conf,-1,-1,-1")
    parser.add_argument("--json", metavar="BOXES.jsonl", help="boxes per frame as JSON lines")
    parser.add_argument("--model", metavar="MODEL.npz", help="model file (default: the bundled model)")
    add_oncoming_arguments(parser)
    parser.add_argument("--debug", action="store_true",
                        help="add panels along the top: windows by scale, heat map, thresholded blobs")
    parser.add_argument("--profile", action="store_true", help="print a table of ms per frame per stage")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument("--start", type=nonneg_int, default=0, metavar="S",
                        help="skip the first S frames (frame numbers stay those of the file)")
    parser.add_argument("--frames", type=positive_int, default=None, metavar="N",
                        help="process at most N frames")
    d = HeatConfig()
    parser.add_argument("--heat-frames", type=positive_int, default=d.n_frames, metavar="N",
                        help=f"frames the heat map remembers (default {d.n_frames})")
    parser.add_argument("--heat-decay", type=float, default=d.decay, metavar="D",
                        help=f"weight of a frame k frames old is D**k (default {d.decay})")
    parser.add_argument("--heat-threshold", type=float, default=d.threshold, metavar="T",
                        help=f"heat a pixel needs to be part of a vehicle (default {d.threshold})")


def _heat_config(args: argparse.Namespace) -> HeatConfig:
    try:
        return HeatConfig(n_frames=getattr(args, "heat_frames", HeatConfig.n_frames),
                          decay=getattr(args, "heat_decay", HeatConfig.decay),
                          threshold=getattr(args, "heat_threshold", HeatConfig.threshold))
    except ValueError as exc:
        raise FastdetError(f"heat map: {exc}") from None


_STAGES = (
    ("decode", "decode", "reader"),
    ("resize/colour", "resize_colour", "main"),
    ("HOG", "hog", "main"),
    ("scoring", "score", "main"),
    ("heat", "heat", "main"),
    ("label", "label", "main"),
    ("motion", "motion", "main"),
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


def run(args: argparse.Namespace, detector: Any = None) -> int:
    """The ``video`` subcommand. ``detector`` replaces the model's Detector (tests)."""
    _passive_omp()
    out, boxes_path, json_path = args.output, args.boxes, args.json
    if not (out or boxes_path or json_path):
        raise FastdetError("nothing to write: give -o OUTPUT.mp4, --boxes BOXES.txt and/or --json BOXES.jsonl")
    named = [p for p in (out, boxes_path, json_path) if p]
    if len({os.path.abspath(p) for p in named}) != len(named):
        raise FastdetError("the outputs must be different files")
    heat = _heat_config(args)
    if not os.path.exists(args.input):
        raise DataError(f"{args.input}: file not found")
    for p, what in ((out, "video"), (boxes_path, "boxes"), (json_path, "JSON")):
        if p:
            check_output_path(p, what, args.input)

    reader = FrameReader(args.input, args.start, args.frames)
    sink = mot = jsl = None
    try:
        if detector is None:
            detector = make_detector(args.model, oncoming_arg(args))
        elif args.model is not None:
            raise FastdetError("--model cannot be used with an injected detector")
        vd = VideoDetector(detector, heat)
        vd.warmup()

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
        bar = _progress(reader.expected, not args.no_progress, os.path.basename(args.input))
        try:
            for fno, frame, t_dec in reader:
                t0 = time.perf_counter()
                dets = vd.update(frame)
                t1 = time.perf_counter()
                if mot is not None:
                    mot.write(fno, dets.boxes, dets.scores)
                if jsl is not None:
                    jsl.write(fno, dets.boxes, dets.scores)
                t2 = time.perf_counter()
                if sink is not None:
                    dbg = None
                    if args.debug:
                        dbg = (vd.last_windows, vd.last_heat, vd.last_labels, vd.last_mask)
                    sink.put((frame, dets, dbg))
                for k, v in vd.timings.items():
                    totals[k] = totals.get(k, 0.0) + v
                totals["decode"] = totals.get("decode", 0.0) + t_dec
                totals["boxes_out"] = totals.get("boxes_out", 0.0) + (t2 - t1)
                main_busy += t2 - t0
                n += 1
                bar.update(1)
        finally:
            bar.close()
            written = sink.close() if sink is not None else None
            wall = time.perf_counter() - t_start
            if sink is not None:
                totals["draw"], totals["encode"] = sink.draw_s, sink.encode_s
            outs = [str(p) for p in (written, boxes_path, json_path) if p]
            if n:
                print(f"fastdet video: {n} frames in {wall:.2f} s, {n / wall:.1f} fps"
                      + (f"; wrote {', '.join(outs)}" if outs else ""), flush=True)
                if args.profile:
                    print(_profile_table(totals, n, wall, main_busy), flush=True)
    finally:
        reader.close()
        if sink is not None:
            sink.close()
        for wr in (mot, jsl):
            if wr is not None:
                wr.close()
    return 0
