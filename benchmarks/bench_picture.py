"""Single pictures: the whole-picture search (``fastdet image`` / :func:`fastdet.detect_picture`,
:class:`fastdet.config.PictureSearch`) side by side with its first stage alone (the windows
above decision value 2 after NMS, no refinement or verifier: the default before the second
stage) and the former ``image`` path (the video's horizon-relative bands and a single-frame heat
map), ms per 1280x720 picture at 1 and 2 Numba threads.

Run::

    python -m benchmarks.bench_picture            # both thread counts, one subprocess each
    python -m benchmarks.bench_picture --rounds 20
    python -m benchmarks.bench_picture --second-stage --rounds 5   # the second stage alone

``--second-stage``: the second stage alone (refinement and verifier of the first stage's boxes
above decision value 0, :meth:`PictureDetector.second_stage`) with the package's crops, and with
the crops and features made one box at a time as first written (``tests/reference.py``
``ref_box_features``: ``cv2.copyMakeBorder`` + ``cv2.resize`` per box and context), the two
interleaved picture by picture so that both see the same load; plus the video's refinement
(:func:`fastdet.video.refine.refine`, the boxes a ``VideoDetector`` returns on the first frames
of ``test_video.mp4``) both ways.

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


def _measure_second_stage(rounds: int) -> dict[str, dict[str, float]]:
    import cv2

    from fastdet.data import data_dir
    from fastdet.detect import regressor, verifier
    from fastdet.video import box_stages
    from fastdet.video.picture import PictureDetector
    from fastdet.video.pipeline import VideoDetector
    from tests.reference import ref_box_features

    frames = [cv2.imread(str(p)) for p in sorted((data_dir() / "test_images").glob("*.jpg"))]
    det = PictureDetector()
    found = [det.boxes_from_windows(det.windows(f)) for f in frames]
    # the video's refinement: the boxes VideoDetector hands to refine() on test_video's frames
    cap = cv2.VideoCapture(str(data_dir() / "videos" / "test_video.mp4"))
    vd, calls = VideoDetector(), []
    real = box_stages.refine
    box_stages.refine = lambda *a: calls.append(a) or real(*a)
    try:
        for _ in range(40):
            ok, f = cap.read()
            if not ok:
                break
            vd.update(f)
    finally:
        box_stages.refine = real
        cap.release()
    fast = regressor.box_features

    def use(fn) -> None:
        regressor.box_features = verifier.box_features = fn

    cases = {"second stage": [(lambda i=i: det.second_stage(frames[i], found[i])) for i in range(len(frames))],
             "video refine (a frame)": [(lambda c=c: real(*c)) for c in calls]}
    out = {}
    try:
        for name, jobs in cases.items():
            times: dict[str, tuple[list[float], list[float]]] = {"package": ([], []), "one box at a time": ([], [])}
            for r in range(rounds + 1):
                for job in jobs:
                    for how, fn in (("package", fast), ("one box at a time", ref_box_features)):
                        use(fn)
                        c0, t0 = time.process_time(), time.perf_counter()
                        job()
                        if r:  # the first round warms up
                            times[how][0].append(time.perf_counter() - t0)
                            times[how][1].append(time.process_time() - c0)
            for how, (wall, cpu) in times.items():
                out[f"{name}, {how}"] = {"best_ms": 1e3 * min(wall), "median_ms": 1e3 * statistics.median(wall),
                                         "cpu_median_ms": 1e3 * statistics.median(cpu),
                                         "mean_ms": 1e3 * statistics.mean(wall),
                                         "cpu_mean_ms": 1e3 * statistics.mean(cpu)}
    finally:
        use(fast)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=10)
    ap.add_argument("--second-stage", action="store_true",
                    help="time the second stage alone, the package's crops against one box at a time")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        print(json.dumps(_measure_second_stage(args.rounds) if args.second_stage else _measure(args.rounds)))
        return 0
    print(f"load average before: {os.getloadavg()[0]:.1f}")
    extra = " | mean ms | CPU ms (mean)" if args.second_stage else ""
    print(f"| path | threads | best ms | median ms | CPU ms (median){extra} |")
    print("|---|---|---|---|---|" + ("---|---|" if args.second_stage else ""))
    for threads in (1, 2):
        env = dict(os.environ, NUMBA_NUM_THREADS=str(threads))
        res = subprocess.run([sys.executable, "-m", "benchmarks.bench_picture", "--child", "--rounds",
                              str(args.rounds)] + (["--second-stage"] if args.second_stage else []),
                             env=env, capture_output=True, text=True, check=True)
        for name, r in json.loads(res.stdout.strip().splitlines()[-1]).items():
            more = f" | {r['mean_ms']:.2f} | {r['cpu_mean_ms']:.2f}" if args.second_stage else ""
            print(f"| {name} | {threads} | {r['best_ms']:.1f} | {r['median_ms']:.1f} | "
                  f"{r['cpu_median_ms']:.1f}{more} |")
    print(f"load average after: {os.getloadavg()[0]:.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
