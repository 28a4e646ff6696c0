"""CPU of ``Detector.detect`` per frame with the default main search and with other bands
(run by hand; ``docs/geometry.md``).

Both detectors (the video pipeline's: main + oncoming model, full search) score the same
frames, alternating, ``--repeat`` times; prints the median CPU milliseconds per frame
(``time.process_time``: all threads) and the ratio.

    NUMBA_NUM_THREADS=1 python -m tools.studies.band_cost --bands 0.75:400:460,1:400:496,... [--clip test_small1]
"""
from __future__ import annotations

import argparse
import statistics
import time
from dataclasses import replace

from fastdet.config import PipelineConfig, SearchBand
from fastdet.data import data_dir
from fastdet.io.reader import FrameReader
from fastdet.video import make_detector


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--bands", required=True, help="scale:y0:y1[:x0:x1],... (1280x720 reference pixels)")
    ap.add_argument("--clip", default="test_small1")
    ap.add_argument("--frames", type=int, default=20)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    bands = []
    for item in args.bands.split(","):
        p = item.split(":")
        bands.append(SearchBand(float(p[0]), int(p[1]), int(p[2]), int(p[3]) if len(p) > 3 else None,
                                int(p[4]) if len(p) > 4 else None))
    reader = FrameReader(data_dir() / "videos" / f"{args.clip}.mp4")
    try:
        frames = [f for _, (_, f, _) in zip(range(args.frames), reader)]
    finally:
        reader.close()
    today = make_detector(PipelineConfig())
    other = make_detector(PipelineConfig(search=replace(PipelineConfig().search, bands=tuple(bands))))
    for d in (today, other):
        d.warmup()
        for f in frames[:3]:
            d.detect(f)
    ms: dict[str, list[float]] = {"today": [], "other": []}
    for _ in range(args.repeat):
        for name, d in (("today", today), ("other", other)):
            t = time.process_time()
            for f in frames:
                d.detect(f)
            ms[name].append((time.process_time() - t) / len(frames) * 1e3)
    a, b = statistics.median(ms["today"]), statistics.median(ms["other"])
    print(f"default bands {a:.1f} ms/frame CPU, --bands {b:.1f} ms/frame CPU: {b / a:.2f}x "
          f"({args.frames} frames of {args.clip}, median of {args.repeat})")


if __name__ == "__main__":
    main()
