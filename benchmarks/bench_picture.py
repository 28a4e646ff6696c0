"""Single pictures: the whole-picture search (``fastdet image`` / :func:`fastdet.detect_picture`,
:class:`fastdet.config.PictureSearch`) side by side with its first stage alone (the windows
above decision value 2 after NMS, no refinement or verifier: the default before the second
stage) and the former ``image`` path (the video's horizon-relative bands and a single-frame heat
map), ms per 1280x720 picture at 1 and 2 Numba threads.

Run::

    python -m benchmarks.bench_picture            # both thread counts, one subprocess each
    python -m benchmarks.bench_picture --rounds 20

Pictures: ``test_images/*.jpg`` (six 1280x720 dashcam frames), one per call, cycled; after
one warm-up round, ``--rounds`` rounds. Reported: best and median wall ms a picture, and the
median process CPU ms (all threads) -- on a machine shared with other jobs the CPU figure is the
steadier one. Budget: the picture search at most 50 ms at 2 threads.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time


def _measure(rounds: int) -> dict[str, dict[str, float]]:
    import cv2

    from fastdet.config import HeatConfig, PictureSearch, PipelineConfig
    from fastdet.data import data_dir
    from fastdet.video.detector import make_detector
    from fastdet.video.heatmap import detect_image
    from fastdet.video.picture import PictureDetector

    frames = [cv2.imread(str(p)) for p in sorted((data_dir() / "test_images").glob("*.jpg"))]
    old = make_detector(PipelineConfig(oncoming=False))
    heat = HeatConfig().single_frame()
    new = PictureDetector()
    first = PictureDetector(config=PictureSearch(nms_min_score=2.0, refine=None, verify=False))
    cases = {"former image path (video bands + heat map)": lambda f: detect_image(f, old, heat),
             "picture search, first stage only (NMS above 2)": first.detect,
             "picture search (PictureSearch defaults)": new.detect}
    out = {}
    for name, fn in cases.items():
        for f in frames:
            fn(f)
        wall, cpu = [], []
        for _ in range(rounds):
            for f in frames:
                c0, t0 = time.process_time(), time.perf_counter()
                fn(f)
                wall.append(time.perf_counter() - t0)
                cpu.append(time.process_time() - c0)
        out[name] = {"best_ms": 1e3 * min(wall), "median_ms": 1e3 * statistics.median(wall),
                     "cpu_median_ms": 1e3 * statistics.median(cpu),
                     "windows_bands": len(new.detector(frames[0].shape).search.bands) if "picture" in name else 7}
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=10)
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        print(json.dumps(_measure(args.rounds)))
        return 0
    print(f"load average before: {os.getloadavg()[0]:.1f}")
    print("| path | threads | best ms | median ms | CPU ms (median) |")
    print("|---|---|---|---|---|")
    for threads in (1, 2):
        env = dict(os.environ, NUMBA_NUM_THREADS=str(threads))
        res = subprocess.run([sys.executable, "-m", "benchmarks.bench_picture", "--child", "--rounds",
                              str(args.rounds)], env=env, capture_output=True, text=True, check=True)
        for name, r in json.loads(res.stdout.strip().splitlines()[-1]).items():
            print(f"| {name} | {threads} | {r['best_ms']:.1f} | {r['median_ms']:.1f} | {r['cpu_median_ms']:.1f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
