"""ms per frame of the teacher (``fastdet label``, :class:`fastdet.teacher.TeacherDetector`) at
several input widths, side by side: the sizes take turns frame by frame, so a machine whose
load changes during the run slows them alike. Per size: the median and mean wall ms of
``detect`` (letterbox, network, decode + NMS, each given) and its CPU ms (``time.process_time``:
every thread of the process; less sensitive to other jobs than the wall time).

    python -m tools.studies.teacher_speed [--video V] [--sizes 640 960] [--threads 2] [--repeats 2]

Run it from the checkout's root; needs onnxruntime (``pip install -e '.[teacher]'``).
"""
from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from fastdet.data import data_dir
from fastdet.io.reader import read_frames
from fastdet.teacher import TeacherDetector


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--video", default=str(data_dir() / "videos" / "test_video.mp4"))
    ap.add_argument("--teacher", default=str(data_dir() / "teachers" / "yolox_nano.onnx"))
    ap.add_argument("--sizes", type=int, nargs="+", default=[640, 960])
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=2)
    args = ap.parse_args(argv)
    frames = read_frames(args.video)
    dets = {s: TeacherDetector(args.teacher, size=s, threads=args.threads) for s in args.sizes}
    for d in dets.values():  # onnxruntime plans the first runs of a shape
        d.detect(frames[0])
        d.detect(frames[-1])
    wall: dict[int, list[float]] = {s: [] for s in dets}
    parts = {s: np.zeros(3) for s in dets}
    cpu = dict.fromkeys(dets, 0.0)
    for _ in range(args.repeats):
        for frame in frames:
            for s, d in dets.items():
                c0, t0 = time.process_time(), time.perf_counter()
                blob, r = d.preprocess(frame)
                t1 = time.perf_counter()
                raw = d.run_input(blob)
                t2 = time.perf_counter()
                d.decode(raw, r, frame.shape)
                t3 = time.perf_counter()
                wall[s].append(t3 - t0)
                parts[s] += (t1 - t0, t2 - t1, t3 - t2)
                cpu[s] += time.process_time() - c0
    h, w = frames[0].shape[:2]
    print(f"{len(frames)} frames of {w}x{h} x {args.repeats}, {args.threads} threads")
    print("| size | input | ms a frame, median (mean) | letterbox | network | decode + NMS | CPU ms a frame |")
    print("|---:|---|---:|---:|---:|---:|---:|")
    for s, d in dets.items():
        n = len(wall[s])
        ih, iw = d.input_size(frames[0].shape)
        pre, net, dec = 1e3 * parts[s] / n
        print(f"| {s} | {iw}x{ih} | {1e3 * statistics.median(wall[s]):.0f} ({1e3 * np.mean(wall[s]):.0f}) "
              f"| {pre:.1f} | {net:.0f} | {dec:.1f} | {1e3 * cpu[s] / n:.0f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
