"""``fastdet adapt``'s operating point on its own: the three runs over a kept-aside stretch (the
bundled model, the replay of the 8 default offsets, the model moved by 8), timed, with the
stretch decoded once and held (what ``adapt`` does) or, ``--reopen``, each run opening the
video at the stretch (what it did: every frame before it decoded three times).

Run::

    python -m benchmarks.bench_adapt --minutes 10 --keep /tmp/fb_10.mp4   # makes the footage (once)
    python -m benchmarks.bench_adapt_step /tmp/fb_10.mp4                   # held
    python -m benchmarks.bench_adapt_step /tmp/fb_10.mp4 --reopen          # re-opened
    python -m benchmarks.bench_adapt_step /tmp/fb_10.mp4 --save held.pkl   # ... and compare the two:
    python -m benchmarks.bench_adapt_step --compare held.pkl reopen.pkl    # frames whose boxes differ

The stretch: the last ``--frames`` (default 400, ``AdaptConfig.holdout_max``) frames of the
video by its header's count. ``ms a frame``: a run's steady frame loop (from its first frame out),
as the adapt summary's.
"""
from __future__ import annotations

import argparse
import pickle
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

OFFSETS = (-1.0, 0.0, 1.0, 2.0, 3.0, 4.0, 6.0, 8.0)


def _rows(dets: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    return dets.boxes.copy(), dets.scores.copy(), None if dets.ids is None else dets.ids.copy()


def measure(video: str, frames: int, reopen: bool) -> tuple[dict[str, float], dict[str, Any]]:
    """The step's seconds (and each run's steady ms a frame) and every run's boxes."""
    from fastdet.config import PipelineConfig
    from fastdet.io.hold import hold_frames
    from fastdet.io.reader import FrameReader
    from fastdet.model import load_model
    from fastdet.train.blend import offset
    from fastdet.video.horizon import HORIZON_FRAMES
    from fastdet.video.replay import iter_offset_detections
    from fastdet.video.run import iter_video_detections

    with FrameReader(video, notify=lambda _n: None) as r:
        total = r.frame_count
    if total is None or total <= frames:
        raise SystemExit(f"bench_adapt_step: {video}: needs a frame count above {frames}")
    start = total - frames
    secs: dict[str, float] = {}
    boxes: dict[str, Any] = {}
    with tempfile.TemporaryDirectory(prefix="bench-adapt-step-") as tmp:
        moved = str(Path(tmp) / "moved8.npz")
        offset(load_model(), 8.0).save(moved)
        list(iter_video_detections(video, frames=2, progress=False))  # models and kernels loaded
        t0 = time.perf_counter()
        src: Any = video
        if not reopen:
            src = hold_frames(video, start, max(frames, HORIZON_FRAMES))
            secs["read once"] = time.perf_counter() - t0
        try:
            for name, model in (("before", None), ("replay", None), ("after", moved)):
                t = time.perf_counter()
                if name == "replay":
                    boxes[name] = [(f, {o: _rows(d) for o, d in by.items()})
                                   for f, by in iter_offset_detections(src, OFFSETS, PipelineConfig(), start=start,
                                                                       frames=frames)]
                else:
                    cfg = PipelineConfig() if model is None else replace(PipelineConfig(), model=model)
                    rows, first = [], 0.0
                    for f, d in iter_video_detections(src, cfg, start=start, frames=frames, progress=False):
                        first = first or time.perf_counter()
                        rows.append((f, _rows(d)))
                    secs[f"{name} ms a frame"] = 1000 * (time.perf_counter() - first) / max(len(rows) - 1, 1)
                    boxes[name] = rows
                secs[name] = time.perf_counter() - t
        finally:
            if not reopen:
                src.close()
        secs["step"] = time.perf_counter() - t0
    return secs, boxes


def compare(a: dict[str, Any], b: dict[str, Any]) -> list[str]:
    """Per run (and offset), the boxes and the frames whose boxes, scores or ids differ."""
    def same(x: tuple, y: tuple) -> bool:
        return all((p is None and q is None) or (p is not None and q is not None and np.array_equal(p, q))
                   for p, q in zip(x, y))

    out = []
    for name in ("before", "after"):
        if [f for f, _ in a[name]] != [f for f, _ in b[name]]:
            out.append(f"{name}: other frames")
            continue
        diff = sum(not same(x, y) for (_, x), (_, y) in zip(a[name], b[name]))
        out.append(f"{name}: {len(a[name])} frames, {sum(len(x[0]) for _, x in a[name])} boxes, {diff} differ")
    for o in OFFSETS:
        diff = sum(not same(x[o], y[o]) for (_, x), (_, y) in zip(a["replay"], b["replay"]))
        out.append(f"replay {o:g}: {sum(len(x[o][0]) for _, x in a['replay'])} boxes, {diff} frames differ")
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("video", nargs="?", help="the footage (e.g. /tmp/fb_10.mp4)")
    p.add_argument("--frames", type=int, default=400, help="the kept-aside stretch (default 400)")
    p.add_argument("--reopen", action="store_true", help="each run opens the video at the stretch (as before)")
    p.add_argument("--save", type=Path, default=None, help="pickle every run's boxes here")
    p.add_argument("--compare", nargs=2, type=Path, default=None, metavar=("A.pkl", "B.pkl"))
    args = p.parse_args(argv)
    if args.compare:
        a, b = (pickle.loads(f.read_bytes()) for f in args.compare)
        print("\n".join(compare(a, b)))
        return 0
    if not args.video:
        p.error("give the video (or --compare A.pkl B.pkl)")
    secs, boxes = measure(args.video, args.frames, args.reopen)
    print(f"{'re-opened' if args.reopen else 'held'}: " + ", ".join(f"{k} {v:.1f}" for k, v in secs.items()),
          flush=True)
    if args.save:
        args.save.write_bytes(pickle.dumps(boxes))
    return 0


if __name__ == "__main__":
    sys.exit(main())
